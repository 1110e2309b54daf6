#!/usr/bin/env bash
# Side-by-side benchmark of the calibration job (issue #11 item 2; figures in README, "Speed and
# memory"): `imucal bench` of this build and of a baseline build (default: b90c6e1, the code when
# issue #11 was filed) on the same archive and machine, in alternating rounds so that load from
# other work hits both alike; then both builds' `imucal calibrate --json` compared parameter by
# parameter in units of the baseline's σ.
# Usage: tools/bench_calibration.sh [BUILD_DIR] [--baseline REV] [--rounds N] [--repeat N]
#   The baseline is built once (imucal only) in build-baseline/REV and reused.
#   The archive: $IMUCAL_BENCH_ARCHIVE or var/runs/bench60 (simulated with factory-60 if missing).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=build BASELINE=b90c6e1 ROUNDS=3 REPEAT=5
while [ $# -gt 0 ]; do
  case "$1" in
    --baseline) BASELINE=$2; shift 2 ;;
    --rounds) ROUNDS=$2; shift 2 ;;
    --repeat) REPEAT=$2; shift 2 ;;
    -*) echo "bench_calibration.sh: unknown option $1" >&2; exit 2 ;;
    *) BUILD=$1; shift ;;
  esac
done
NEW=$(realpath "$BUILD")/bin/imucal
[ -x "$NEW" ] || { echo "bench_calibration.sh: no $NEW (build first)" >&2; exit 2; }
ARCHIVE=${IMUCAL_BENCH_ARCHIVE:-var/runs/bench60}
if [ ! -d "$ARCHIVE" ]; then
  echo "simulating $ARCHIVE (factory-60, seed 42)..."
  "$NEW" simulate --sequence factory-60 --seed 42 --out "$ARCHIVE" >/dev/null
fi

# The baseline build: a worktree of REV with only imucal built, kept for the next run.
REV=$(git rev-parse --short "$BASELINE")
BASE_DIR=$(pwd)/build-baseline/$REV
OLD=$BASE_DIR/build/bin/imucal
if [ ! -x "$OLD" ]; then
  echo "building the baseline imucal at $REV in $BASE_DIR..."
  rm -rf "$BASE_DIR" && git worktree prune
  git worktree add --detach -f "$BASE_DIR" "$REV" >/dev/null
  launcher=()
  command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  cmake -S "$BASE_DIR" -B "$BASE_DIR/build" -DCMAKE_BUILD_TYPE=Release -DIMUCAL_BUILD_TESTS=OFF \
    "${launcher[@]}" >/dev/null
  cmake --build "$BASE_DIR/build" -j2 --target imucal >/dev/null
fi

OUT=$(mktemp -d "${TMPDIR:-/tmp}/imucal-bench-cal-XXXXXX")
trap 'rm -rf "$OUT"' EXIT
for r in $(seq "$ROUNDS"); do
  echo "round $r of $ROUNDS..."
  "$OLD" bench "$ARCHIVE" --repeat "$REPEAT" --json >"$OUT/old.$r.json"
  "$NEW" bench "$ARCHIVE" --repeat "$REPEAT" --json >"$OUT/new.$r.json"
done
"$OLD" calibrate "$ARCHIVE" --json >"$OUT/old.cal.json" 2>/dev/null || true
"$NEW" calibrate "$ARCHIVE" --json >"$OUT/new.cal.json" 2>/dev/null || true

python3 - "$OUT" "$ROUNDS" "$REV" <<'PY'
import json, sys
out, rounds, rev = sys.argv[1], int(sys.argv[2]), sys.argv[3]
def load(name):
    return [json.load(open(f"{out}/{name}.{r}.json")) for r in range(1, rounds + 1)]
old, new = load("old"), load("new")
def best(runs, key): return min(r[key] for r in runs)
def worst(runs, key): return max(r[key] for r in runs)
o_min, n_min = best(old, "wall_s_min"), best(new, "wall_s_min")
o_med = sorted(r["wall_s_median"] for r in old)[rounds // 2]
n_med = sorted(r["wall_s_median"] for r in new)[rounds // 2]
print(f"\n{old[0]['samples']} samples, {rounds} rounds x {old[0]['repeat']} runs each")
print(f"{'':24}{'wall min':>10}{'median':>10}{'peak RSS':>11}")
print(f"{'baseline ' + rev:24}{o_min:>9.3f}s{o_med:>9.3f}s{worst(old, 'peak_rss_mb'):>8.1f} MB")
print(f"{'this build':24}{n_min:>9.3f}s{n_med:>9.3f}s{worst(new, 'peak_rss_mb'):>8.1f} MB")
print(f"{'ratio':24}{n_min / o_min:>9.2f}x{n_med / o_med:>9.2f}x")

def flat(o, p=""):
    if isinstance(o, dict):
        return {k2: v2 for k, v in o.items() for k2, v2 in flat(v, f"{p}.{k}").items()}
    if isinstance(o, list):
        return {k2: v2 for i, v in enumerate(o) for k2, v2 in flat(v, f"{p}[{i}]").items()}
    return {p: o}
a, b = json.load(open(f"{out}/old.cal.json")), json.load(open(f"{out}/new.cal.json"))
print("\nresults, this build against the baseline (|Δ| / baseline σ, largest parameter):")
status = 0
for m in ("ains", "nlsq"):
    if m not in a or m not in b:
        print(f"  {m}: missing in one of the outputs"); status = 1; continue
    pa, pb, s = flat(a[m]["params"]), flat(b[m]["params"]), flat(a[m]["sigma"])
    d, k = max((abs(pa[k] - pb[k]) / s[k], k) for k in pa if s[k] > 0)
    print(f"  {m:5} {d:.4f} σ at {k[1:]}")
    status |= d > 0.1
print(f"  verdicts: baseline {a.get('verdict')}, this build {b.get('verdict')}")
sys.exit(status)
PY
