#!/usr/bin/env python3
"""The external-simulator validation of the gap diagnosis (issue #49 item 5): make the runs,
diagnose every one, score, tabulate.  Re-runnable with any imucal binary and output directory.

    batch.py --imucal BIN --out DIR [--psins PSINS_CHECKOUT] [--gis GNSS_INS_SIM_CHECKOUT]
             [--sequence factory-std] [--jobs 2] [--only psins|gis] [--rediagnose]

DIR/runs/<sim>-<name>/   the run archives (made once; kept unless --regenerate)
DIR/diag/<run>.json      imucal diagnose --json of each run (redone with --rediagnose)
DIR/calib/<run>.json     imucal calibrate --json of the null runs
DIR/twin/<run>.json      the run's twin on the project's own simulator: the same effects, sizes,
                         noise, grade and sequence, 5 seeds; how many name an injected effect
DIR/results.csv, DIR/results.json   one row per run (machine-readable)
DIR/summary.md, DIR/summary.json    the table per simulator

Run specs are deterministic (fixed seeds below), so the same DIR/runs is rebuilt bit for bit on
the same simulator checkouts.  A run whose archive exists is not regenerated: to measure a new
diagnosis on the same runs, pass the new binary with --rediagnose.
"""
import argparse
import concurrent.futures as cf
import csv
import json
import math
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

# Effects one sequence cannot tell apart: a name from the same group counts as the injected one.
ALIASES = [{"accel_quadratic_k2", "accel_asymmetry"}]
PLAUSIBLE_X_TYPICAL = 50.0  # navigation grade: the diagnosis's plausibility limit (FORMAT.md)


def group(name):
    for g in ALIASES:
        if name in g:
            return g
    return {name}


# ----------------------------------------------------------------------------------- run specs
def psins_specs():
    """PSINS runs: (name, cfg in imuerrset units, injected catalogue effects)."""
    rng = np.random.default_rng(4901)
    specs = []

    def base(seed):
        r = lambda lo, hi, n: [float(x) for x in rng.uniform(lo, hi, n) * rng.choice([-1, 1], n)]
        return {"seed": seed, "eb": r(0.005, 0.05, 3), "db": r(20, 300, 3), "web": 0.0015,
                "wdb": 10.0, "dKGii": r(10, 300, 3), "dKAii": r(10, 300, 3),
                "dKGij": r(5, 60, 6), "dKAij": r(5, 60, 3)}

    s = lambda lo, hi, n=3: [float(x) for x in rng.uniform(lo, hi, n) * rng.choice([-1, 1], n)]
    effects = {
        "k2": lambda: {"Ka2": s(30, 100)},                               # ug/g^2
        "lever": lambda: {"rxyz": s(1, 4, 9)},                           # cm
        # ms; PSINS's imuadderr takes 0 <= dtGA < 10 samples only (it pads the accelerometer
        # series by one sample before and ten after), so the sign drawn is dropped
        "skew": lambda: {"dtGA": float(abs(rng.uniform(0.5, 2.0) * rng.choice([-1, 1])))},
        "gsens": lambda: {"gSens": s(0.03, 0.15, 9)},                    # deg/h/g
        "asym": lambda: {"Kap": s(30, 100)},                             # ppm
        "markov": lambda: {"sqrtR0G": float(rng.uniform(0.003, 0.01)), "TauG": 500.0,
                           "sqrtR0A": float(rng.uniform(30, 100)), "TauA": 500.0},
    }
    combos = ([(e,) for e in effects for _ in range(2)]
              + [("k2", "lever"), ("k2", "skew"), ("lever", "skew"), ("k2", "gsens"),
                 ("lever", "gsens"), ("skew", "gsens"), ("asym", "lever"), ("k2", "markov"),
                 ("lever", "markov"), ("skew", "markov"), ("gsens", "markov"), ("asym", "skew")]
              + [("k2", "lever", "skew"), ("k2", "lever", "gsens"), ("k2", "skew", "gsens"),
                 ("lever", "skew", "gsens"), ("k2", "lever", "markov"), ("asym", "lever", "skew")])
    seed = 100
    # the two cases first, with its sizes: K2 ~50 ug/g^2 + inner lever arms (+ 1 ms skew)
    c = base(seed); c.update({"Ka2": [50.0, 50.0, 50.0], "rxyz": [2, 1, 0, -1, 2, 0, 0, 1, 3]})
    specs.append(("issue-k2-lever", c))
    seed += 1
    c = base(seed); c.update({"Ka2": [50.0, 50.0, 50.0], "rxyz": [2, 1, 0, -1, 2, 0, 0, 1, 3], "dtGA": 1.0})
    specs.append(("issue-k2-lever-skew1ms", c))
    for i, combo in enumerate(combos):
        seed += 1
        c = base(seed)
        for e in combo:
            c.update(effects[e]())
        specs.append(("-".join(combo) + f"-{i:02d}", c))
    for i in range(12):
        seed += 1
        specs.append((f"null-{i:02d}", base(seed)))
    return specs


