#!/usr/bin/env bash
# The room rules' check (tools/check_rooms.cmake, ARCHITECTURE §2.3) fails on every kind of breach:
# a copy of the tree's sources passes as it is, then each mutation below, applied to a fresh copy,
# must make the check exit non-zero naming the breach. Usage: room_rule_mutations.sh SOURCE_DIR
set -euo pipefail
src=${1:?usage: room_rule_mutations.sh SOURCE_DIR}
check=$src/tools/check_rooms.cmake
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0
tops=(calib sequences db drivers station tools)

mkdir "$work/pristine"
cp "$src/CMakeLists.txt" "$work/pristine/"
for top in "${tops[@]}"; do cp -r "$src/$top" "$work/pristine/$top"; done
tree=$work/tree
fresh() { rm -rf "$tree" && cp -r "$work/pristine" "$tree"; }
run_check() { cmake -DSOURCE_DIR="$tree" -P "$check" 2>&1; }

# mutate FILE SED_SCRIPT: edits FILE of the copy; a script that changes nothing is a failure of its
# own (the tree moved on and the mutation no longer tests anything).
mutate() {
  local f=$tree/$1
  local before
  before=$(cat "$f")
  sed -i "$2" "$f"
  if [[ "$(cat "$f")" == "$before" ]]; then
    echo "FAIL: the mutation '$2' changes nothing in $1"; failures=$((failures + 1))
  fi
}
# add_include FILE AFTER_LINE INCLUDE: a line #include "INCLUDE" after the line AFTER_LINE of FILE.
add_include() { mutate "$1" "s|^$2\$|&\\n#include \"$3\"|"; }

# expect_breach NAME PATTERN: the check on the mutated copy exits non-zero and prints PATTERN.
expect_breach() {
  local out rc=0
  out=$(run_check) || rc=$?
  if [[ $rc -eq 0 ]]; then
    echo "FAIL: $1: the check passed"; failures=$((failures + 1))
  elif ! grep -qE -- "$2" <<<"$out"; then
    echo "FAIL: $1: the check failed without naming the breach /$2/:"; echo "$out"
    failures=$((failures + 1))
  else
    echo "ok: $1: $(grep -E -- "$2" <<<"$out" | head -1)"
  fi
}

fresh
if out=$(run_check); then echo "ok: the tree as it is: $out"; else
  echo "FAIL: the tree as it is breaks the rules:"; echo "$out"; failures=$((failures + 1)); fi

# --- calib/: the world and the estimate apart --------------------------------------------------
fresh  # an estimator includes the simulator
add_include calib/ains/ains.cpp '#include "calib/ains/ains.hpp"' calib/sim/truth_sim.hpp
expect_breach "AINS includes the simulator" 'calib/ains/ains.cpp:[0-9]+: includes calib/sim/truth_sim.hpp, but calib/ains/ may include only calib/core'

fresh  # the simulator includes an estimator
add_include calib/sim/truth_stream.hpp '#pragma once' calib/nlsq/nlsq.hpp
expect_breach "the streaming simulator includes NLSQ" 'calib/sim/truth_stream.hpp:[0-9]+: includes calib/nlsq/nlsq.hpp, but calib/sim/'

fresh  # the diagnosis includes the simulator instead of taking a RunSource
add_include calib/diagnosis/diagnosis_validation.cpp '#include "calib/diagnosis/diagnosis_validation.hpp"' calib/sim/sim_input.hpp
expect_breach "the validation includes the simulator" 'calib/diagnosis/diagnosis_validation.cpp:[0-9]+: includes calib/sim/sim_input.hpp'

fresh  # an effect's forward model includes the simulator
add_include calib/effects/size_effect.hpp '#pragma once' calib/sim/truth_sim.hpp
expect_breach "an effect includes the simulator" 'calib/effects/size_effect.hpp:[0-9]+: includes calib/sim/truth_sim.hpp'

fresh  # the graph itself lets an estimator reach the simulator (README kept in step)
mutate calib/rooms.cmake 's|^\(imucal_room(calib/legacy .*MAY_INCLUDE calib/core\))$|\1 calib/studies/paper)|; s|calib/studies/paper))$|calib/studies/paper)|'
mutate calib/legacy/README.md 's|^May include: `calib/core/`|May include: `calib/core/`, `calib/studies/paper/`|'
expect_breach "legacy may reach sim through paper" 'calib/legacy reaches calib/sim \(calib/legacy -> calib/studies/paper -> calib/sim\): the world and the estimate stay apart'

fresh  # the simulator's graph widened
mutate calib/rooms.cmake 's|MAY_INCLUDE calib/core calib/effects sequences)$|MAY_INCLUDE calib/core calib/effects calib/checks sequences)|'
expect_breach "sim may include checks" 'calib/sim reaches calib/checks, calib/ains: the simulator may include calib/core and calib/effects only'

fresh  # a cycle
mutate calib/rooms.cmake 's|^\(imucal_room(calib/core .*MAY_INCLUDE\) sequences)|\1 calib/checks sequences)|'
expect_breach "core depends on checks" 'calib/core depends on itself \(calib/core -> calib/checks -> calib/core\)'

fresh  # a README that says something else than the graph
mutate calib/checks/README.md 's|May include: `calib/core/`, `calib/ains/`|May include: `calib/core/`|'
expect_breach "checks' README omits ains" 'calib/checks/README.md: "May include" names \[calib/core, sequences\] but calib/rooms.cmake gives \[calib/ains, calib/core, sequences\]'

