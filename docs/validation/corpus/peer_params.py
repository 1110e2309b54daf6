#!/usr/bin/env python3
"""The peers' published calibrations of the corpus recordings as this project's parameter sets.

Pure Python 3 (standard library only), read-only except for OUT_DIR:
    python3 docs/validation/corpus/peer_params.py OUT_DIR [--corpus DIR] [--archives DIR]
then, per unit, e.g.
    imucal check OUT_DIR/mikoff0.json <archive of imu0.log> --json

Writes to OUT_DIR one parameter-set JSON (db/archive/param_json.cpp: accel_bias_mps2, accel_M,
gyro_bias_radps, gyro_M, table_misalignment_rad, plus a "source" object saying where the numbers
came from) per peer calibration:
    mikoff0.json           IMU-calib, unit #1 (data/imu0.log), the README's table (image)
    mikoff0_notebook.json  IMU-calib, data/imu0.log, Example.ipynb's printed output (4 decimals)
    mikoff1.json           IMU-calib, unit #2 (data/imu1.log), the table
    mikoff3.json           IMU-calib, unit #4 (data/imu3.log), the table
    suarez_mpu6050.json    ImuCalibration, params_acc.csv / params_gyro.csv (MPU-6050)
The numbers are hard-coded from the corpus folders' peer_result.txt (mikoff_mpu9150/ and
suarez_mpu6050/, kept outside the checkout in $IMUCAL_CORPUS_DATA as corpus.md says).

This product (calib/core/imu_error_model.hpp, ImuCompensator) corrects the imported raw values
        f = (I + accel_M)^-1 (f_raw - accel_bias),   w = (I + gyro_M)^-1 (w_raw - gyro_bias),
with f_raw, w_raw what `imucal import` made of the file: the file's numbers times the nominal
scale of the folder's import.toml (IMU-calib: scale 1, the files are SI; ImuCalibration:
counts x 9.80665/16384 m/s^2 and counts x (pi/180)/131 rad/s), offset 0.

IMU-calib (github.com/mikoff/imu-calib @ 12dff577725dbc7bd7161431e4142b6249395fec):
  code/imu_model.py:9-20   M = [[1+S_X, NO_Y, NO_Z], [0, 1+S_Y, NO_X], [0, 0, 1+S_Z]], b = B
  code/imu_model.py:22-27  E(eps) = I + skew(eps)   ("gyroscope frame to accelerometer frame")
  code/helpers.py:47-59    accelerometer   f = M_a^-1 (f_raw - b_a)
  code/helpers.py:61-74    gyroscope       w = M_g^-1 E^-1 w_raw - M_g^-1 b_g
                           (the same expressions as code/cost_functions.py:10-17 and 43-47,71)
  calibrate_real_imu.py:39,54-55: the gyros are fitted against the CALIBRATED accelerometer, so
  both outputs are in the calibrated accelerometer's frame.
  Exact map:  accel_M = M_a - I,            accel_bias = b_a
              gyro_M  = E(eps) M_g - I,     gyro_bias  = E(eps) b_g
  since (E M_g)^-1 (w_raw - E b_g) = M_g^-1 E^-1 w_raw - M_g^-1 b_g.  E is the peer's own
  first-order matrix I + skew(eps), used as they use it (not an exact rotation).
  Table units: s in %, m in degrees (m_yz = NO_X, m_xy = NO_Y, m_xz = NO_Z: the notebook's imu0
  NO 0.0021 0.0003 0.0055 rad = 0.120 0.017 0.315 deg is the table's #1 m_yz m_xy m_xz 0.123 0.02
  0.317, and the positions in M), accelerometer b in m/s^2, gyro b in deg/s, eps in degrees. The
  table's gyro b are 0.001 rad/s steps printed in deg/s (1.146 = 0.020 rad/s, 4.813 = 0.084):
  the rad/s value is recovered (and the reading asserted); the rounding, up to 0.5 mrad/s =
  0.029 deg/s, is the table's largest imprecision.

ImuCalibration (github.com/tomisuarez2/ImuCalibration @ c86ea2531da0da7929b884b52d8955c0ea0615ff):
  ImuCalibrationModules/imu_calibration.py:395-437  a = T_a K_a (c_a + b_a),
      T_a = [[1, -a_yz, a_zy], [0, 1, -a_zx], [0, 0, 1]] built as float32 (l. 422-426),
      K_a = diag(s_a); c_a raw counts; b_a in counts, ADDED
  ImuCalibrationModules/imu_calibration.py:439-481 with 848 (and 678-684, 698):
      w = T_g K_g (c_g - b_g),
      T_g = [[1, -g_yz, g_zy], [g_xz, 1, -g_zx], [-g_xy, g_yx, 1]] built as float32 (l. 466-470),
      K_g = diag(s_g); b_g = mean raw counts of the first t_init (not fitted), SUBTRACTED
  The gyro fit (gyro_residuals, l. 512-574) carries the calibrated accelerometer's gravity, so
  both outputs are in the accelerometer's (T_a) frame.
  With the product's raw values f_raw = sa c_a, w_raw = sg c_g (sa, sg the nominal scales):
  Exact map:  accel_M = sa K_a^-1 T_a^-1 - I,   accel_bias = -sa b_a
              gyro_M  = sg K_g^-1 T_g^-1 - I,   gyro_bias  =  sg b_g
  (T_a, T_g with their entries rounded to float32, as the peer's code builds them.)

Self-check (always run): for synthetic raw vectors, each peer's model implemented as its code
does it and the product's compensation with the converted set, as read back from the written
JSON, agree to 1e-9 (m/s^2, rad/s); the script exits 1 otherwise.
--corpus DIR (the folder holding suarez_mpu6050/): also recompute, from the recording's counts,
the peer's published calibrated mean specific force at its 10 rests (peer_result.txt,
calibrated_accel_avg_data.csv) with the peer model and with the product's compensation.
--archives DIR (holding the imported archive s_example_data_calibration/): the same from the
archive's imu.csv (dv / dt), i.e. through `imucal import`.
"""
import argparse
import json
import lzma
import math
import os
import random
import struct
import sys