# gnss-ins-sim's own accuracy presets (gnss_ins_sim/sim/imu_model.py, in its accuracy-dict units:
# deg/h, deg/sqrt(h), m/s^2, m/s/sqrt(h)): "high" (partly HG9900) is a tactical unit by the
# datasheets' ranges (gyro drift 0.1 deg/h), "mid" (partly IMU381) and "low" (AHRS380) are MEMS.
GIS_PRESETS = {
    "high": {"gyro_b_stability": 0.1, "gyro_arw": 2.0e-3, "accel_b_stability": 3.6e-6,
             "accel_vrw": 2.5e-5, "grade": "tactical"},
    "mid": {"gyro_b_stability": 3.5, "gyro_arw": 0.25, "accel_b_stability": 5.0e-5,
            "accel_vrw": 0.03, "grade": "mems"},
    "low": {"gyro_b_stability": 10.0, "gyro_arw": 0.75, "accel_b_stability": 2.0e-4,
            "accel_vrw": 0.05, "grade": "mems"},
}


def gis_specs():
    """gnss-ins-sim runs: its error model has one catalogue effect, the Gauss-Markov bias drift
    (bias_instability), for the gyros and the accelerometers, with a correlation time. Each run is
    declared at a grade whose datasheet range holds its drift (the product's plausible bound,
    `imucal effects`): navigation-grade runs at 3-10x the catalogue's typical (0.001 deg/h, 10 ug;
    the bound is 10x), tactical and MEMS runs with gnss-ins-sim's own presets and noise."""
    rng = np.random.default_rng(4902)
    specs = []

    def base(seed, preset=None):
        r = lambda lo, hi: [float(x) for x in rng.uniform(lo, hi, 3) * rng.choice([-1, 1], 3)]
        c = {"seed": seed, "gyro_b": r(0.005, 0.05), "gyro_arw": 0.0015,
             "accel_b": r(2e-4, 3e-3), "accel_vrw": 10 * 9.80665e-6 * 60,
             "gyro_b_stability": 0.0, "accel_b_stability": 0.0}
        if preset:
            P = GIS_PRESETS[preset]
            c.update({"gyro_arw": P["gyro_arw"], "accel_vrw": P["accel_vrw"], "grade": P["grade"]})
        return c

    seed = 200
    i = 0
    # navigation grade: 3-10x typical (factor 4 or 8, times 0.8-1.25)
    for kind in ("gyro", "accel", "both"):
        for tau in (100.0, 300.0, 1000.0, 3000.0):
            for f in (4.0, 8.0):
                seed += 1
                c = base(seed)
                if kind in ("gyro", "both"):   # catalogue typical 0.001 deg/h
                    c["gyro_b_stability"] = 0.001 * f * float(rng.uniform(0.8, 1.25))
                    c["gyro_b_corr"] = tau
                if kind in ("accel", "both"):  # catalogue typical 10 ug
                    c["accel_b_stability"] = 10 * 9.80665e-6 * f * float(rng.uniform(0.8, 1.25))
                    c["accel_b_corr"] = tau
                specs.append((f"nav-{kind}-tau{int(tau)}-x{int(f)}-{i:02d}", c))
                i += 1
    # tactical and MEMS: gnss-ins-sim's presets at its correlation time (100 s) and two longer
    # ones; the tactical preset also at 3x (0.3 deg/h, still within a tactical unit's range)
    runs = ([("high", t, 1.0) for t in (100.0, 300.0, 1000.0)] + [("high", 100.0, 3.0)]
            + [(p, t, 1.0) for p in ("mid", "low") for t in (100.0, 300.0, 1000.0)])
    for preset, tau, scale in runs:
        seed += 1
        c = base(seed, preset)
        P = GIS_PRESETS[preset]
        c["gyro_b_stability"] = P["gyro_b_stability"] * scale
        c["accel_b_stability"] = P["accel_b_stability"] * scale
        c["gyro_b_corr"] = c["accel_b_corr"] = tau
        specs.append((f"{P['grade'][:3]}-{preset}-tau{int(tau)}-x{int(scale)}-{i:02d}", c))
        i += 1
    for j, preset in enumerate([None] * 6 + ["high"] * 3 + ["mid", "mid", "low"]):
        seed += 1
        specs.append((f"null-{(preset or 'nav')}-{j:02d}", base(seed, preset)))
    # a gyro drift alone where a sequence resolves it (added 2026-11-30, after the navigation
    # grade's gyro drifts proved below factory-std's resolution; appended so that every run above
    # keeps its draws): the tactical preset's noise, its drift at 1x and 3x, four tau
    for tau in (100.0, 300.0, 1000.0, 3000.0):
        for scale in (1.0, 3.0):
            seed += 1
            c = base(seed, "high")
            c["gyro_b_stability"] = GIS_PRESETS["high"]["gyro_b_stability"] * scale
            c["gyro_b_corr"] = tau
            specs.append((f"tac-gyro-tau{int(tau)}-x{int(scale)}-{i:02d}", c))
            i += 1
    return specs