fresh  # a file left outside the rooms, and an include without its room
printf '#pragma once\n' >"$tree/calib/stray.hpp"
mutate calib/core/strapdown.hpp '0,/#include "calib\/core\/earth.hpp"/s//#include "calib\/earth.hpp"/'
expect_breach "a stray file in calib/" 'calib/stray.hpp: a source file in no room of calib/'
expect_breach "an include without its room" 'calib/core/strapdown.hpp:[0-9]+: includes calib/earth.hpp, in no room'

fresh  # calib/ reaches db/
add_include calib/core/param_set.hpp '#pragma once' db/history/repository.hpp
expect_breach "calib/core includes db/history" 'calib/core/param_set.hpp:[0-9]+: includes db/history/repository.hpp, but calib/core/ may include only sequences'

# --- the other top folders -----------------------------------------------------------------------
fresh  # the archive includes the simulator (issue #47)
add_include db/archive/run_archive.hpp '#pragma once' calib/sim/truth_sim.hpp
expect_breach "db/archive includes calib/sim" 'db/archive/run_archive.hpp:[0-9]+: includes calib/sim/truth_sim.hpp, but db/archive/ may include only'

fresh  # the IMU's driver includes an estimator
add_include drivers/imu/imu_codec.cpp '#include "drivers/imu/imu_codec.hpp"' calib/ains/ains.hpp
expect_breach "drivers/imu includes calib/ains" 'drivers/imu/imu_codec.cpp:[0-9]+: includes calib/ains/ains.hpp, but drivers/imu/ may include only calib/core'

fresh  # the control socket includes the run
add_include station/control/control_server.cpp '#include "station/control/control_server.hpp"' station/run/run_controller.hpp
expect_breach "station/control includes station/run" 'station/control/control_server.cpp:[0-9]+: includes station/run/run_controller.hpp, but station/control/ may include only'

fresh  # sequences/ includes calib/
add_include sequences/motion_profile.hpp '#pragma once' calib/core/rotation.hpp
expect_breach "sequences includes calib" 'sequences/motion_profile.hpp:[0-9]+: includes calib/core/rotation.hpp, but sequences/ may include nothing of ours'

fresh  # altsim, the independent simulator, includes calib/
add_include tools/altsim/alt_sim.cpp '#include "tools/altsim/alt_sim.hpp"' calib/core/earth.hpp
expect_breach "altsim includes calib" 'tools/altsim/alt_sim.cpp:[0-9]+: includes calib/core/earth.hpp, but tools/altsim/ may include only sequences'

fresh  # an include that climbs out of its folder
add_include station/run/capture.cpp '#include "station/run/capture.hpp"' ../control/control_server.hpp
expect_breach "a relative include" 'station/run/capture.cpp:[0-9]+: includes ../control/control_server.hpp, climbs out of its folder'

fresh  # a station room's README disagrees with station/rooms.cmake
mutate station/run/README.md 's|`calib/nlsq/` and `calib/diagnosis/`|`calib/diagnosis/`|'
expect_breach "station/run's README omits calib/nlsq" 'station/run/README.md: "May include" names \[.*\] but station/rooms.cmake gives \[.*calib/nlsq.*\]'

fresh  # a room without its README
rm "$tree/drivers/simulated/README.md"
expect_breach "drivers/simulated without a README" 'drivers/simulated/README.md: missing'

fresh  # a stray source file directly in station/, and a program folder that is no room
printf '#pragma once\n' >"$tree/station/stray.hpp"
mkdir "$tree/tools/newtool" && printf 'int main() { return 0; }\n' >"$tree/tools/newtool/main.cpp"
expect_breach "a stray file in station/" 'station/stray.hpp: a source file in no room of station/'
expect_breach "a folder that is no room" 'tools/newtool/main.cpp: a source file in no room of tools/'

fresh  # a cycle between two station rooms (README kept in step)
mutate station/rooms.cmake 's|MAY_INCLUDE drivers/turntable drivers/imu db/fleet|MAY_INCLUDE station/run drivers/turntable drivers/imu db/fleet|'
mutate station/config/README.md 's|^May include: |May include: `station/run/`, |'
expect_breach "station/config and station/run include each other" 'station/config depends on itself \(station/config -> station/run -> station/config\)'

fresh  # the dependency direction broken in a rooms.cmake (README kept in step)
mutate db/rooms.cmake 's|^\(imucal_room(db/history .*MAY_INCLUDE db/archive\)|\1 station/run|'
mutate db/history/README.md 's|^May include: |May include: `station/run/`, |'
expect_breach "db/history may include station/run" 'db/history may include station/run, against the dependency direction: db/ may include only its own rooms and calib/, sequences/'

fresh  # a folder's own rule broken in its rooms.cmake
mutate drivers/rooms.cmake 's|^\(imucal_room(drivers/imu .*MAY_INCLUDE calib/core\))|\1 calib/ains)|; s|calib/ains))$|calib/ains)|'
expect_breach "drivers/imu may include calib/ains" 'drivers/imu reaches calib/ains: the IMU.s driver includes calib/core only'

fresh  # a list naming no room, and a room declared by another folder
mutate tools/rooms.cmake 's|^\(imucal_room(tools/stationd .*MAY_INCLUDE station/daemon\)|\1 station/nothing|'
printf 'imucal_room(station/extra)\n' >>"$tree/db/rooms.cmake"
expect_breach "an unknown room in a list" "tools/stationd may include 'station/nothing', which is no room"
expect_breach "a room declared by db/" 'db/rooms.cmake: declares station/extra, a room of station/'

[[ $failures -eq 0 ]] || { echo "$failures mutation(s) not caught"; exit 1; }
echo "every breach caught"
