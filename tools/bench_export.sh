#!/usr/bin/env bash
# Benchmark of `stationctl export` (issue #11 item 3; figures in README, "Streamed export"): a
# history of 100 000 runs (200 000 rows: both methods of each run), exported through a running
# stationd in each format, then straight from the database with the daemon stopped; wall time and
# the client's peak memory (GNU time), the daemon's memory before and after, and a client killed in
# the middle of an export (the daemon must go on serving).
# Usage: tools/bench_export.sh [BUILD_DIR]      (default build; needs build/bin/db_history_bench)
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "${1:-build}")/bin
WORK=$(mktemp -d "${TMPDIR:-/tmp}/imucal-bench-export-XXXXXX")
DAEMON=""
cleanup() {
  [ -n "$DAEMON" ] && kill "$DAEMON" 2>/dev/null && wait "$DAEMON" 2>/dev/null
  rm -rf "$WORK"
}
trap cleanup EXIT

# The history: db_history_bench builds it once (1 000 serials x 100 runs) and keeps it.
DB=${IMUCAL_BENCH_DB:-/tmp/imucal-history-bench.db}
IMUCAL_BENCH_DB=$DB "$BIN/db_history_bench" --benchmark_filter=BM_ActiveParams >/dev/null 2>&1
cp "$DB" "$WORK/history.sqlite"
cat >"$WORK/stationd.toml" <<CONF
[station]
name = "bench"
lat_deg = 55.0
lon_deg = 12.0
height_m = 30.0
data_dir = "data"
database = "history.sqlite"
[control]
socket = "stationd.sock"
[turntable]
endpoint = "tcp:127.0.0.1:1"
reconnect_give_up_ms = 0
[imu]
can = "unixcan:$WORK/none.sock"
CONF

rss_kb() { awk '/^VmRSS/ {print $2}' "/proc/$1/status"; }
ctl() { "$BIN/stationctl" --config "$WORK/stationd.toml" "$@"; }
measure() {  # measure LABEL STDOUT ARGS...: one export, its wall time and the client's peak RSS
  local label=$1 out=$2
  shift 2
  /usr/bin/time -f "%e %M" -o "$WORK/time" "$BIN/stationctl" --config "$WORK/stationd.toml" "$@" \
    >"$out" 2>/dev/null
  read -r wall peak <"$WORK/time"
  awk -v l="$label" -v w="$wall" -v p="$peak" 'BEGIN {printf "%-38s %6.2f s %7.1f MB client peak\n", l, w, p / 1024}'
}

"$BIN/stationd" --config "$WORK/stationd.toml" >"$WORK/stationd.out" 2>"$WORK/stationd.log" &
DAEMON=$!
for _ in $(seq 100); do ctl run status >/dev/null 2>&1 && break; sleep 0.1; done
ctl run status >/dev/null
echo "history: 100 000 runs, 200 000 rows ($(du -m "$WORK/history.sqlite" | cut -f1) MB)"
before=$(rss_kb "$DAEMON")
for f in csv json ndjson; do
  measure "through stationd, --format $f" /dev/null export --format "$f" --output "$WORK/out.$f"
done
measure "through stationd, csv to stdout" /dev/null export --format csv
# A client that goes away in the middle: the daemon goes on (and answers at once).
set +o pipefail
ctl export --format json | head -c 10000000 >/dev/null
set -o pipefail
ctl run status >/dev/null && echo "client gone after 10 MB of json: stationd answers run status"
after=$(rss_kb "$DAEMON")
awk -v b="$before" -v a="$after" \
  'BEGIN {printf "stationd RSS: %.1f MB before, %.1f MB after the exports\n", b / 1024, a / 1024}'
kill "$DAEMON"
wait "$DAEMON" 2>/dev/null || true
DAEMON=""
measure "from the database (daemon down), csv" /dev/null export --format csv --output "$WORK/db.csv"
cmp -s "$WORK/out.csv" "$WORK/db.csv" && echo "daemon and database exports are identical (csv)"
wc -l <"$WORK/out.ndjson" | awk '{print "ndjson lines:", $1}'
