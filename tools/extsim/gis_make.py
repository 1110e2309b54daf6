#!/usr/bin/env python3
"""One run archive written by Aceinna's gnss-ins-sim (its IMU error model, Python/numpy).

    gis_make.py --gis GNSS_INS_SIM_CHECKOUT --imucal BIN --sequence factory-std --work DIR \
                --cfg '{"seed": 3, "gyro_b": [...], ..., "accel_b_stability": [...]}' --out ARCHIVE

gnss-ins-sim generates a vehicle's trajectory from Euler-angle/velocity commands through a PD
controller (pathgen.path_gen); it cannot follow a two-axis turntable's profile, and it passes no
sensor errors through its from-files mode.  So the reference here is the sequence's table
profile (extsim_common.Profile) made into exact mean rates and specific forces over each
sample interval, with gnss-ins-sim's Earth model (geoparams.geo_param: WGS-84 normal gravity,
Earth rate):

    dtheta_k = log( C_bn(k-1)^T exp([w_ie^n ts x]) C_bn(k) )          (inertial attitude change)
    dv_k     = C_bn(k-1)^T (I + [w_ie^n ts/2 x]) f^n ts,  f^n = (0, 0, -g)   (interval start)
    ref_w = dtheta_k / ts,  ref_a = dv_k / ts

and gnss-ins-sim's own sensor model adds its errors (imu_model.IMU with an accuracy dict,
pathgen.gyro_gen / pathgen.acc_gen: constant bias, first-order Gauss-Markov bias drift
"b_stability"/"b_corr", white noise ARW/VRW, optional vibration).  Its outputs are rates
(rad/s, m/s^2) of a sampled IMU; an integrating IMU's increment is the mean rate times ts, which
is what is written (the errors are additive and constant or slow within a sample).

--cfg keys, in gnss-ins-sim's own units (imu_model.IMU accuracy dict):
  seed, gyro_b [3] deg/h, gyro_arw [3] deg/sqrt(h), gyro_b_stability [3] deg/h, gyro_b_corr [3] s,
  accel_b [3] m/s^2, accel_vrw [3] m/s/sqrt(h), accel_b_stability [3] m/s^2, accel_b_corr [3] s,
  grade: the archive's [prior] grade ("navigation" when absent; db/archive/FORMAT.md),
  gyro_vib / accel_vib: a pathgen vib_def dict ({"type": "random"|"sinusoidal", "x": ..,
  "y": .., "z": .., "freq": Hz}), rad/s or m/s^2 (optional; no catalogue effect models it).
"""
import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import extsim_common as ec  # noqa: E402


def skew(v):
    v = np.asarray(v, float)
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def log_so3(R):
    """Rotation vectors of a stack of rotation matrices (angles < 90 deg), precise when small."""
    s = 0.5 * np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], 1)
    sn = np.linalg.norm(s, axis=1)
    th = np.arcsin(np.clip(sn, 0, 1))
    f = np.where(sn > 1e-300, th / np.where(sn > 1e-300, sn, 1), 1.0)
    return s * f[:, None]


def reference(profile, geoparams):
    """Exact interval increments (archive convention) of the table profile, gnss-ins-sim's Earth."""
    lat = math.radians(profile.lat_deg)
    _rm, _rn, g, sl, cl, w_ie = geoparams.geo_param(
        np.array([lat, math.radians(profile.lon_deg), profile.height_m]))
    ts = 1.0 / profile.rate_hz
    wn = w_ie * np.array([cl, 0.0, -sl])             # Earth rate in NED
    _, C = profile.attitudes()                        # C_bn at t = 0 and at every stamp
    th = np.linalg.norm(wn) * ts
    K = skew(wn / np.linalg.norm(wn))
    E = np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * K @ K  # exp([wn ts x])
    R = np.einsum("kji,jl,klm->kim", C[:-1], E, C[1:])               # C_{k-1}^T E C_k
    dth = log_so3(R)
    fn = np.array([0.0, 0.0, -g])
    Ehalf = np.eye(3) + skew(wn * ts / 2)
    dv = np.einsum("kji,j->ki", C[:-1], Ehalf @ fn) * ts
    return dth, dv, g


