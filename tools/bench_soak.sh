#!/usr/bin/env bash
# The long soak (issue #22 item 4; figures in README, "Soak"): tests/e2e/station_soak_slow_test with
# IMUCAL_SOAK_RUNS runs (default 1000: ~45 min at 400x, two cores) over IMUCAL_SOAK_UNITS units
# (default 50: a unit's whole history stays plant-sized, see the test) and one CSV row per run
# (IMUCAL_SOAK_LOG), then a summary of the CSV: the daemon's RSS (first and last run, least-squares
# slope over the second half, the test's own check), its open descriptors, the latency of the
# `stationctl history` made right after each run and of the parallel querier's queries, the
# database size and the wall time. A benchmark, not CI (CI runs the same test with 12 runs).
# Usage: tools/bench_soak.sh [BUILD_DIR] [--runs N] [--units N] [--csv FILE]
#   BUILD_DIR default build (needs BUILD_DIR/tests/e2e_station_soak_slow_test and its bin/);
#   the CSV is kept (default var/soak/soak-<runs>-<date>.csv); run it under nice on a shared machine.
#   With --summary-only FILE it only summarises an existing CSV.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=build RUNS=1000 UNITS=50 CSV="" ONLY=""
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) RUNS=$2; shift 2 ;;
    --units) UNITS=$2; shift 2 ;;
    --csv) CSV=$2; shift 2 ;;
    --summary-only) ONLY=$2; shift 2 ;;
    -*) echo "bench_soak.sh: unknown option $1" >&2; exit 2 ;;
    *) BUILD=$1; shift ;;
  esac
done

summarise() {  # summarise CSV: the figures the README quotes
  local csv=$1
  # Columns: run,run_id,verdict,rss_kb,fds,db_bytes,wal_bytes,run_s,history_ms,
  #          q_history_n,q_history_median_ms,q_history_max_ms,q_export_n,q_export_median_ms,q_export_max_ms
  awk -F, 'NR > 1 {
      n++; rss[n] = $4; fds = $5; if (n == 1 || fds < fmin) fmin = fds; if (fds > fmax) fmax = fds
      if ($3 == "PASS") pass++; db = $6; wal = $7; run_s += $8; qn += $10 + $13
      if ($12 > qhmax) qhmax = $12; if ($15 > qemax) qemax = $15
    }
    END {
      if (n < 2) { print "bench_soak.sh: fewer than two runs in the CSV" > "/dev/stderr"; exit 1 }
      h = int(n / 2); m = n - h; sx = sy = 0
      for (k = h + 1; k <= n; k++) { sx += k; sy += rss[k] }
      mx = sx / m; my = sy / m; sxy = sxx = 0
      for (k = h + 1; k <= n; k++) { sxy += (k - mx) * (rss[k] - my); sxx += (k - mx) ^ 2 }
      slope = (sxx > 0) ? sxy / sxx : 0
      lo = rss[1]; hi = rss[1]; for (k = 1; k <= n; k++) { if (rss[k] < lo) lo = rss[k]; if (rss[k] > hi) hi = rss[k] }
      printf "runs: %d, %d PASS; %.1f s a run on average (start to verdict)\n", n, pass, run_s / n
      printf "daemon RSS: run 1 %d kB, run %d %d kB (min %d, max %d kB); slope over runs %d-%d %+.2f kB/run\n", \
        rss[1], n, rss[n], lo, hi, h + 1, n, slope
      printf "daemon descriptors (idle, no client): min %d, max %d\n", fmin, fmax
      printf "database: %.1f MiB file + %.1f MiB WAL after run %d\n", db / 1048576, wal / 1048576, n
      printf "parallel querier: %d queries; slowest history %.0f ms, slowest export %.0f ms\n", qn, qhmax, qemax
    }' "$csv"
  # Medians and p99 (nearest rank) of the per-run columns.
  pct() {  # pct COLUMN: median p99 max of a column
    tail -n +2 "$csv" | cut -d, -f"$1" | sort -g |
      awk '{v[NR] = $1} END {p = int(0.99 * NR + 0.999999); printf "median %.1f ms, p99 %.1f ms, max %.1f ms", v[int((NR + 1) / 2)], v[p], v[NR]}'
  }
  echo "history right after each run (through stationd, nothing beside it): $(pct 9)"
  echo "querier's history queries, per-run median: $(pct 11)"
  echo "querier's exports (csv/json, whole history), per-run median: $(pct 14)"
  awk -F, 'NR > 1 && $3 != "PASS" {print "not PASS: run " $1 " (id " $2 "): " $3 ", RSS " $4 " kB after it"}' "$csv"
  head -2 "$csv" | tail -1 | cut -d, -f1-9 | sed 's/^/first row: /'
  tail -1 "$csv" | cut -d, -f1-9 | sed 's/^/last row:  /'
}

if [ -n "$ONLY" ]; then
  summarise "$ONLY"
  exit 0
fi

TEST=$(realpath "$BUILD")/tests/e2e_station_soak_slow_test
[ -x "$TEST" ] || { echo "bench_soak.sh: no $TEST (build e2e_station_soak_slow_test first)" >&2; exit 2; }
[ -n "$CSV" ] || CSV=var/soak/soak-$RUNS-$(date +%F).csv
mkdir -p "$(dirname "$CSV")"
LOG=${CSV%.csv}.log
echo "soak: $RUNS runs over $UNITS units, CSV $CSV, test output $LOG ($(date '+%F %T'))"
start=$(date +%s)
set +e
IMUCAL_SOAK_RUNS=$RUNS IMUCAL_SOAK_UNITS=$UNITS IMUCAL_SOAK_LOG=$CSV "$TEST" >"$LOG" 2>&1
status=$?
set -e
end=$(date +%s)
grep -E '^\[soak\] (daemon RSS|[0-9]+ queries)' "$LOG" || true
awk -v s=$((end - start)) 'BEGIN {printf "wall time: %d min %02d s\n", s / 60, s % 60}'
summarise "$CSV"
if [ "$status" -ne 0 ]; then
  echo "the soak test FAILED (exit $status): see $LOG" >&2
  grep -E 'Failure|Expected|Which is|creeps|grew|leak' "$LOG" | head -20 >&2 || true
fi
exit "$status"