# ------------------------------------------------------------------------------------------------
# 3x3 algebra on lists
# ------------------------------------------------------------------------------------------------


def eye():
    return [[1.0 if r == c else 0.0 for c in range(3)] for r in range(3)]


def mm(a, b):
    return [[sum(a[r][k] * b[k][c] for k in range(3)) for c in range(3)] for r in range(3)]


def mv(a, v):
    return [sum(a[r][k] * v[k] for k in range(3)) for r in range(3)]


def madd(a, b, sb=1.0):
    return [[a[r][c] + sb * b[r][c] for c in range(3)] for r in range(3)]


def vsub(a, b):
    return [a[i] - b[i] for i in range(3)]


def diag(v):
    return [[v[r] if r == c else 0.0 for c in range(3)] for r in range(3)]


def mscale(a, s):
    return [[s * a[r][c] for c in range(3)] for r in range(3)]


def inv3(a):
    """Inverse by Gauss-Jordan with partial pivoting (as accurate as numpy.linalg.inv here)."""
    m = [list(a[r]) + eye()[r] for r in range(3)]
    for col in range(3):
        piv = max(range(col, 3), key=lambda r: abs(m[r][col]))
        if m[piv][col] == 0.0:
            raise ValueError("singular matrix")
        m[col], m[piv] = m[piv], m[col]
        p = m[col][col]
        m[col] = [x / p for x in m[col]]
        for r in range(3):
            if r != col and m[r][col] != 0.0:
                f = m[r][col]
                m[r] = [x - f * y for x, y in zip(m[r], m[col])]
    return [row[3:] for row in m]


def skew(v):
    """code/imu_model.py:3-7 of IMU-calib."""
    return [[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]]