def make(gis, imucal, sequence, work, cfg, out, serial, rate_hz=100.0):
    sys.path.insert(0, os.path.abspath(gis))
    from gnss_ins_sim.geoparams import geoparams
    from gnss_ins_sim.pathgen import pathgen
    from gnss_ins_sim.sim import imu_model

    os.makedirs(work, exist_ok=True)
    profile = ec.Profile(imucal, sequence, work, rate_hz)
    cache = os.path.join(work, f"gis-ref-{os.path.basename(profile.dir)}.npz")
    if os.path.exists(cache):
        z = np.load(cache)
        dth, dv, g = z["dth"], z["dv"], float(z["g"])
    else:
        dth, dv, g = reference(profile, geoparams)
        np.savez(cache, dth=dth, dv=dv, g=g)
    ts = 1.0 / rate_hz
    arr = lambda k, d: np.asarray(cfg.get(k, d), float) * np.ones(3)
    acc = {"gyro_b": arr("gyro_b", 0), "gyro_arw": arr("gyro_arw", 0),
           "gyro_b_stability": arr("gyro_b_stability", 0),
           "accel_b": arr("accel_b", 0), "accel_vrw": arr("accel_vrw", 0),
           "accel_b_stability": arr("accel_b_stability", 0)}
    if "gyro_b_corr" in cfg:
        acc["gyro_b_corr"] = arr("gyro_b_corr", 0)
    if "accel_b_corr" in cfg:
        acc["accel_b_corr"] = arr("accel_b_corr", 0)
    imu = imu_model.IMU(accuracy=acc, axis=6, gps=False)
    np.random.seed(int(cfg.get("seed", 1)))
    w = pathgen.gyro_gen(rate_hz, dth / ts, imu.gyro_err, cfg.get("gyro_vib"))
    a = pathgen.acc_gen(rate_hz, dv / ts, imu.accel_err, cfg.get("accel_vib"))
    ge, ae = imu.gyro_err, imu.accel_err
    eff = {}
    sg = float(np.max(ge["b_drift"])) if np.all(np.isfinite(ge["b_corr"])) else 0.0
    sa = float(np.max(ae["b_drift"])) if np.all(np.isfinite(ae["b_corr"])) else 0.0
    if sg > 0 or sa > 0:
        tau = float(ge["b_corr"][0]) if sg > 0 else float(ae["b_corr"][0])
        eff["bias_instability"] = {"gyro_sigma": sg, "accel_sigma": sa, "tau": tau}
    truth = ec.truth_json(gyro_bias=ge["b"], accel_bias=ae["b"], gyro_M=np.zeros((3, 3)),
                          accel_M=np.zeros((3, 3)), effects=eff,
                          arw_rad_per_sqrt_s=float(ge["arw"][0]),
                          vrw_mps_per_sqrt_s=float(ae["vrw"][0]))
    extra = {k: cfg[k] for k in ("gyro_vib", "accel_vib") if k in cfg}
    if extra:
        truth_extra = os.path.join(work, os.path.basename(os.path.normpath(out)) + ".uncatalogued.json")
        with open(truth_extra, "w") as f:
            json.dump(extra, f)
    arw = float(ge["arw"][0]) * 180 / math.pi * 60
    vrw = float(ae["vrw"][0]) / 9.80665e-6
    ec.write_archive(out, profile, w * ts, a * ts, serial=serial, gravity_mps2=g,
                     arw_deg_per_sqrt_h=max(arw, 1e-6), vrw_ug_per_sqrt_hz=max(vrw, 1e-3),
                     truth=truth, generator="gnss-ins-sim imu_model/pathgen via tools/extsim/gis_make.py",
                     grade=cfg.get("grade"))
    return truth


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--gis", required=True, help="gnss-ins-sim checkout (has gnss_ins_sim/)")
    ap.add_argument("--imucal", required=True)
    ap.add_argument("--sequence", default="factory-std")
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--work", required=True)
    ap.add_argument("--cfg", required=True, help="JSON text or file")
    ap.add_argument("--out", required=True)
    ap.add_argument("--serial", default="GIS-1")
    a = ap.parse_args()
    cfg = json.load(open(a.cfg)) if os.path.exists(a.cfg) else json.loads(a.cfg)
    truth = make(a.gis, a.imucal, a.sequence, a.work, cfg, a.out, a.serial, a.rate)
    print(json.dumps(truth["effects"]))


if __name__ == "__main__":
    main()
