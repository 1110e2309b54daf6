"""Shared pieces of the external-simulator converters (tools/extsim/README.md).

* the turntable profile of a sequence, taken from an `imucal simulate` run of it (table.csv:
  encoder angles and rest flags on the IMU's time stamps, run.toml: site, table geometry and the
  sequence's name and sha256), turned into the body attitude C_bn (body -> NED) at every stamp;
* a run-archive writer (db/archive/FORMAT.md) for increments in the archive's convention;
* the truth.json of a run in the catalogue's names (imucal effects).

Python 3 + numpy only (Debian python3-numpy).  Nothing here imports a simulator.
"""
import hashlib
import json
import math
import os
import shutil
import subprocess
import tomllib

import numpy as np

G_ARCHIVE = 9.80665  # the archive's µg


def rot(axis, angle):
    """Active rotation matrix about a unit axis (Rodrigues), as calib::core::TableModel's R."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def rz(a):
    return rot([0, 0, 1], a)


def euler_C_bn(roll, pitch, yaw):
    """C_bn = Rz(yaw) Ry(pitch) Rx(roll) (calib::core::euler_to_C_bn)."""
    return rz(yaw) @ rot([0, 1, 0], pitch) @ rot([1, 0, 0], roll)


class Profile:
    """The table profile of one sequence at one IMU rate."""

    def __init__(self, imucal, sequence, workdir, rate_hz=100.0):
        self.sequence = sequence
        self.rate_hz = rate_hz
        self.dir = os.path.join(workdir, f"template-{os.path.basename(sequence)}-{rate_hz:g}")
        if not os.path.exists(os.path.join(self.dir, "table.csv")):
            os.makedirs(workdir, exist_ok=True)
            subprocess.run([imucal, "simulate", "--sequence", sequence, "--out", self.dir,
                            "--rate", f"{rate_hz:g}", "--seed", "1", "--overwrite"],
                           check=True, stdout=subprocess.DEVNULL)
        with open(os.path.join(self.dir, "run.toml"), "rb") as f:
            self.toml = tomllib.load(f)
        with open(os.path.join(self.dir, "table.csv")) as f:
            self.table_lines = f.read().splitlines()
        rows = [ln.split(",") for ln in self.table_lines[1:]]
        self.t_text = [r[0] for r in rows]
        tab = np.array([[float(x) for x in r] for r in rows])
        self.t = tab[:, 0]
        self.outer = np.radians(tab[:, 1])
        self.inner = np.radians(tab[:, 2])
        self.at_rest = tab[:, 3].astype(int)
        tg = self.toml.get("table", {})
        self.outer_axis = tg.get("outer_axis", [1.0, 0.0, 0.0])
        self.inner_axis = tg.get("inner_axis", [0.0, 0.0, 1.0])
        self.heading = math.radians(tg.get("heading_deg", 0.0))
        m = [math.radians(x) for x in tg.get("mount_rpy_deg", [0.0, 0.0, 0.0])]
        self.C_bp = euler_C_bn(*m)
        st = self.toml["station"]
        self.lat_deg, self.lon_deg, self.height_m = st["lat_deg"], st["lon_deg"], st["height_m"]
        dt = np.diff(self.t)
        if abs(self.t[0] - 1.0 / rate_hz) > 1e-9 or np.max(np.abs(dt - 1.0 / rate_hz)) > 1e-9:
            raise SystemExit(f"{self.dir}/table.csv: time stamps are not k/{rate_hz:g} s")

    def C_bn(self, outer, inner):
        """Table reference C_bn = C_tn R(outer_axis, outer) R(inner_axis, inner) C_bp (FORMAT.md)."""
        return rz(self.heading) @ rot(self.outer_axis, outer) @ rot(self.inner_axis, inner) @ self.C_bp

    def attitudes(self):
        """t (first row t = 0, the table still at its first row's angles) and C_bn per stamp."""
        t = np.concatenate([[0.0], self.t])
        o = np.concatenate([[self.outer[0]], self.outer])
        i = np.concatenate([[self.inner[0]], self.inner])
        if self.outer[0] != self.outer[1] or self.inner[0] != self.inner[1]:
            raise SystemExit("the sequence does not start with the table still")
        return t, np.array([self.C_bn(a, b) for a, b in zip(o, i)])

    def write_attitude_csv(self, path):
        t, C = self.attitudes()
        with open(path, "w") as f:
            f.write("t_s,c11,c12,c13,c21,c22,c23,c31,c32,c33\n")
            for tk, Ck in zip(t, C):
                f.write(",".join([repr(float(tk))] + [repr(float(x)) for x in Ck.reshape(-1)]) + "\n")


def fmt(x):
    """Shortest round-trip decimal (Python repr), never 'nan'/'inf'."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"non-finite value {x}")
    r = repr(x)
    return "0" if r == "-0.0" else r


def write_archive(out_dir, profile, dtheta, dv, *, serial, gravity_mps2, arw_deg_per_sqrt_h,
                  vrw_ug_per_sqrt_hz, truth, generator, grade=None, dv_convention="interval_start"):
    """Write a run archive (imu.csv, table.csv, run.toml, truth.json) into out_dir (replaced)."""
    n = len(profile.t)
    if dtheta.shape != (n, 3) or dv.shape != (n, 3):
        raise ValueError(f"increments {dtheta.shape}/{dv.shape} do not match the table's {n} rows")
    tmp = out_dir + ".tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    os.makedirs(tmp)
    with open(os.path.join(tmp, "imu.csv"), "w") as f:
        f.write("t_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps\n")
        for k in range(n):
            f.write(profile.t_text[k] + "," + ",".join(fmt(x) for x in dtheta[k]) + ","
                    + ",".join(fmt(x) for x in dv[k]) + "\n")
    with open(os.path.join(tmp, "table.csv"), "w") as f:
        f.write("\n".join(profile.table_lines) + "\n")
    seq = profile.toml["sequence"]
    tg = profile.toml.get("table", {})
    lines = [
        "# Run archive metadata (db/archive/FORMAT.md), written by tools/extsim",
        f"# generator: {generator}",
        f'serial = "{serial}"',
        'software_version = "extsim"',
        'reference = "table"',
        "",
        "[station]",
        'name = "extsim"',
        f"lat_deg = {fmt(profile.lat_deg)}",
        f"lon_deg = {fmt(profile.lon_deg)}",
        f"height_m = {fmt(profile.height_m)}",
        f"gravity_mps2 = {fmt(gravity_mps2)}",
        "",
        "[imu]",
        f"rate_hz = {fmt(profile.rate_hz)}",
        f'dv_convention = "{dv_convention}"',
        "",
        "[table]",
        f"outer_axis = [{', '.join(fmt(x) for x in tg.get('outer_axis', [1.0, 0.0, 0.0]))}]",
        f"inner_axis = [{', '.join(fmt(x) for x in tg.get('inner_axis', [0.0, 0.0, 1.0]))}]",
        f"heading_deg = {fmt(tg.get('heading_deg', 0.0))}",
        f"mount_rpy_deg = [{', '.join(fmt(x) for x in tg.get('mount_rpy_deg', [0.0, 0.0, 0.0]))}]",
        "",
        "[sequence]",
        f'name = "{seq["name"]}"',
        f'sha256 = "{seq["sha256"]}"',
        "",
    ]
    if grade:
        lines += ["[prior]", f'grade = "{grade}"', ""]
    lines += ["[noise]", f"arw_deg_per_sqrt_h = {fmt(arw_deg_per_sqrt_h)}",
              f"vrw_ug_per_sqrt_hz = {fmt(vrw_ug_per_sqrt_hz)}", ""]
    with open(os.path.join(tmp, "run.toml"), "w") as f:
        f.write("\n".join(lines))
    with open(os.path.join(tmp, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1, sort_keys=True)
    shutil.rmtree(out_dir, ignore_errors=True)
    os.rename(tmp, out_dir)


def truth_json(*, gyro_bias, accel_bias, gyro_M, accel_M, effects, arw_rad_per_sqrt_s,
               vrw_mps_per_sqrt_s):
    """truth.json (FORMAT.md): params, catalogue-named effects (SI), noise."""
    lst = lambda v: [float(x) for x in np.asarray(v).reshape(-1)]
    mat = lambda m: [lst(r) for r in np.asarray(m).reshape(3, 3)]
    return {
        "params": {"accel_bias_mps2": lst(accel_bias), "accel_M": mat(accel_M),
                   "gyro_bias_radps": lst(gyro_bias), "gyro_M": mat(gyro_M),
                   "table_misalignment_rad": [0.0, 0.0, 0.0]},
        "effects": effects,
        "noise": {"arw_rad_per_sqrt_s": float(arw_rad_per_sqrt_s),
                  "vrw_mps_per_sqrt_s": float(vrw_mps_per_sqrt_s),
                  "gyro_bias_instability_radps": 0.0, "gyro_bias_tau_s": 1000.0,
                  "accel_bias_instability_mps2": 0.0, "accel_bias_tau_s": 1000.0,
                  "dtheta_lsb_rad": 0.0, "dv_lsb_mps": 0.0},
    }


def file_sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for b in iter(lambda: f.read(1 << 20), b""):
            h.update(b)
    return h.hexdigest()
