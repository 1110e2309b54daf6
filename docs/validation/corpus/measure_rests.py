#!/usr/bin/env python3
"""Rests, hand-held start, clipping and time stamps of the corpus recordings (issue #48, item 1).

Pure Python 3 (no numpy), read-only, run from the repository root:
    python3 docs/validation/corpus/measure_rests.py [NAME ...]
NAMES: mikoff0 mikoff1 mikoff3 suarez_cal suarez_rot suarez_static madlab_counts madlab_si xio_walk

Method, the same for every recording: the samples are converted with the NOMINAL values of the
folder's import.toml into g and deg/s. Over a centred window of 0.5 s, s_a is the root-sum-square
over the three axes of the accelerometer's standard deviation (mg) and s_g the same for the gyro
(deg/s). A sample is still when s_a < TA and s_g < TG, with TA = max(10 mg, 2.5 x the 5th
percentile of s_a) and TG = max(2 deg/s, 3 x the 5th percentile of s_g): thresholds set by the
recording's own quietest windows, loose enough for hand tremor (~1 deg/s) but not for a slow
turn. A run of still samples of at least 1 s is a rest. Per rest: start, length, mean |f| (g), and
the standard deviation of accelerometer (mg) and gyro (deg/s) over the whole rest (rss of axes).
A rest whose gyro scatter is > 3x that of the quietest quartile of rests is marked "tremor" (held
by hand, or on a surface that moves).
Clipping: raw counts at the int16 limits (-32768, +32767), listed as runs with their times.
Time stamps (where there is a time column): repeated stamps and steps > 1.5x the median step.
"""
import csv, io, lzma, math, os, sys

HERE = os.path.dirname(os.path.abspath(__file__))
# The recordings themselves are not in the repository (fetched material; see corpus.md): their
# folders, each with the .xz files, sit in $IMUCAL_CORPUS_DATA.
DATA = os.environ.get("IMUCAL_CORPUS_DATA", "")
if not DATA:
    sys.exit("measure_rests.py: set IMUCAL_CORPUS_DATA to the folder holding the corpus recordings")


def text(folder, name):
    with lzma.open(os.path.join(DATA, folder, name + ".xz"), "rt", encoding="utf-8") as f:
        return f.read()


def running_var(x, w):
    n, h = len(x), w // 2
    s, s2 = [0.0], [0.0]
    for v in x:
        s.append(s[-1] + v)
        s2.append(s2[-1] + v * v)
    out = []
    for i in range(n):
        a, b = max(0, i - h), min(n, i + h + 1)
        m = b - a
        mu = (s[b] - s[a]) / m
        out.append(max(0.0, (s2[b] - s2[a]) / m - mu * mu))
    return out


def sd3(rows):
    m = len(rows)
    mean = [sum(r[k] for r in rows) / m for k in range(3)]
    return mean, math.sqrt(sum(sum((r[k] - mean[k]) ** 2 for r in rows) / m for k in range(3)))


