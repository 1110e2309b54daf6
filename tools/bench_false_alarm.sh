#!/usr/bin/env bash
# Benchmark of the gap check's false-alarm rate (issue #22 item 1; figures in README, "A verdict QA
# can trust"): null runs (no unmodelled effect) of every shipped sequence, drawn by the project's
# truth simulator and by the independent one (tools/altsim), each calibrated (NLSQ) and diagnosed
# blind at the station's false-alarm rate per run; a run counts as a false alarm when the diagnosis
# says anything but "consistent" (the station would end it REVIEW). Prints per sequence and
# simulator the count, the rate and its exact 95 % interval, and the totals.
# Usage: tools/bench_false_alarm.sh [NULLS_PER_SEQUENCE] [RATE] [BUILD_DIR]
#        (defaults 500, 1e-4 = the station's [calibration] gap_false_alarm, build)
# IMUCAL_BENCH_SIMULATORS="truth alt" and IMUCAL_BENCH_SEQUENCES="short factory-60 pos19
# factory-std" choose the sets; IMUCAL_BENCH_OUT=DIR keeps the JSON of each set.
set -euo pipefail
cd "$(dirname "$0")/.."
NULLS=${1:-500}
RATE=${2:-1e-4}
BIN=$(realpath "${3:-build}")/bin
OUT=${IMUCAL_BENCH_OUT:-$(mktemp -d "${TMPDIR:-/tmp}/imucal-bench-fa-XXXXXX")}
mkdir -p "$OUT"
SIMS=${IMUCAL_BENCH_SIMULATORS:-truth alt}
SEQS=${IMUCAL_BENCH_SEQUENCES:-short factory-60 pos19 factory-std}
start=$SECONDS
for sim in $SIMS; do
  for seq in $SEQS; do
    # --runs 1 --pairs 0: the null runs are the point; one run per effect keeps the thresholds'
    # computation honest (the command needs at least one). Seeds differ per sequence and simulator.
    seed=$(( $(printf '%s' "$sim$seq" | cksum | cut -d' ' -f1) % 100000 + 1 ))
    t0=$SECONDS
    "$BIN/imucal" validate-diagnosis --simulator "$sim" --sequence "$seq" --runs 1 --pairs 0 \
      --nulls "$NULLS" --false-alarm "$RATE" --seed "$seed" --json >"$OUT/$sim-$seq.json" \
      2>/dev/null || true  # exit 3 (below a bar) still writes the figures
    echo "$sim $seq: $((SECONDS - t0)) s" >&2
  done
done
python3 - "$OUT" "$RATE" $SIMS <<'PY'
import json, math, os, sys
out, rate, sims = sys.argv[1], float(sys.argv[2]), sys.argv[3:]

def cp(k, n, level=0.95):
    # Clopper-Pearson by bisection on the binomial CDF (the same rule as calib/core/binomial_interval).
    def cdf(k, p):
        if p <= 0: return 1.0
        if p >= 1: return 1.0 if k >= n else 0.0
        return min(1.0, sum(math.exp(math.lgamma(n + 1) - math.lgamma(i + 1) - math.lgamma(n - i + 1)
                                     + i * math.log(p) + (n - i) * math.log1p(-p)) for i in range(k + 1)))
    def solve(f, target):
        lo, hi = 0.0, 1.0
        for _ in range(100):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if f(mid) > target else (lo, mid)
        return (lo + hi) / 2
    tail = (1 - level) / 2
    up = 1.0 if k == n else solve(lambda p: cdf(k, p), tail)
    low = 0.0 if k == 0 else solve(lambda p: cdf(k - 1, p), 1 - tail)
    return low, up

print(f"false alarms at a rate of {rate:g} per run (null runs ending anything but consistent)")
print(f"{'simulator':10} {'sequence':12} {'nulls':>6} {'alarms':>6} {'rate %':>7} {'95 % interval %':>17}")
for sim in sims:
    tk = tn = 0
    for f in sorted(os.listdir(out)):
        if not f.startswith(sim + "-") or not f.endswith(".json"): continue
        j = json.load(open(os.path.join(out, f)))
        n = j["null_runs"]; k = round(j["false_alarm"] * n)
        lo, up = cp(k, n)
        tk += k; tn += n
        print(f"{sim:10} {j['sequence']:12} {n:6d} {k:6d} {100*k/max(n,1):7.3f}   {100*lo:6.3f}-{100*up:6.3f}")
        for r in j["runs"]:
            if not r["injected"] and (r["named"] != "none" or r["verdict"] != "consistent"):
                print(f"    alarm: seed {r['seed']} verdict {r['verdict']} named {r['named']}")
    if tn:
        lo, up = cp(tk, tn)
        print(f"{sim:10} {'all':12} {tn:6d} {tk:6d} {100*tk/tn:7.3f}   {100*lo:6.3f}-{100*up:6.3f}")
PY
echo "bench_false_alarm: $((SECONDS - start)) s; JSON in $OUT" >&2
