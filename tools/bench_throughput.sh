#!/usr/bin/env bash
# The station's throughput (issue #23 item 3; figures in README, "Several units per table run"):
# stationsim (1, 2 or 4 units on its table) and stationd as processes at simulated real time x SPEED,
# RUNS table runs back to back per case (factory-std and factory-fast, 1, 2 and 4 units), each
# followed to its last verdict with `stationctl run start --serial ... --wait`. Per case:
#   table minutes per calibrated unit   the run's table time (its archive's data span) / units
#   calibration wall time               capture end (run.toml end_time) to the last unit's verdict
#   units per hour at real time         3600 x units / (table time + calibration wall time), one
#                                       station, loading and unloading the fixture not counted
#   samples lost                        the daemon's own counters over every unit (samples_lost +
#                                       frames_error of each run's capture)
#   daemon CPU and peak memory          utime + stime of stationd over the case, its VmHWM
# Every unit must end PASS (the script says so otherwise). A benchmark, not CI.
# Usage: tools/bench_throughput.sh [BUILD_DIR] [--runs N] [--speed X] [--sequences "A B"]
#        [--units "1 2 4"]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=build RUNS=2 SPEED=200 SEQUENCES="factory-std factory-fast" UNITS="1 2 4"
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) RUNS=$2; shift 2 ;;
    --speed) SPEED=$2; shift 2 ;;
    --sequences) SEQUENCES=$2; shift 2 ;;
    --units) UNITS=$2; shift 2 ;;
    -*) echo "bench_throughput.sh: unknown option $1" >&2; exit 2 ;;
    *) BUILD=$1; shift ;;
  esac
done
BIN=$(realpath "$BUILD")/bin
for p in stationsim stationd stationctl; do
  [ -x "$BIN/$p" ] || { echo "bench_throughput.sh: no $BIN/$p (build it first)" >&2; exit 2; }
done
TICK=$(getconf CLK_TCK)
SLOTS=(A B C D)
MOUNTS=("0/0/0" "0/0/90" "0/0/180" "0/0/-90")
LEVERS=("0.12/0/0.04" "0/0.12/0.04" "-0.12/0/0.04" "0/-0.12/0.04")
SIM_PID="" D_PID="" WORK=""
cleanup() {
  [ -n "$D_PID" ] && kill "$D_PID" 2>/dev/null && wait "$D_PID" 2>/dev/null || true
  [ -n "$SIM_PID" ] && kill "$SIM_PID" 2>/dev/null && wait "$SIM_PID" 2>/dev/null || true
  [ -n "$WORK" ] && rm -rf "$WORK"
  SIM_PID="" D_PID="" WORK=""
}
trap cleanup EXIT

cpu_ticks() { awk '{print $14 + $15}' "/proc/$1/stat"; }

# case SEQUENCE N: one station with N units, RUNS table runs; prints one table row.
run_case() {
  local seq=$1 n=$2
  WORK=$(mktemp -d /tmp/imucal-tput-XXXXXX)
  local sim_args=(--modbus 127.0.0.1:0 --can "$WORK/bus-A.sock" --ready-file "$WORK/ready.json"
                  --speed "$SPEED" --seed 7 --mount "${MOUNTS[0]}" --lever-arm "${LEVERS[0]}")
  local i imus=""
  for ((i = 1; i < n; i++)); do
    sim_args+=(--also "$WORK/bus-${SLOTS[i]}.sock,mount=${MOUNTS[i]},lever=${LEVERS[i]}")
  done
  "$BIN/stationsim" "${sim_args[@]}" >"$WORK/sim.out" 2>"$WORK/sim.err" &
  SIM_PID=$!
  for _ in $(seq 100); do [ -s "$WORK/ready.json" ] && break; sleep 0.1; done
  local modbus
  modbus=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["modbus"])' "$WORK/ready.json")
  for ((i = 0; i < n; i++)); do
    imus+="[[imu]]
