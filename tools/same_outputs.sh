#!/usr/bin/env bash
# Behaviour unchanged across a restructure: runs the same commands with two builds' programs and
# compares what they write, byte for byte, but for run times, wall-clock stamps and paths.
#
#   tools/same_outputs.sh OLD_BIN NEW_BIN [WORK_DIR]
#
# OLD_BIN and NEW_BIN are directories holding imucal, stationd, stationsim and stationctl (e.g. a
# build of the commit before the change: `git worktree add /tmp/old REV && cd /tmp/old &&
# IMUCAL_BUILD_DIR=build bash tools/setup.sh --main`, then /tmp/old/build/bin). WORK_DIR (default: a
# new temporary directory) keeps both sides' outputs, old/ and new/, for a look at any difference.
# The commands: imucal simulate (factory short and factory-std with an injected effect, land, sea),
# calibrate --method all --json, diagnose --json, evaluate, crlb, effects, validate-diagnosis and
# paper-tables at small counts, import of a raw recording; and a station (stationsim, stationd and
# stationctl as processes) calibrating two of those archives through `stationctl import`, with its
# history, show, params and export. Prints one line per output, "same" or "DIFFERS", and exits 1 if any differs.
set -euo pipefail
[ $# -ge 2 ] || { sed -n '2,15p' "$0" >&2; exit 2; }
OLD=$(realpath "$1")
NEW=$(realpath "$2")
WORK=$(realpath -m "${3:-$(mktemp -d "${TMPDIR:-/tmp}/same-outputs-XXXXXX")}")
ROOT=$(cd "$(dirname "$0")/.." && pwd)
for bin in "$OLD" "$NEW"; do
  for exe in imucal stationd stationsim stationctl; do
    [ -x "$bin/$exe" ] || { echo "same_outputs: $bin/$exe is missing" >&2; exit 2; }
  done
done
rm -rf "$WORK/old" "$WORK/new"
mkdir -p "$WORK/old" "$WORK/new"

# What may differ between two runs of the same program: run times, wall-clock stamps, the
# software's version line, the work directory's own path.
normalise() {  # FILE SIDE_DIR
  sed -E -e "s#$2#WORK#g" \
    -e 's/"(runtime_s|[a-z_]*wall[a-z_]*|[a-z_]*elapsed[a-z_]*|[a-z_]*_seconds|duration_s|[a-z_]*_at|[a-z_]*_at_ms|archive_sha256|start_time|end_time|time_utc|[a-z_]*_time)": *("[^"]*"|[-0-9.e+]+)/"\1": T/g' \
    -e 's/^(start_time|end_time|software_version) = .*/\1 = T/' \
    -e 's/^(  archive sha  ).*/\1T/' \
    -e 's/[0-9]{4}-[0-9]{2}-[0-9]{2}[T ][0-9]{2}:[0-9]{2}:[0-9]{2}(\.[0-9]+)?Z?/TIMESTAMP/g' \
    -e 's/\b(in|took|runtime|time) [0-9.]+ ?(s|ms)\b/\1 T/g' \
    -e 's/(iterations?), [0-9.]+ s\b/\1, T s/g' -e 's/, [0-9]+ s(, about [0-9]+ s left)?/, T s/g' "$1" |
    case "$1" in
      # CSV exports: the columns of times, run times and the archive's hash (an imported archive's
      # copy records when it was imported), found by their header names.
      *.csv) awk -F, -v OFS=, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i ~ /(_at|runtime_s|archive_sha256)$/) m[i] = 1 }
                               NR > 1 { for (i in m) $i = "T" } { print }' ;;
      *) cat ;;
    esac
}

