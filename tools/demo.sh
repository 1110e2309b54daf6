#!/usr/bin/env bash
# The main job (README): the station on loopback. Starts the simulated station hardware
# (stationsim: Modbus TCP turntable + CAN IMU, accelerated) and the station daemon (stationd) with a
# config written under var/demo/ (SQLite history and run archives there too), runs one unit through
# a sequence with `stationctl run start --wait` (live progress line), prints the verdict and the
# unit's history, and stops both processes cleanly (also on Ctrl-C or an error).
#
# Usage: tools/demo.sh [SERIAL] [SEQUENCE]          (defaults: SIM-0001 factory-std)
# Environment:
#   SPEED=200        simulation speed factor (sim seconds per wall second)
#   BUILD_DIR=build  build tree (tools/setup.sh --main builds the four programs there)
#   SKIP_BUILD=1     do not run tools/setup.sh --main (install packages if missing + build) first
#   DEMO_DIR=var/demo  where the config, logs, archives and history go
#   DEMO_FRESH=1     start with an empty DEMO_DIR (otherwise the history keeps earlier demo runs)
# Exit code: stationctl's (0 = done with verdict PASS, 1 = review/failed/aborted, others: errors).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
SERIAL=${1:-SIM-0001}
SEQ=${2:-factory-std}
SPEED=${SPEED:-200}
BUILD_DIR=${BUILD_DIR:-build}
BIN="$(realpath -m "$BUILD_DIR")/bin"
DEMO=$(realpath -m "${DEMO_DIR:-var/demo}")   # .gitignore ignores var/

if [ "${SKIP_BUILD:-0}" != 1 ]; then
  IMUCAL_BUILD_DIR="$BUILD_DIR" bash tools/setup.sh --main
fi
for exe in stationsim stationd stationctl; do
  if [ ! -x "$BIN/$exe" ]; then
    echo "demo: $BIN/$exe is missing (build it: cmake --build $BUILD_DIR --target $exe)" >&2
    exit 2
  fi
done

[ "${DEMO_FRESH:-0}" = 1 ] && rm -rf "$DEMO"
mkdir -p "$DEMO"
CONFIG="$DEMO/stationd.toml"
SOCKET="$DEMO/stationd.sock"
rm -f "$DEMO/sim-ready.json" "$DEMO/bus.sock"

SIM_PID=""
DAEMON_PID=""
stop_process() {  # PID NAME: SIGTERM, wait up to 10 s, then SIGKILL
  local pid=$1 name=$2
  [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null || return 0
  kill -TERM "$pid" 2>/dev/null || true
  for _ in $(seq 100); do
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.1
  done
  if kill -0 "$pid" 2>/dev/null; then
    echo "demo: $name did not stop on SIGTERM, killing it" >&2
    kill -KILL "$pid" 2>/dev/null || true
  fi
  wait "$pid" 2>/dev/null || true
}
cleanup() {
  echo "== stopping stationd and stationsim" >&2
  # The daemon first: on SIGTERM it brings the table to a safe stop (through the simulator).
  stop_process "$DAEMON_PID" stationd
  stop_process "$SIM_PID" stationsim
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# Both servers run in their own sessions (setsid): a Ctrl-C in the terminal reaches this script and
# stationctl only, and cleanup() then stops the daemon first (run aborted, table to a safe stop
# through the still running simulator) and the simulator after it.
echo "== stationsim: simulated turntable (Modbus TCP) + IMU (CAN), speed ${SPEED}x"
setsid "$BIN/stationsim" --modbus 127.0.0.1:0 --can "$DEMO/bus.sock" --speed "$SPEED" \
  --ready-file "$DEMO/sim-ready.json" --truth-out "$DEMO/truth.json" \
  >"$DEMO/stationsim.out" 2>"$DEMO/stationsim.log" &
SIM_PID=$!
for _ in $(seq 200); do
  [ -s "$DEMO/sim-ready.json" ] && break
  kill -0 "$SIM_PID" 2>/dev/null || { echo "demo: stationsim exited:" >&2; cat "$DEMO/stationsim.log" >&2; exit 4; }
  sleep 0.1
done
[ -s "$DEMO/sim-ready.json" ] || { echo "demo: stationsim not ready after 20 s" >&2; exit 4; }
MODBUS=$(sed -n 's/.*"modbus" *: *"\([^"]*\)".*/\1/p' "$DEMO/sim-ready.json")
echo "   $(cat "$DEMO/sim-ready.json")"

# The station config (documented key by key in station/config/stationd.example.toml). Relative paths are
# relative to this file's directory, var/demo/.
cat >"$CONFIG" <<EOF
# Written by tools/demo.sh: the station on loopback against stationsim.
[station]
name = "demo-station"
lat_deg = 55.7856     # the simulator's site (demo factory, calib/core/site_presets.hpp)
lon_deg = 12.5213
height_m = 30.0
data_dir = "data"
database = "data/history.sqlite"

[control]
socket = "stationd.sock"

[turntable]
endpoint = "$MODBUS"

[imu]
can = "unixcan:bus.sock"
rate_hz = 100.0

[calibration]
default_sequence = "factory-std"
k_sigma = 4.0

[log]
level = "info"
EOF

echo "== stationd --config $CONFIG (log: $DEMO/stationd.log)"
setsid "$BIN/stationd" --config "$CONFIG" >"$DEMO/stationd.out" 2>"$DEMO/stationd.log" &
DAEMON_PID=$!
ready=0
for _ in $(seq 300); do
  kill -0 "$DAEMON_PID" 2>/dev/null || { echo "demo: stationd exited:" >&2; cat "$DEMO/stationd.log" >&2; exit 4; }
  if [ -S "$SOCKET" ] && "$BIN/stationctl" --config "$CONFIG" run status >/dev/null 2>&1; then
    ready=1
    break
  fi
  sleep 0.1
done
[ "$ready" = 1 ] || { echo "demo: stationd does not answer after 30 s" >&2; cat "$DEMO/stationd.log" >&2; exit 4; }

echo "== stationctl run start --serial $SERIAL --sequence $SEQ --wait"
set +e
"$BIN/stationctl" --config "$CONFIG" run start --serial "$SERIAL" --sequence "$SEQ" \
  --operator "${USER:-demo}" --wait
rc=$?
set -e
case $rc in
  0) verdict="done, verdict PASS" ;;
  1) verdict="finished without PASS (review, failed or aborted: see the reason above and 'show')" ;;
  *) verdict="error (stationctl exit code $rc)" ;;
esac
echo
echo "== verdict: $verdict"
echo
echo "== stationctl history $SERIAL"
"$BIN/stationctl" --config "$CONFIG" history "$SERIAL" || true
echo
echo "More: $BIN/stationctl --config $CONFIG show RUN_ID | params $SERIAL | export --format csv"
echo "Archives: $DEMO/data/runs/   database: $DEMO/data/history.sqlite"
exit $rc