def f32(x):
    """x rounded to IEEE single precision (numpy's dtype=np.float32)."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


# ------------------------------------------------------------------------------------------------
# The product's compensation (calib/core/imu_error_model.hpp, ImuCompensator)
# ------------------------------------------------------------------------------------------------


def product_compensate(m, bias, raw):
    return mv(inv3(madd(eye(), m)), vsub(raw, bias))


def param_set_json(accel_bias, accel_m, gyro_bias, gyro_m, source):
    return {
        "accel_bias_mps2": list(accel_bias),
        "accel_M": [list(r) for r in accel_m],
        "gyro_bias_radps": list(gyro_bias),
        "gyro_M": [list(r) for r in gyro_m],
        "table_misalignment_rad": [0.0, 0.0, 0.0],
        "source": source,
    }


# ------------------------------------------------------------------------------------------------
# IMU-calib (mikoff/imu-calib)
# ------------------------------------------------------------------------------------------------

MIKOFF_REPO = "https://github.com/mikoff/imu-calib"
MIKOFF_COMMIT = "12dff577725dbc7bd7161431e4142b6249395fec"
DEG = math.pi / 180.0

# mikoff_mpu9150/peer_result.txt, (A): the README's table images/real_imu.png,
# transcribed (checked against the image, 2026-11-29). Units #1, #2, #4 = data/imu0, imu1, imu3.
# Per sensor: s x y z (%), m_yz m_xy m_xz (deg), b x y z (accel m/s^2, gyro deg/s), eps x y z (deg).
MIKOFF_TABLE = {
    1: {"acc": ([0.363, 0.315, 0.647], [0.123, 0.02, 0.317], [0.103, 0.097, 0.344]),
        "gyr": ([0.041, 0.457, 0.826], [-0.034, -0.12, 0.806], [1.146, -0.401, 1.261]),
        "eps": [0.03, -0.364, -0.074]},
    2: {"acc": ([0.471, 0.482, 0.932], [-0.284, -0.01, 0.145], [0.09, 0.07, 0.338]),
        "gyr": ([0.007, 0.26, -0.179], [-0.639, 0.21, 0.262], [-0.573, 1.089, 0.286]),
        "eps": [-0.565, 0.013, 0.069]},
    4: {"acc": ([0.263, 0.448, 0.721], [-0.009, -0.028, -0.104], [0.065, 0.092, -0.009]),
        "gyr": ([0.227, 0.599, 0.308], [-0.105, 0.025, 0.072], [-1.261, 1.031, 4.813]),
        "eps": [-0.102, -0.129, 0.015]},
}
# mikoff_mpu9150/peer_result.txt, (B): Example.ipynb's printed output for
# data/imu0.log, theta in the peer's order [S_X S_Y S_Z NO_X NO_Y NO_Z B_X B_Y B_Z (E_X E_Y E_Z)],
# scales and angles dimensionless / rad, accel B in m/s^2, gyro B in rad/s (4 decimals).
MIKOFF_NOTEBOOK_IMU0_ACC = [0.0036, 0.0032, 0.0065, 0.0021, 0.0003, 0.0055, 0.1027, 0.0967, 0.3444]
MIKOFF_NOTEBOOK_IMU0_GYR = [0.0002, 0.0045, 0.0082, -0.0006, -0.0023, 0.0140, 0.0196, -0.0067,
                            0.0216, 0.0005, -0.0063, -0.0014]


def mikoff_theta_from_table(unit):
    """The table's column as the peer's theta vectors (acc 9, gyr 9, eps 3), SI / rad."""
    t = MIKOFF_TABLE[unit]

    def sensor(s_pct, m_deg, b, b_scale):
        m_yz, m_xy, m_xz = m_deg
        return ([x / 100.0 for x in s_pct] + [m_yz * DEG, m_xy * DEG, m_xz * DEG]
                + [x * b_scale for x in b])

    acc = sensor(*t["acc"], 1.0)
    gyr = sensor(*t["gyr"][:2], [0.0, 0.0, 0.0], 1.0)
    # Gyro b: printed in deg/s from a value rounded to 0.001 rad/s; recover that value.
    for i, b_deg in enumerate(t["gyr"][2]):
        b_rad = round(b_deg * DEG, 3)
        assert abs(b_rad - b_deg * DEG) < 1e-5, (unit, b_deg)
        gyr[6 + i] = b_rad
    eps = [x * DEG for x in t["eps"]]
    return acc, gyr, eps


def mikoff_sensor_error_model(theta):
    """code/imu_model.py:9-20."""
    kx, ky, kz, nox, noy, noz, bx, by, bz = theta
    m = [[1.0 + kx, noy, noz], [0.0, 1.0 + ky, nox], [0.0, 0.0, 1.0 + kz]]
    return m, [bx, by, bz]


def mikoff_misalignment(eps):
    """code/imu_model.py:22-27."""
    return madd(eye(), skew(eps))


def mikoff_calibrate_acc(theta, f):
    """code/helpers.py:47-59: C @ (measurement - b), C = inv(M)."""
    m, b = mikoff_sensor_error_model(theta)
    return mv(inv3(m), vsub(f, b))


def mikoff_calibrate_gyr(theta, eps, w):
    """code/helpers.py:61-74: C @ Rm @ w - C @ b, C = inv(M), Rm = inv(misalignment(eps))."""
    m, b = mikoff_sensor_error_model(theta)
    c = inv3(m)
    rm = inv3(mikoff_misalignment(eps))
    return vsub(mv(mm(c, rm), w), mv(c, b))


def mikoff_to_params(acc, gyr, eps):
    ma, ba = mikoff_sensor_error_model(acc)
    mg, bg = mikoff_sensor_error_model(gyr)
    e = mikoff_misalignment(eps)
    return ba, madd(ma, eye(), -1.0), mv(e, bg), madd(mm(e, mg), eye(), -1.0)


# ------------------------------------------------------------------------------------------------
# ImuCalibration (tomisuarez2/ImuCalibration)
# ------------------------------------------------------------------------------------------------

SUAREZ_REPO = "https://github.com/tomisuarez2/ImuCalibration"
SUAREZ_COMMIT = "c86ea2531da0da7929b884b52d8955c0ea0615ff"
# suarez_mpu6050/peer_result.txt ('optmization result data/params_acc.csv' and
# params_gyro.csv, verbatim): acc [a_yz a_zy a_zx, s_x s_y s_z, b_x b_y b_z (counts)],
# gyro [g_yz g_zy g_xz g_zx g_xy g_yx, s_x s_y s_z, b_x b_y b_z (counts)].
SUAREZ_ACC = [1.043860522409845042e-05, 2.098452816658057195e-06, 2.005985606930172646e-06,
              6.020083400010406817e-04, 5.968449488725015338e-04, 5.859241382355084718e-04,
              -7.115163422327075295e+02, 3.585054836108664063e+02, 1.840128451085784491e+03]
SUAREZ_GYR = [-9.967394130262499652e-03, 9.183836411500549690e-03, -2.912198601931083493e-03,
              7.234881652289322680e-03, -9.841957371310869340e-03, 5.795923574753897821e-03,
              1.373743743438648286e-04, 1.329249743689399734e-04, 1.339443406342994032e-04,
              -4.274617614746093750e+02, 1.479479370117187500e+02, -8.072266387939453125e+01]
# The peer's 10 rests (static_intervals.csv, sample indices [start, end)) and its calibrated mean
# specific force there (calibrated_accel_avg_data.csv), both from peer_result.txt.
SUAREZ_REST_STARTS = [150, 4297, 4934, 5585, 6205, 7018, 7570, 8297, 9094, 9662]
SUAREZ_REST_ENDS = [3613, 4299, 4946, 5690, 6368, 7046, 7765, 8457, 9158, 10095]
SUAREZ_REST_MEANS = [
    [-5.253836034167722602e-01, -2.664464290149970438e-01, 9.786775298604101891e+00],
    [4.999328593244395380e-01, 4.503424103723330796e-01, -9.782514149388305214e+00],
    [-9.787760019878318118e+00, -3.576050771965020303e-01, -6.284260773715067971e-01],
    [9.790692520735003512e+00, -2.135061634078135595e-01, 4.697074065563215939e-01],
    [-1.954982920569014460e-01, -9.789018514104974145e+00, 5.401750836268839340e-01],
    [1.797593085849830408e-01, 9.805526373944315921e+00, 7.692276388805303552e-03],
    [-2.798005419134430571e-01, 6.782410927552442459e+00, 7.076764581914331664e+00],
    [-6.206336980382324287e-01, -5.770965849120766045e+00, 7.906330739369928473e+00],
    [-8.742213625768009422e+00, -1.478739345838613328e-01, 4.422447556700162430e+00],
    [4.761591720988588072e+00, 2.235259426612158651e-02, 8.579281777879646853e+00],
]
# The nominal scales `imucal import` applied (suarez_mpu6050/import.toml).
SUAREZ_ACC_NOMINAL = 5.985504150390625e-4   # 9.80665/16384 m/s^2 per count
SUAREZ_GYR_NOMINAL = 1.3323124061025417e-4  # (pi/180)/131 rad/s per count


def suarez_t_acc(p):
    """imu_calibration.py:422-426 (float32 entries)."""
    yz, zy, zx = (f32(x) for x in p[:3])
    return [[1.0, -yz, zy], [0.0, 1.0, -zx], [0.0, 0.0, 1.0]]


def suarez_t_gyr(p):
    """imu_calibration.py:466-470 (float32 entries)."""
    yz, zy, xz, zx, xy, yx = (f32(x) for x in p[:6])
    return [[1.0, -yz, zy], [xz, 1.0, -zx], [-xy, yx, 1.0]]


def suarez_apply_acc(p, counts):
    """imu_calibration.py:395-437: T @ K @ (raw + bias)."""
    return mv(mm(suarez_t_acc(p), diag(p[3:6])), [counts[i] + p[6 + i] for i in range(3)])


def suarez_apply_gyr(p, counts):
    """imu_calibration.py:439-481 as show_data (l. 848) calls it: T @ K @ (raw - bias)."""
    return mv(mm(suarez_t_gyr(p), diag(p[6:9])), [counts[i] - p[9 + i] for i in range(3)])


def suarez_to_params(pa, pg, sa=SUAREZ_ACC_NOMINAL, sg=SUAREZ_GYR_NOMINAL):
    a = mscale(mm(suarez_t_acc(pa), diag(pa[3:6])), 1.0 / sa)  # corrected = a (f_raw + sa b_a)
    g = mscale(mm(suarez_t_gyr(pg), diag(pg[6:9])), 1.0 / sg)  # corrected = g (w_raw - sg b_g)
    return ([-sa * x for x in pa[6:9]], madd(inv3(a), eye(), -1.0),
            [sg * x for x in pg[9:12]], madd(inv3(g), eye(), -1.0))


# ------------------------------------------------------------------------------------------------


def units():
    """name -> (params tuple, peer model functions, raw -> product raw, source, raw generator)."""
    out = {}
    for name, unit, log in (("mikoff0", 1, "imu0"), ("mikoff1", 2, "imu1"), ("mikoff3", 4, "imu3")):
        acc, gyr, eps = mikoff_theta_from_table(unit)
        out[name] = ("mikoff", (acc, gyr, eps), {
            "peer": "IMU-calib (Mikov, Reginya, Moschevikin, ICINS 2020)",
            "repository": MIKOFF_REPO, "commit": MIKOFF_COMMIT,
            "recording": "data/%s.log" % log,
            "numbers": "README table images/real_imu.png, unit #%d (transcribed; "
                       "mikoff_mpu9150/peer_result.txt (A))" % unit,
            "peer_theta_acc": acc, "peer_theta_gyr": gyr, "peer_eps_rad": eps,
            "map": "accel_M = M_a - I, accel_bias = b_a; gyro_M = (I + skew(eps)) M_g - I, "
                   "gyro_bias = (I + skew(eps)) b_g (exact; code/helpers.py:47-74)"})
    acc, gyr, eps = MIKOFF_NOTEBOOK_IMU0_ACC, MIKOFF_NOTEBOOK_IMU0_GYR[:9], \
        MIKOFF_NOTEBOOK_IMU0_GYR[9:]
    out["mikoff0_notebook"] = ("mikoff", (acc, gyr, eps), {
        "peer": "IMU-calib (Mikov, Reginya, Moschevikin, ICINS 2020)",
        "repository": MIKOFF_REPO, "commit": MIKOFF_COMMIT, "recording": "data/imu0.log",
        "numbers": "Example.ipynb, cell 'Calibrate real IMU', printed output (4 decimals; "
                   "mikoff_mpu9150/peer_result.txt (B)); a different run from the table",
        "peer_theta_acc": acc, "peer_theta_gyr": gyr, "peer_eps_rad": eps,
        "map": "as mikoff0.json"})
    out["suarez_mpu6050"] = ("suarez", (SUAREZ_ACC, SUAREZ_GYR), {
        "peer": "ImuCalibration (Suarez, Corazza, Perez; Tedaldi et al. 2014 method)",
        "repository": SUAREZ_REPO, "commit": SUAREZ_COMMIT,
        "recording": "calibration data/example_data_calibration.csv (fitted); the same unit's "
                     "results test data/*.csv held out",
        "numbers": "optmization result data/params_acc.csv, params_gyro.csv "
                   "(suarez_mpu6050/peer_result.txt)",
        "peer_params_acc": SUAREZ_ACC, "peer_params_gyro": SUAREZ_GYR,
        "nominal_scales": {"accel_mps2_per_count": SUAREZ_ACC_NOMINAL,
                           "gyro_radps_per_count": SUAREZ_GYR_NOMINAL},
        "map": "accel_M = sa K_a^-1 T_a^-1 - I, accel_bias = -sa b_a; gyro_M = sg K_g^-1 T_g^-1 - I, "
               "gyro_bias = sg b_g; T with float32 entries (exact; "
               "ImuCalibrationModules/imu_calibration.py:395-481)"})
    return out


def convert(kind, peer):
    if kind == "mikoff":
        return mikoff_to_params(*peer)
    return suarez_to_params(*peer)


def self_check(kind, peer, ps, rng, n=200):
    """Largest |peer output - product output| (accel m/s^2, gyro rad/s) over n synthetic samples."""
    ab, am, gb, gm = (ps["accel_bias_mps2"], ps["accel_M"], ps["gyro_bias_radps"], ps["gyro_M"])
    worst = 0.0
    for _ in range(n):
        if kind == "mikoff":
            acc, gyr, eps = peer
            f = [rng.uniform(-40.0, 40.0) for _ in range(3)]   # SI, as the files hold them
            w = [rng.uniform(-6.0, 6.0) for _ in range(3)]
            pa, pw = mikoff_calibrate_acc(acc, f), mikoff_calibrate_gyr(gyr, eps, w)
            qa, qw = product_compensate(am, ab, f), product_compensate(gm, gb, w)
        else:
            pacc, pgyr = peer
            ca = [float(rng.randint(-32768, 32767)) for _ in range(3)]  # int16 counts
            cg = [float(rng.randint(-32768, 32767)) for _ in range(3)]
            pa, pw = suarez_apply_acc(pacc, ca), suarez_apply_gyr(pgyr, cg)
            # what `imucal import` stores: counts x nominal scale (offset 0)
            qa = product_compensate(am, ab, [c * SUAREZ_ACC_NOMINAL for c in ca])
            qw = product_compensate(gm, gb, [c * SUAREZ_GYR_NOMINAL for c in cg])
        worst = max(worst, max(abs(x - y) for x, y in zip(pa + pw, qa + qw)))
    return worst


def read_counts_csv(path):
    rows = []
    with lzma.open(path, "rt", encoding="utf-8") as fh:
        for line in fh:
            cells = line.strip().split(",")
            if len(cells) == 6 and all(c.lstrip("-").isdigit() for c in cells):
                rows.append([float(c) for c in cells])
    return rows


def mean_rows(rows, a, b, cols):
    n = b - a
    return [sum(rows[i][c] for i in range(a, b)) / n for c in cols]


def suarez_data_check(ps, counts=None, archive_rows=None):
    """Largest |recomputed - published| of the peer's calibrated rest means, m/s^2."""
    worst_peer = worst_prod = 0.0
    for a, b, pub in zip(SUAREZ_REST_STARTS, SUAREZ_REST_ENDS, SUAREZ_REST_MEANS):
        if counts is not None:
            c = mean_rows(counts, a, b, (0, 1, 2))
            worst_peer = max(worst_peer, max(abs(x - y) for x, y in
                                             zip(suarez_apply_acc(SUAREZ_ACC, c), pub)))
            raw = [x * SUAREZ_ACC_NOMINAL for x in c]
        else:
            raw = mean_rows(archive_rows, a, b, (0, 1, 2))
        got = product_compensate(ps["accel_M"], ps["accel_bias_mps2"], raw)
        worst_prod = max(worst_prod, max(abs(x - y) for x, y in zip(got, pub)))
    return worst_peer, worst_prod


