#!/usr/bin/env python3
"""One run archive written by PSINS (Gongmin Yan's Matlab INS toolbox, run in Octave).

    psins_make.py --psins PSINS_CHECKOUT --imucal BIN --sequence factory-std --work DIR \
                  --cfg '{"seed": 3, "eb": [...], ..., "Ka2": [50, -40, 30]}' --out ARCHIVE

The attitude profile is the sequence's turntable profile (extsim_common.Profile); PSINS turns it
into error-free increments with its own Earth model (psins_ideal.m, cached per sequence in
--work), adds its SIMU errors with imuerrset/imuadderr (psins_run.m; --cfg in imuerrset's units,
see psins_run.m), and this script converts PSINS's raw increments (wm, vm) into the archive's
convention with PSINS's own coning/sculling relations (psins cnscl, one previous subsample):

    dtheta_k = wm_k + wm_{k-1} x wm_k / 12
    dv_k     = vm_k + wm_k x vm_k / 2 + (wm_{k-1} x vm_k + vm_{k-1} x wm_k) / 12

(PSINS's velocity increment in the body frame at the start of the interval, which is the
archive's "interval_start" dv).  truth.json names the injected effects by the catalogue's names
from the SI error structure PSINS used.
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import extsim_common as ec  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


def octave(script, *args):
    subprocess.run(["octave-cli", "--no-gui", "-q", os.path.join(HERE, script), *args], check=True,
                   stdout=subprocess.DEVNULL)


def ideal(psins, profile, work):
    """Cached error-free PSINS increments of the profile: (Octave binary path, PSINS g)."""
    path = os.path.join(work, f"psins-ideal-{os.path.basename(profile.dir)}.bin")
    if not os.path.exists(path):
        att = os.path.join(work, f"att-{os.path.basename(profile.dir)}.csv")
        profile.write_attitude_csv(att)
        octave("psins_ideal.m", psins, att, ec.fmt(profile.lat_deg), ec.fmt(profile.lon_deg),
               ec.fmt(profile.height_m), path + ".tmp")
        os.rename(path + ".tmp", path)
    return path


def to_interval_start(wm, vm):
    wm1 = np.vstack([np.zeros(3), wm[:-1]])
    vm1 = np.vstack([np.zeros(3), vm[:-1]])
    dth = wm + np.cross(wm1, wm) / 12
    dv = vm + np.cross(wm, vm) / 2 + (np.cross(wm1, vm) + np.cross(vm1, wm)) / 12
    return dth, dv


def psins_gravity(ideal_path):
    """g saved by psins_ideal.m (Octave text-free binary: read back through Octave)."""
    cache = ideal_path + ".g"
    if not os.path.exists(cache):
        out = subprocess.run(["octave-cli", "--no-gui", "-q", "--eval",
                              f"S=load('{ideal_path}'); printf('%.17g', S.g);"],
                             check=True, capture_output=True, text=True).stdout
        with open(cache, "w") as f:
            f.write(out.strip())
    with open(cache) as f:
        return float(f.read())


def truth_from_err(e):
    """Catalogue effects (imucal effects) from PSINS's SI error structure (psins_run.m)."""
    v = lambda k: np.asarray(e[k], float).reshape(-1)
    eff = {}
    if np.any(v("Ka2") != 0):
        k2 = v("Ka2")
        eff["accel_quadratic_k2"] = {"k2_x": k2[0], "k2_y": k2[1], "k2_z": k2[2]}
    if "Kap" in e:
        kap = v("Kap")
        eff["accel_asymmetry"] = {"kap_x": kap[0], "kap_y": kap[1], "kap_z": kap[2]}
    if "r" in e and np.any(v("r") != 0):
        r = np.asarray(e["r"], float).reshape(3, 3)  # row i = lever arm of accelerometer i
        eff["size_effect"] = {f"r_{a}_{b}": r[i, j] for i, a in enumerate("xyz")
                              for j, b in enumerate("xyz")}
    if "gSens" in e:
        G = np.asarray(e["gSens"], float).reshape(3, 3)
        eff["gyro_g_sensitivity"] = {f"G_{a}{b}": G[i, j] for i, a in enumerate("xyz")
                                     for j, b in enumerate("xyz")}
    if "dtGA" in e and float(e["dtGA"]) != 0:
        # PSINS: dtGA = T_acc - T_gyro > 0 ("acc later"): the accelerometer increment of sample k
        # is that of [t_{k-1} + dtGA, t_k + dtGA], so f_meas = f(t + dtGA) = f - dtGA (w x f).
        # The catalogue's model is df = t_GA (w x f), so t_GA = -dtGA (imucal diagnose fits
        # t_GA = -1.00 ms on a PSINS run with dtGA = +1 ms; the catalogue's wording "the
        # accelerometers sample t_GA after the gyros" reads the other way: see README.md).
        eff["gyro_accel_skew"] = {"t_GA": -float(e["dtGA"])}
    sg, sa = v("sigma_g"), v("sigma_a")
    if np.any(sg > 0) or np.any(sa > 0):
        tau = float(v("tau_g")[0]) if np.any(sg > 0) else float(v("tau_a")[0])
        eff["bias_instability"] = {"gyro_sigma": float(sg.max()), "accel_sigma": float(sa.max()),
                                   "tau": tau}
    for name in eff:
        eff[name] = {k: float(x) for k, x in eff[name].items()}
    return eff