# ------------------------------------------------------------------------------------- making
def make_run(sim, name, cfg, a):
    out = os.path.join(a.out, "runs", f"{sim}-{name}")
    if os.path.exists(os.path.join(out, "truth.json")) and not a.regenerate:
        return out
    work = os.path.join(a.out, "work")
    if sim == "psins":
        import psins_make
        psins_make.make(a.psins, a.imucal, a.sequence, work, cfg, out, f"PSINS-{name}")
    else:
        import gis_make
        gis_make.make(a.gis, a.imucal, a.sequence, work, cfg, out, f"GIS-{name}")
    return out


def imucal_json(command, folder, run, a):
    """`imucal COMMAND --json RUN` into OUT/FOLDER/RUN.json (written whole: a .tmp renamed), kept
    unless --rediagnose; a failure is stored as {"error", "rc"}."""
    path = os.path.join(a.out, folder, os.path.basename(run) + ".json")
    if os.path.exists(path) and not a.rediagnose:
        return path
    os.makedirs(os.path.dirname(path), exist_ok=True)
    p = subprocess.run([a.imucal, command, "--json", run], capture_output=True, text=True)
    with open(path + ".tmp", "w") as f:
        f.write(p.stdout if p.stdout.strip() else json.dumps({"error": p.stderr.strip(), "rc": p.returncode}))
    os.rename(path + ".tmp", path)
    return path


def diagnose(run, a):
    return imucal_json("diagnose", "diag", run, a)


def calibrate(run, a):
    return imucal_json("calibrate", "calib", run, a)


# ------------------------------------------------------------------------------ the own twin
TWIN_SEEDS = 5


