#!/usr/bin/env bash
# The room rule's check (tools/check_calib_rooms.cmake) fails on every kind of breach: a copy of
# calib/ passes as it is, then each mutation below, applied to a fresh copy, must make the check
# exit non-zero naming the breach. Usage: room_rule_mutations.sh SOURCE_DIR
set -euo pipefail
src=${1:?usage: room_rule_mutations.sh SOURCE_DIR}
check=$src/tools/check_calib_rooms.cmake
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0

fresh() { rm -rf "$work/calib" && cp -r "$src/calib" "$work/calib"; }
run_check() { cmake -DCALIB_DIR="$work/calib" -P "$check" 2>&1; }

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
  echo "FAIL: the tree as it is breaks the rule:"; echo "$out"; failures=$((failures + 1)); fi

fresh  # an estimator includes the simulator
sed -i 's|^#include "calib/ains/ains.hpp"$|&\n#include "calib/sim/truth_sim.hpp"|' "$work/calib/ains/ains.cpp"
expect_breach "AINS includes the simulator" 'calib/ains/ains.cpp:[0-9]+: includes calib/sim/truth_sim.hpp, but calib/ains/ may include only ains, core'

fresh  # the simulator includes an estimator
sed -i 's|^#pragma once$|&\n#include "calib/nlsq/nlsq.hpp"|' "$work/calib/sim/truth_stream.hpp"
expect_breach "the streaming simulator includes NLSQ" 'calib/sim/truth_stream.hpp:[0-9]+: includes calib/nlsq/nlsq.hpp'

fresh  # the diagnosis includes the simulator instead of taking a RunSource
sed -i 's|^#include "calib/diagnosis/diagnosis_validation.hpp"$|&\n#include "calib/sim/sim_input.hpp"|' "$work/calib/diagnosis/diagnosis_validation.cpp"
expect_breach "the validation includes the simulator" 'calib/diagnosis/diagnosis_validation.cpp:[0-9]+: includes calib/sim/sim_input.hpp'

fresh  # an effect's forward model includes the simulator
sed -i 's|^#pragma once$|&\n#include "calib/sim/truth_sim.hpp"|' "$work/calib/effects/size_effect.hpp"
expect_breach "an effect includes the simulator" 'calib/effects/size_effect.hpp:[0-9]+: includes calib/sim/truth_sim.hpp'

fresh  # the graph itself lets an estimator reach the simulator (README kept in step)
sed -i "s|^set(calib_room_deps_legacy core)|set(calib_room_deps_legacy core studies/paper)|" "$work/calib/rooms.cmake"
sed -i 's|^May include: `calib/core/`|May include: `calib/core/`, `calib/studies/paper/`|' "$work/calib/legacy/README.md"
expect_breach "legacy may reach sim through paper" 'calib/legacy is on the estimate side and reaches the simulator \(calib/sim\) through core, studies/paper'

fresh  # the simulator's graph widened
sed -i 's/^set(calib_room_deps_sim core effects)/set(calib_room_deps_sim core effects checks)/' "$work/calib/rooms.cmake"
expect_breach "sim may include checks" 'calib/sim reaches checks, ains: the simulator may include calib/core and calib/effects only'

fresh  # a cycle
sed -i 's/^set(calib_room_deps_core "")/set(calib_room_deps_core checks)/' "$work/calib/rooms.cmake"
expect_breach "core depends on checks" 'calib/core depends on itself'

fresh  # a README that says something else than the graph
sed -i 's|May include: `calib/core/`, `calib/ains/`|May include: `calib/core/`|' "$work/calib/checks/README.md"
expect_breach "checks' README omits ains" 'calib/checks/README.md: "May include" names \[core\] but calib/rooms.cmake gives \[ains, core\]'

fresh  # a file left outside the rooms, and an include without its room
printf '#pragma once\n' >"$work/calib/stray.hpp"
sed -i '0,/#include "calib\/core\/earth.hpp"/s//#include "calib\/earth.hpp"/' "$work/calib/core/strapdown.hpp"
expect_breach "a stray file" 'calib/stray.hpp: a source file outside the rooms'
expect_breach "an include without its room" 'calib/core/strapdown.hpp:[0-9]+: includes calib/earth.hpp, a path without its room'

[[ $failures -eq 0 ]] || { echo "$failures mutation(s) not caught"; exit 1; }
echo "every breach caught"