def read_archive_accel(path):
    """imu.csv of a run archive: per row dv / dt (m/s^2), dt from t_s as db/archive/FORMAT.md."""
    rows, prev_t, rate = [], None, None
    with open(os.path.join(path, "run.toml"), encoding="utf-8") as fh:
        for line in fh:
            if line.strip().startswith("rate_hz"):
                rate = float(line.split("=")[1])
    with open(os.path.join(path, "imu.csv"), encoding="utf-8") as fh:
        next(fh)
        for line in fh:
            c = line.split(",")
            t = float(c[0])
            dt = 1.0 / rate if prev_t is None else t - prev_t
            prev_t = t
            rows.append([float(c[4]) / dt, float(c[5]) / dt, float(c[6]) / dt])
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out_dir")
    ap.add_argument("--corpus", help="folder holding suarez_mpu6050/example_data_calibration.csv.xz")
    ap.add_argument("--archives", help="folder holding the imported archive s_example_data_calibration")
    args = ap.parse_args()
    os.makedirs(args.out_dir, exist_ok=True)
    rng = random.Random(48)
    ok = True
    written = {}
    for name, (kind, peer, source) in units().items():
        ab, am, gb, gm = convert(kind, peer)
        path = os.path.join(args.out_dir, name + ".json")
        with open(path, "w", encoding="utf-8") as fh:
            json.dump(param_set_json(ab, am, gb, gm, source), fh, indent=2)
            fh.write("\n")
        with open(path, encoding="utf-8") as fh:
            ps = json.load(fh)
        written[name] = ps
        worst = self_check(kind, peer, ps, rng)
        good = worst <= 1e-9
        ok = ok and good
        print("%-18s %s  self-check: peer model vs product compensation, max |diff| %.2e %s"
              % (name, path, worst, "ok" if good else "FAILED (> 1e-9)"))
    if args.corpus:
        counts = read_counts_csv(os.path.join(args.corpus, "suarez_mpu6050",
                                              "example_data_calibration.csv.xz"))
        wp, wq = suarez_data_check(written["suarez_mpu6050"], counts=counts)
        print("suarez data check (%d rows): the peer's published calibrated rest means recomputed "
              "from the counts: peer model max |diff| %.2e m/s^2, product %.2e m/s^2"
              % (len(counts), wp, wq))
        ok = ok and wp < 1e-4 and wq < 1e-4
    if args.archives:
        rows = read_archive_accel(os.path.join(args.archives, "s_example_data_calibration"))
        _, wq = suarez_data_check(written["suarez_mpu6050"], archive_rows=rows)
        print("suarez archive check (%d rows): the same from the imported archive's dv/dt with "
              "the product's compensation: max |diff| %.2e m/s^2" % (len(rows), wq))
        ok = ok and wq < 1e-4
    if not ok:
        print("peer_params.py: a check FAILED", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