def analyse(name, acc_g, gyr_dps, rate, raw=None, stamps=None):
    n = len(acc_g)
    w = max(3, int(round(0.5 * rate)))
    va = [running_var([a[k] for a in acc_g], w) for k in range(3)]
    vg = [running_var([g[k] for g in gyr_dps], w) for k in range(3)]
    sa = [1000 * math.sqrt(va[0][i] + va[1][i] + va[2][i]) for i in range(n)]
    sg = [math.sqrt(vg[0][i] + vg[1][i] + vg[2][i]) for i in range(n)]
    qa, qg = sorted(sa)[n // 20], sorted(sg)[n // 20]
    TA, TG = max(10.0, 2.5 * qa), max(2.0, 3.0 * qg)
    still = [sa[i] < TA and sg[i] < TG for i in range(n)]
    rests, i = [], 0
    while i < n:
        if still[i]:
            j = i
            while j < n and still[j]:
                j += 1
            if (j - i) / rate >= 1.0:
                rests.append((i, j))
            i = j
        else:
            i += 1
    print(f"== {name}: {n} samples = {n / rate:.2f} s at {rate} Hz; quietest windows: "
          f"{qa:.2f} mg, {qg:.3f} deg/s; still if s_a < {TA:.1f} mg and s_g < {TG:.2f} deg/s")
    stats = []
    for a, b in rests:
        ma, sda = sd3(acc_g[a:b])
        mg, sdg = sd3(gyr_dps[a:b])
        stats.append((a, b, math.sqrt(sum(v * v for v in ma)), 1000 * sda, sdg, mg))
    sg_sorted = sorted(s[4] for s in stats)
    med_g = sg_sorted[len(stats) // 2] if stats else float("nan")
    quiet_g = sg_sorted[len(stats) // 4] if stats else float("nan")   # the quietest quartile
    print("  rest  start_s  length_s  |f|_g    acc_sd_mg  gyro_sd_dps  gyro_mean_dps (x y z)")
    for k, (a, b, f, sda, sdg, mg) in enumerate(stats):
        flag = "  tremor (> 3x the quiet rests)" if sdg > 3 * quiet_g else ""
        print(f"  {k:4d} {a / rate:8.2f} {(b - a) / rate:9.2f} {f:7.4f} {sda:10.2f} {sdg:12.3f}"
              f"  {mg[0]:+7.3f} {mg[1]:+7.3f} {mg[2]:+7.3f}{flag}")
    if stats:
        L = sorted((b - a) / rate for a, b, *_ in stats)
        print(f"  {len(stats)} rests; length min {L[0]:.2f} / median {L[len(L) // 2]:.2f} / "
              f"max {L[-1]:.2f} s; rest gyro sd: quietest quartile {quiet_g:.3f}, median {med_g:.3f} deg/s; "
              f"{sum(1 for s in stats if s[4] > 3 * quiet_g)} rests with tremor")
    for T in (5.0,):
        m = min(n, int(T * rate))
        print(f"  first {T:.0f} s: gyro sd {sd3(gyr_dps[:m])[1]:.3f} deg/s, "
              f"acc sd {1000 * sd3(acc_g[:m])[1]:.2f} mg")
    print("  max |gyro| deg/s: " + " ".join(f"{max(abs(g[k]) for g in gyr_dps):.1f}" for k in range(3))
          + "; max |acc| g: " + " ".join(f"{max(abs(a[k]) for a in acc_g):.3f}" for k in range(3)))
    if raw is not None:
        for c, label in enumerate(("ax", "ay", "az", "gx", "gy", "gz")):
            hits = [i for i, r in enumerate(raw) if r[c] >= 32767 or r[c] <= -32768]
            if not hits:
                continue
            runs, start = [], hits[0]
            for p, q in zip(hits, hits[1:] + [None]):
                if q != p + 1:
                    runs.append((start, p))
                    start = q
            print(f"  clipped {label}: {len(hits)} samples at the int16 limit, runs: " + ", ".join(
                f"t={a / rate:.2f}-{(b + 1) / rate:.2f} s ({b - a + 1}, {int(raw[a][c]):+d})" for a, b in runs))
    else:
        print("  (SI data: no raw counts to test against the int16 limits)")
    if stamps is not None:
        d = [b - a for a, b in zip(stamps, stamps[1:])]
        pos = sorted(x for x in d if x > 0)
        med = pos[len(pos) // 2]
        gaps = [x for x in d if x > 1.5 * med]
        print(f"  time column: median step {med * 1000:.4f} ms ({1 / med:.2f} Hz); "
              f"{sum(1 for x in d if x == 0)} repeated stamps; {sum(1 for x in d if x < 0)} backwards; "
              f"{len(gaps)} steps > 1.5x median (largest {max(gaps) * 1000 if gaps else 0:.2f} ms)")
    print()


def load(name):
    if name.startswith("mikoff"):
        rows = [list(map(float, l.split())) for l in text("mikoff_mpu9150", f"imu{name[-1]}.log").splitlines() if l.strip()]
        return dict(acc_g=[[v / 9.80665 for v in r[0:3]] for r in rows],
                    gyr_dps=[[math.degrees(v) for v in r[3:6]] for r in rows], rate=100.0)
    if name.startswith("suarez"):
        fn = {"suarez_cal": "example_data_calibration.csv", "suarez_rot": "imu_90_x_rot.csv",
              "suarez_static": "imu_static_test.csv"}[name]
        lines = text("suarez_mpu6050", fn).splitlines()
        rows = [list(map(float, l.split(","))) for l in lines[5:] if l.strip()]
        return dict(acc_g=[[v / 16384.0 for v in r[0:3]] for r in rows],
                    gyr_dps=[[v / 131.0 for v in r[3:6]] for r in rows], rate=100.0, raw=rows)
    if name == "madlab_counts":
        rows = list(csv.reader(io.StringIO(text("madlab_ferraris_counts", "annotated_session.csv"))))[1:]
        rows = [r[1] for r in sorted(([int(r[1]), [float(v) for v in r[2:8]]] for r in rows))]
        return dict(acc_g=[[v / 2048.0 for v in r[0:3]] for r in rows],
                    gyr_dps=[[v / 16.4 for v in r[3:6]] for r in rows], rate=204.8, raw=rows)
    if name == "madlab_si":
        rows = [[float(v) for v in r] for r in list(csv.reader(io.StringIO(text("madlab_ferraris_si", "example_ferraris_session.csv"))))[1:]]
        return dict(acc_g=[[v / 9.80665 for v in r[4:7]] for r in rows], gyr_dps=[r[1:4] for r in rows], rate=102.4)
    if name == "xio_walk":
        rows = [[float(v) for v in r] for r in list(csv.reader(io.StringIO(text("xio_ngimu_walk", "short_walk.csv"))))[1:]]
        return dict(acc_g=[r[4:7] for r in rows], gyr_dps=[r[1:4] for r in rows], rate=400.0,
                    stamps=[r[0] for r in rows])
    raise SystemExit(f"unknown recording {name}")


if __name__ == "__main__":
    names = sys.argv[1:] or ["mikoff0", "mikoff1", "mikoff3", "suarez_cal", "suarez_rot",
                             "suarez_static", "madlab_counts", "madlab_si", "xio_walk"]
    for nm in names:
        analyse(nm, **load(nm))