def twin_unit_toml(truth):
    """A unit file with the run's sensor noise (truth.json "noise", SI) for `imucal simulate`."""
    n = truth.get("noise", {})
    arw = n.get("arw_rad_per_sqrt_s", 0.0) * 180.0 / math.pi * 60.0
    vrw = n.get("vrw_mps_per_sqrt_s", 0.0) / 9.80665e-6
    return (f"[noise]\narw_deg_per_sqrt_h = {arw!r}\nvrw_ug_per_sqrt_hz = {vrw!r}\n"
            f"dtheta_lsb_rad = {n.get('dtheta_lsb_rad', 0.0)!r}\ndv_lsb_mps = {n.get('dv_lsb_mps', 0.0)!r}\n")


def catalogue_order(imucal):
    """{effect: [parameter names in the catalogue's order]} (`imucal effects --json`), the order
    `imucal simulate --effect NAME=V,...` reads."""
    out = subprocess.run([imucal, "effects", "--json"], capture_output=True, text=True, check=True)
    return {e["name"]: [q["name"] for q in e["parameters"]] for e in json.loads(out.stdout)}


def twin(run, grade, a, order):
    """Whether the project's own simulator resolves this run's injected effects: the same effects
    at the same sizes, the same sensor noise, grade, sequence and rate, TWIN_SEEDS seeds, each
    diagnosed as the run is. {"detected": k, "seeds": n}: k runs named an injected effect (or its
    set). Decided before and apart from the run's own diagnosis: a run whose effects the product
    does not resolve where its model is exact measures the sequence, not the diagnosis."""
    name = os.path.basename(run)
    path = os.path.join(a.out, "twin", name + ".json")
    if os.path.exists(path) and not a.rediagnose:
        return json.load(open(path))
    truth = json.load(open(os.path.join(run, "truth.json")))
    effects = truth.get("effects", {})
    if not effects:
        return None
    work = os.path.join(a.out, "twin", name)
    os.makedirs(work, exist_ok=True)
    with open(os.path.join(work, "unit.toml"), "w") as f:
        f.write(twin_unit_toml(truth))
    rate = "100"
    with open(os.path.join(run, "run.toml")) as f:
        for line in f:
            if line.strip().startswith("rate_hz"):
                rate = line.split("=")[1].strip()
    allowed = set().union(*[group(e) for e in effects])
    args = []
    for e, p in effects.items():
        args += ["--effect", e + "=" + ",".join(repr(float(p.get(k, 0.0))) for k in order[e])]
    detected = 0
    for k in range(TWIN_SEEDS):
        out = os.path.join(work, f"seed{k}")
        subprocess.run([a.imucal, "simulate", "--sequence", a.sequence, "--out", out, "--overwrite",
                        "--unit", os.path.join(work, "unit.toml"), "--grade", grade, "--rate", rate,
                        "--seed", str(9001 + k)] + args, capture_output=True, text=True, check=True)
        p = subprocess.run([a.imucal, "diagnose", "--json", out], capture_output=True, text=True)
        try:
            d = json.loads(p.stdout)
        except json.JSONDecodeError:
            continue
        detected += any(n["effect"] in allowed for n in named_effects(d))
        subprocess.run(["rm", "-rf", out])
    r = {"detected": detected, "seeds": TWIN_SEEDS}
    with open(path + ".tmp", "w") as f:
        json.dump(r, f)
    os.rename(path + ".tmp", path)
    return r


# ------------------------------------------------------------------------------------ scoring
def named_effects(d):
    """The effects a diagnosis names ("explained by"), each with its size and sigma."""
    names = []
    for e in d.get("explained_by") or []:
        n = e if isinstance(e, str) else (e.get("effect") or e.get("name"))
        names += [x.strip() for x in str(n).split("|") if x.strip()]
    steps = {s.get("effect"): s for s in d.get("steps") or [] if isinstance(s, dict)}
    cands = {c.get("effect"): c for c in d.get("candidates") or [] if isinstance(c, dict)}
    out = []
    for n in names:
        s = steps.get(n) or cands.get(n) or {}
        c = cands.get(n) or {}
        mag, sig = s.get("magnitude"), s.get("sigma")
        typ = None
        if c.get("typical_ratio") and c.get("magnitude"):
            typ = c["magnitude"] / c["typical_ratio"]
        out.append({"effect": n, "magnitude": mag, "sigma": sig, "unit": s.get("unit", c.get("unit")),
                    "typical": typ, "plausible_flag": c.get("plausible")})
    return out