slot = \"${SLOTS[i]}\"
can = \"unixcan:$WORK/bus-${SLOTS[i]}.sock\"
mount_rpy_deg = [${MOUNTS[i]//\//, }]
lever_arm_m = [${LEVERS[i]//\//, }]
"
  done
  python3 - "$WORK/ready.json" "$WORK" "$modbus" >"$WORK/stationd.toml" <<'EOF'
import json, sys
ready, work, modbus = json.load(open(sys.argv[1])), sys.argv[2], sys.argv[3]
s = ready["site"]
print(f'''[station]
name = "throughput"
lat_deg = {s["lat_deg"]}
lon_deg = {s["lon_deg"]}
height_m = {s["height_m"]}
gravity_mps2 = {s["gravity_mps2"]}
data_dir = "{work}/data"
[control]
socket = "{work}/control.sock"
[turntable]
endpoint = "{modbus}"
poll_period_ms = 5''')
EOF
  printf '%s[calibration]\ndefault_sequence = "%s"\n[log]\nlevel = "warn"\n' "$imus" "$seq" >>"$WORK/stationd.toml"
  "$BIN/stationd" --config "$WORK/stationd.toml" >"$WORK/d.out" 2>"$WORK/d.err" &
  D_PID=$!
  for _ in $(seq 100); do "$BIN/stationctl" --config "$WORK/stationd.toml" run status >/dev/null 2>&1 && break; sleep 0.1; done
  local cpu0 t0 r serials table_s=0 calib_s=0 pass=0 units=0 lost_total=0
  cpu0=$(cpu_ticks "$D_PID")
  t0=$(date +%s.%N)
  for ((r = 1; r <= RUNS; r++)); do
    serials=()
    for ((i = 0; i < n; i++)); do serials+=(--serial "TP-$r-${SLOTS[i]}"); done
    "$BIN/stationctl" --config "$WORK/stationd.toml" run start "${serials[@]}" --wait \
      >"$WORK/run-$r.out" 2>"$WORK/run-$r.err" || true
    local figures
    figures=$("$BIN/stationctl" --config "$WORK/stationd.toml" --json history --limit 0 |
      python3 -c '
import json, sys, tomllib, datetime
r, n = sys.argv[1], int(sys.argv[2])
runs = [x for x in json.load(sys.stdin)["runs"] if x["serial"].startswith(f"TP-{r}-")]
t = lambda s: datetime.datetime.fromisoformat(s.replace("Z", "+00:00")).timestamp()
info = tomllib.load(open(runs[0]["archive_path"] + "/run.toml", "rb"))
# The table time: the first unit archive data span (imu.csv first and last rows).
rows = open(runs[0]["archive_path"] + "/imu.csv").read().split("\n")
body = [l for l in rows[1:] if l.strip()]
span = float(body[-1].split(",")[0]) - float(body[0].split(",")[0])
capture_end = t(info["run"]["end_time"] if "run" in info else info["end_time"])
last = max(t(x["ended_at"]) for x in runs)
lost = sum(x["capture"].get("samples_lost", 0) + x["capture"].get("frames_error", 0) for x in runs)
print(span, last - capture_end, sum(x["verdict"] == "PASS" for x in runs), len(runs), lost)
' "$r" "$n")
    read -r span calib ok count lost <<<"$figures"
    lost_total=$((lost_total + lost))
    table_s=$(echo "$table_s + $span" | bc -l)
    calib_s=$(echo "$calib_s + $calib" | bc -l)
    pass=$((pass + ok))
    units=$((units + count))
  done
  local wall cpu hwm
  wall=$(echo "$(date +%s.%N) - $t0" | bc -l)
  cpu=$(echo "($(cpu_ticks "$D_PID") - $cpu0) / $TICK" | bc -l)
  hwm=$(awk '/VmHWM/ {print $2}' "/proc/$D_PID/status")
  awk -v seq="$seq" -v n="$n" -v runs="$RUNS" -v table="$table_s" -v calib="$calib_s" -v pass="$pass" \
    -v units="$units" -v wall="$wall" -v cpu="$cpu" -v hwm="$hwm" -v lost="$lost_total" 'BEGIN {
      per_run_table = table / runs; per_run_calib = calib / runs
      printf "| %s | %d | %.1f | %.2f | %.0f | %.1f | %d/%d | %d | %.0f s | %.0f s (%.0f %%) | %.0f MiB |\n",
        seq, n, per_run_table / 60, per_run_table / 60 / n, per_run_calib,
        3600 * n / (per_run_table + per_run_calib), pass, units, lost, wall, cpu, 100 * cpu / wall,
        hwm / 1024
    }'
  cleanup
}

echo "speed x$SPEED, $RUNS table runs per case, $(nproc) cores ($(date '+%F %T'))"
echo "| sequence | units | table min a run | table min per unit | calibration wall s | units/h at real time | PASS | samples lost | wall | daemon CPU | daemon peak RSS |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for seq in $SEQUENCES; do
  for n in $UNITS; do run_case "$seq" "$n"; done
done