# The station: stationsim and stationd as processes on loopback (as tools/demo.sh starts them); two
# archives written above are imported through the control socket and calibrated by the daemon's
# worker (a live capture's sample count follows wall-clock timing, an imported archive's does not),
# then the history is read back: history, show, params, export.
station_side() {  # BIN OUT
  local bin=$1 st="$2/station"
  mkdir -p "$st"
  setsid "$bin/stationsim" --modbus 127.0.0.1:0 --can "$st/bus.sock" --speed 400 \
    --ready-file "$st/sim-ready.json" >/dev/null 2>"$st/stationsim.log" &
  local sim=$!
  for _ in $(seq 200); do [ -s "$st/sim-ready.json" ] && break; sleep 0.1; done
  local modbus
  modbus=$(sed -n 's/.*"modbus" *: *"\([^"]*\)".*/\1/p' "$st/sim-ready.json")
  cat >"$st/stationd.toml" <<EOF
[station]
name = "same-outputs"
lat_deg = 55.7856
lon_deg = 12.5213
height_m = 30.0
data_dir = "data"
database = "data/history.sqlite"
[control]
socket = "stationd.sock"
[turntable]
endpoint = "$modbus"
[imu]
can = "unixcan:bus.sock"
rate_hz = 100.0
EOF
  setsid "$bin/stationd" --config "$st/stationd.toml" >/dev/null 2>"$st/stationd.log" &
  local daemon=$!
  local ctl=("$bin/stationctl" --config "$st/stationd.toml")
  for _ in $(seq 300); do "${ctl[@]}" run status >/dev/null 2>&1 && break; sleep 0.1; done
  "${ctl[@]}" import "$2/short7" --wait >import_short7.txt 2>&1 || true
  "${ctl[@]}" import "$2/land3" --wait >import_land3.txt 2>&1 || true
  "${ctl[@]}" --json history SIM-7 >history.json 2>&1 || true
  "${ctl[@]}" history >history.txt 2>&1 || true
  "${ctl[@]}" --json show 1 >show_1.json 2>&1 || true
  "${ctl[@]}" show 2 >show_2.txt 2>&1 || true
  "${ctl[@]}" params SIM-7 >params.txt 2>&1 || true
  "${ctl[@]}" export --format json >export.json 2>&1 || true
  "${ctl[@]}" export --format csv >export.csv 2>&1 || true
  kill -TERM "$daemon" 2>/dev/null || true
  wait "$daemon" 2>/dev/null || true
  kill -TERM "$sim" 2>/dev/null || true
  wait "$sim" 2>/dev/null || true
}

run_side() {  # SIDE BIN: every command, outputs under $WORK/SIDE
  local side=$1 bin=$2 out="$WORK/$1"
  local imucal="$bin/imucal"
  cd "$out"
  "$imucal" simulate --sequence short --seed 7 --out short7 >sim_short7.txt
  "$imucal" simulate --sequence factory-std --seed 11 --effect gyro_accel_skew=0.002 \
    --out fstd11 >sim_fstd11.txt
  "$imucal" simulate --sequence short --setting land --seed 3 --out land3 >sim_land3.txt
  "$imucal" simulate --sequence short --setting sea --seed 4 --out sea4 >sim_sea4.txt
  for run in short7 fstd11 land3 sea4; do
    "$imucal" calibrate "$run" --method all --json >"cal_$run.json" || true
  done
  "$imucal" calibrate short7 --method all >cal_short7.txt || true
  "$imucal" diagnose short7 --json >diag_short7.json || true
  "$imucal" diagnose fstd11 --json >diag_fstd11.json || true
  "$imucal" crlb --sequence factory-std >crlb_fstd.txt
  "$imucal" crlb --sequence short --effects --json >crlb_short_effects.json
  "$imucal" effects >effects.txt
  "$imucal" validate-diagnosis --sequence short --runs 1 >validate.txt 2>&1 || true
  "$imucal" paper-tables --units 2 >paper.txt 2>&1 || true
  # A raw recording in counts (time, gyro and accelerometer increments): the importer's path.
  awk 'NR > 1 { split($0, c, ","); printf "%.6f %d %d %d %d %d %d\n", c[1], c[2]*1e9, c[3]*1e9, c[4]*1e9, c[5]*1e7, c[6]*1e7, c[7]*1e7 }' \
    land3/imu.csv >raw_counts.txt
  "$imucal" import --file raw_counts.txt --out imported --quantity increments \
    --gyro-scale 1e-9 --accel-scale 1e-7 --serial RAW-1 >import.txt 2>&1 || true
  station_side "$bin" "$out"
  cd - >/dev/null
}

run_side old "$OLD"
run_side new "$NEW"

differ=0
cd "$WORK/old"
while IFS= read -r f; do
  case "$f" in
    station/*) continue ;;  # the station's own files: its logs, lock, database file and the copies of the imported archives
  esac
  if [ ! -e "$WORK/new/$f" ]; then
    echo "MISSING  $f"
    differ=1
  elif cmp -s <(normalise "$WORK/old/$f" "$WORK/old") <(normalise "$WORK/new/$f" "$WORK/new"); then
    echo "same     $f"
  else
    echo "DIFFERS  $f"
    diff <(normalise "$WORK/old/$f" "$WORK/old") <(normalise "$WORK/new/$f" "$WORK/new") | head -8 || true
    differ=1
  fi
done < <(find . -type f | sed 's#^\./##' | sort)
echo "same_outputs: outputs in $WORK/{old,new}"
exit $differ