def learn_typicals(diags):
    typ = {}
    for d in diags:
        for c in d.get("candidates") or []:
            if c.get("typical_ratio") and c.get("magnitude"):
                typ.setdefault(c["effect"], c["magnitude"] / c["typical_ratio"])
    return typ


GRADES = ("navigation", "tactical", "mems")  # the order of "plausible_max"


def plausible_limits(imucal):
    """The product's plausible size per effect and grade (`imucal effects --json`, "plausible_max",
    in the effect's magnitude unit, navigation/tactical/MEMS): {grade: {effect: limit}}; {} for a
    build that has none (before issue #49), which then falls back on PLAUSIBLE_X_TYPICAL."""
    out = subprocess.run([imucal, "effects", "--json"], capture_output=True, text=True)
    try:
        E = json.loads(out.stdout)
        return {g: {e["name"]: (e.get("plausible_max") or [None] * 3)[i] for e in E}
                for i, g in enumerate(GRADES)}
    except (json.JSONDecodeError, KeyError, TypeError, IndexError):
        return {}


def score(sim, name, truth, d, calib, typicals, limits=None, grade="navigation", tw=None):
    injected = sorted(truth.get("effects", {}).keys())
    allowed = set().union(*[group(e) for e in injected]) if injected else set()
    named = named_effects(d)
    best = d.get("best")
    best_eff = best.get("effect") if isinstance(best, dict) else (best if isinstance(best, str) else None)
    if not best_eff and d.get("ambiguous"):
        # a set the sequence cannot tell apart is the diagnosis's answer (best is then null)
        best_eff = "|".join(e if isinstance(e, str) else str(e.get("effect")) for e in d["ambiguous"])
    best_set = set(best_eff.split("|")) if best_eff else set()
    weak = []
    for n in named:
        typ = n["typical"] or typicals.get(n["effect"])
        mag, sig = n["magnitude"], n["sigma"]
        why = []
        if mag is not None and sig is not None and abs(mag) < 2 * sig:
            why.append("|size|<2sigma")
        limit = (limits or {}).get(grade, {}).get(n["effect"])
        if mag is not None and limit is not None:
            # the size the named step reports (its joint fit) against the product's bound, by the
            # product's rule (calib/diagnosis judge_plausibility): beyond it by more than its 2 sigma
            if abs(mag) - 2 * (sig or 0.0) > limit:
                why.append(f"beyond the plausible {limit:.3g} {n['unit']} by more than 2 sigma")
        elif mag is not None and typ and abs(mag) / typ > PLAUSIBLE_X_TYPICAL:
            why.append(f"{abs(mag) / typ:.0f}x typical")
        elif n["plausible_flag"] is False:
            why.append("implausible in the candidate table")
        if why:
            weak.append(f'{n["effect"]}={mag:.3g}+-{sig:.2g} {n["unit"]} ({", ".join(why)})'
                        if mag is not None and sig is not None else f'{n["effect"]} ({", ".join(why)})')
    row = {
        "sim": sim, "run": name, "grade": grade, "null": not injected, "injected": "+".join(injected),
        "verdict": d.get("verdict", "error:" + str(d.get("error", ""))[:80]),
        "best": best_eff or "",
        "named": "+".join(n["effect"] for n in named),
        "named_sizes": "; ".join(f'{n["effect"]}={n["magnitude"]:.3g}+-{n["sigma"]:.2g} {n["unit"]}'
                                 for n in named if n["magnitude"] is not None and n["sigma"] is not None),
        "best_right": bool(best_set & allowed) if injected else None,
        "best_right_supported": (bool(best_set & allowed)
                                 and not any(w.split("=")[0].split(" ")[0] in best_set for w in weak))
                                if injected else None,
        "all_named_injected": (all(n["effect"] in allowed for n in named) if named else None),
        "all_injected_named": (all(any(n["effect"] in group(e) for n in named) for e in injected)
                               if injected else None),
        "weak_named": "; ".join(weak),
        "false_alarm": (bool(named) or d.get("verdict") not in ("consistent",)) if not injected else None,
        "twin": f'{tw["detected"]}/{tw["seeds"]}' if tw else "",
        # the project's own simulator names an injected effect in at least half of its seeds
        "resolved": (2 * tw["detected"] >= tw["seeds"]) if (tw and injected) else None,
        "summary": d.get("summary", ""),
        "calibrate": (calib or {}).get("verdict", "") if calib else "",
    }
    # sizes of the injected effects against their fitted values (the 3-sigma check)
    checks = []
    for e, p in truth.get("effects", {}).items():
        step = next((s for s in d.get("steps") or [] if s.get("effect") in group(e)), None)
        label = ""
        if step is None:  # not named (or named as a set): the candidate table's fit
            step = next((c for c in d.get("candidates") or [] if c.get("effect") == e), None)
            label = " (candidate)"
        if step is None:
            continue
        fit = {q["name"]: (q["value"], q["sigma"]) for q in step.get("parameters", [])}
        conv = UNIT_SI.get(step.get("effect"), {})
        worst = 0.0
        for k, v in p.items():
            if k in fit and k in conv and fit[k][1] > 0:
                worst = max(worst, abs(fit[k][0] - v / conv[k]) / fit[k][1])
        if conv:
            checks.append(f"{step['effect']}{label}: max|fit-injected|/sigma={worst:.1f}")
    row["size_checks"] = "; ".join(checks)
    return row