def make(psins, imucal, sequence, work, cfg, out, serial, rate_hz=100.0):
    os.makedirs(work, exist_ok=True)
    profile = ec.Profile(imucal, sequence, work, rate_hz)
    ideal_path = ideal(psins, profile, work)
    g = psins_gravity(ideal_path)
    tag = os.path.basename(os.path.normpath(out))
    cfg_path = os.path.join(work, f"{tag}.cfg.json")
    raw_path = os.path.join(work, f"{tag}.raw.txt")
    err_path = os.path.join(work, f"{tag}.err.json")
    with open(cfg_path, "w") as f:
        json.dump(cfg, f)
    octave("psins_run.m", psins, ideal_path, cfg_path, raw_path, err_path)
    raw = np.loadtxt(raw_path)
    with open(err_path) as f:
        e = json.load(f)
    if raw.shape[0] != len(profile.t) or np.max(np.abs(raw[:, 6] - profile.t)) > 1e-9:
        raise SystemExit(f"{raw_path}: {raw.shape[0]} rows / time stamps do not match the table's")
    dth, dv = to_interval_start(raw[:, 0:3], raw[:, 3:6])
    web = float(np.asarray(e["web"]).reshape(-1)[0])
    wdb = float(np.asarray(e["wdb"]).reshape(-1)[0])
    truth = ec.truth_json(gyro_bias=e["eb"], accel_bias=e["db"], gyro_M=e["dKg"],
                          accel_M=e["dKa"], effects=truth_from_err(e),
                          arw_rad_per_sqrt_s=web, vrw_mps_per_sqrt_s=wdb)
    arw = web * 180 / np.pi * 60  # rad/sqrt(s) -> deg/sqrt(h)
    vrw = wdb / 9.80665e-6        # m/s^2/sqrt(Hz) -> the archive's ug/sqrt(Hz)
    ec.write_archive(out, profile, dth, dv, serial=serial, gravity_mps2=g,
                     arw_deg_per_sqrt_h=max(arw, 1e-6), vrw_ug_per_sqrt_hz=max(vrw, 1e-3),
                     truth=truth, generator="PSINS imuerrset/imuadderr via tools/extsim/psins_make.py")
    for p in (raw_path, err_path):
        os.remove(p)
    return truth


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--psins", required=True, help="PSINS checkout (has base/ and psinsenvi.m)")
    ap.add_argument("--imucal", required=True)
    ap.add_argument("--sequence", default="factory-std")
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--work", required=True, help="scratch directory (profile, PSINS cache)")
    ap.add_argument("--cfg", required=True, help="JSON text or file: imuerrset arguments")
    ap.add_argument("--out", required=True)
    ap.add_argument("--serial", default="PSINS-1")
    a = ap.parse_args()
    cfg = json.load(open(a.cfg)) if os.path.exists(a.cfg) else json.loads(a.cfg)
    cfg.setdefault("seed", 1)
    truth = make(a.psins, a.imucal, a.sequence, a.work, cfg, a.out, a.serial, a.rate)
    print(json.dumps(truth["effects"]))


if __name__ == "__main__":
    main()
