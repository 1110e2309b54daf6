#!/usr/bin/env bash
# The whole test suite: set up (packages, configure, build), ctest, then the sanitizer stages.
# IMUCAL_SKIP_TSAN=1 and IMUCAL_SKIP_FUZZ=1 skip the ThreadSanitizer and fuzzing stages;
# IMUCAL_ASAN=1 runs the whole suite under ASan + UBSan instead of the fuzzing alone.
set -euo pipefail
cd "$(dirname "$0")/.."
stage() {  # stage NAME COMMAND...: runs it and prints how long it took (CI's 30-min budget)
  local name=$1 start=$SECONDS status=0
  shift
  "$@" || status=$?
  echo "test.sh: $name took $((SECONDS - start)) s (exit $status)"
  return $status
}
stage setup bash tools/setup.sh
# The slowest tests first (issue #51): ctest orders a parallel run by each test's cost from the
# tree's last runs; a new tree has none, so it starts from tests/ctest_costs.txt (the costs of a
# full run, refreshed by tools/refresh_ctest_costs.sh), and a long test no longer starts last.
bash tools/refresh_ctest_costs.sh --seed build
stage ctest bash -c 'cd build && ctest --output-on-failure -j2 --timeout 1500'

# ThreadSanitizer (issue #10): the threaded tests (capture, turntable client, simulator, control
# server, daemon, run controller) and three end-to-end tests whose stationd, stationsim and
# stationctl are TSan builds; any report fails (tools/sanitizers.sh; the single-threaded
# calibration core is linked from build/).
if [ "${IMUCAL_SKIP_TSAN:-0}" != 1 ]; then
  stage tsan bash tools/sanitizers.sh tsan
fi

# Fuzzing under ASan + UBSan (issue #10, tests/fuzz/README.md): the libFuzzer targets built with
# clang-16, their corpus replayed and each fuzzed for 30 s. IMUCAL_SKIP_FUZZ=1 skips it.
# IMUCAL_ASAN=1 runs the whole suite under ASan + UBSan instead (tools/sanitizers.sh asan, tree
# build-asan: all but the QEMU guest and the install sets, the slow sets at reduced counts, the
# fuzzing among its tests). Not the default: a cold fresh-clone run with it measured past CI's
# 60 minutes on this 2-core machine (issue #22 item 5, README "A verdict QA can trust").
if [ "${IMUCAL_ASAN:-0}" = 1 ]; then
  stage asan bash tools/sanitizers.sh asan
elif [ "${IMUCAL_SKIP_FUZZ:-0}" != 1 ]; then
  stage fuzz bash tools/sanitizers.sh fuzz
fi