# SI -> the diagnosis's display unit, for comparing the fitted parameters with the injected ones
UG = 9.80665e-6
UNIT_SI = {
    "accel_quadratic_k2": {f"k2_{a}": UG / 9.80665**2 for a in "xyz"},
    "accel_asymmetry": {f"kap_{a}": 1e-6 for a in "xyz"},
    "size_effect": {f"r_{a}_{b}": 1e-3 for a in "xyz" for b in "xyz"},
    "gyro_accel_skew": {"t_GA": 1e-3},
    "gyro_g_sensitivity": {f"G_{a}{b}": math.radians(1 / 3600) / 9.80665 for a in "xyz" for b in "xyz"},
}


def pct(xs):
    xs = [x for x in xs if x is not None]
    return (f"{100 * sum(xs) / len(xs):.0f} % ({sum(xs)}/{len(xs)})" if xs else "n/a"), xs


def summarize(rows):
    out = {}
    for sim in sorted({r["sim"] for r in rows}):
        R = [r for r in rows if r["sim"] == sim]
        eff = [r for r in R if not r["null"]]
        nul = [r for r in R if r["null"]]
        s = {}
        s["runs with effects"] = len(eff)
        s["null runs"] = len(nul)
        res = [r for r in eff if r["resolved"] is not False]
        unres = [r for r in eff if r["resolved"] is False]
        s["effect runs the own simulator resolves (its twin names an injected effect in >= half its seeds)"] = \
            f"{len(res)}/{len(eff)}"
        s["best effect right (an injected effect or its set), resolved runs"] = \
            pct([r["best_right"] for r in res])[0]
        s["best effect right, its size >= 2 sigma and plausible, resolved runs"] = \
            pct([r["best_right_supported"] for r in res])[0]
        s["best effect right, all effect runs"] = pct([r["best_right"] for r in eff])[0]
        s["unresolved runs naming an effect not injected"] = \
            f'{sum(1 for r in unres if r["all_named_injected"] is False)}/{len(unres)}'
        s["every named effect injected (runs naming any)"] = pct([r["all_named_injected"] for r in eff])[0]
        s["effect runs naming nothing"] = f'{sum(1 for r in eff if not r["named"])}/{len(eff)}'
        s["every injected effect named"] = pct([r["all_injected_named"] for r in eff])[0]
        s["runs naming an effect with |size|<2sigma or implausible"] = \
            f'{sum(1 for r in R if r["weak_named"])}/{len(R)}'
        s["false alarms in null runs"] = f'{sum(1 for r in nul if r["false_alarm"])}/{len(nul)}'
        s["null runs calibrate PASS"] = f'{sum(1 for r in nul if r["calibrate"] == "PASS")}/{len(nul)}'
        out[sim] = s
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--imucal", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--psins", help="PSINS checkout")
    ap.add_argument("--gis", help="gnss-ins-sim checkout")
    ap.add_argument("--sequence", default="factory-std")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", choices=["psins", "gis"])
    ap.add_argument("--rediagnose", action="store_true", help="rerun diagnose/calibrate on existing runs")
    ap.add_argument("--regenerate", action="store_true", help="remake the run archives too")
    a = ap.parse_args()
    a.imucal = os.path.abspath(a.imucal)
    a.out = os.path.abspath(a.out)
    os.makedirs(a.out, exist_ok=True)
    jobs = []
    if a.psins and a.only in (None, "psins"):
        a.psins = os.path.abspath(a.psins)
        jobs += [("psins", n, c) for n, c in psins_specs()]
    if a.gis and a.only in (None, "gis"):
        a.gis = os.path.abspath(a.gis)
        jobs += [("gis", n, c) for n, c in gis_specs()]
    if not jobs:
        sys.exit("nothing to do: give --psins and/or --gis")
    # the profile and each simulator's per-sequence cache first, in this process
    first = {}
    for sim, n, c in jobs:
        first.setdefault(sim, (sim, n, c))
    for sim, n, c in first.values():
        make_run(sim, n, c, a)
    with cf.ProcessPoolExecutor(max_workers=a.jobs) as ex:
        runs = list(ex.map(make_run, *zip(*[(s, n, c, a) for s, n, c in jobs])))
    with cf.ThreadPoolExecutor(max_workers=a.jobs) as ex:
        diags = list(ex.map(lambda r: diagnose(r, a), runs))
        nulls = [r for (s, n, c), r in zip(jobs, runs) if n.startswith("null")]
        cals = dict(zip(nulls, ex.map(lambda r: calibrate(r, a), nulls)))
    D = [json.load(open(p)) for p in diags]
    order = catalogue_order(a.imucal)
    with cf.ThreadPoolExecutor(max_workers=a.jobs) as ex:
        twins = list(ex.map(lambda j: twin(j[1], j[0][2].get("grade", "navigation"), a, order)
                            if not j[0][1].startswith("null") else None, zip(jobs, runs)))
    typicals = learn_typicals(D)
    limits = plausible_limits(a.imucal)
    rows = []
    for (sim, n, c), run, d, tw in zip(jobs, runs, D, twins):
        truth = json.load(open(os.path.join(run, "truth.json")))
        cal = None
        if run in cals:
            try:
                cal = json.load(open(cals[run]))
            except json.JSONDecodeError:
                cal = {"verdict": "unreadable"}
        rows.append(score(sim, n, truth, d, cal, typicals, limits, c.get("grade", "navigation"), tw))
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump(rows, f, indent=1)
    with open(os.path.join(a.out, "results.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    summ = summarize(rows)
    with open(os.path.join(a.out, "summary.json"), "w") as f:
        json.dump(summ, f, indent=1)
    sims = list(summ)
    lines = ["| | " + " | ".join(sims) + " |", "|---|" + "---|" * len(sims)]
    for k in summ[sims[0]]:
        lines.append(f"| {k} | " + " | ".join(str(summ[s][k]) for s in sims) + " |")
    lines += ["", "| run | injected | verdict | named (size ± σ) | best right | weak named | size check |",
              "|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["run"].startswith("issue") or r["null"] and r["false_alarm"]:
            lines.append(f'| {r["sim"]}-{r["run"]} | {r["injected"] or "—"} | {r["verdict"]} | '
                         f'{r["named_sizes"] or r["named"] or "—"} | {r["best_right"]} | '
                         f'{r["weak_named"] or "—"} | {r["size_checks"] or "—"} |')
    with open(os.path.join(a.out, "summary.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
