#!/usr/bin/env bash
# The whole test suite (issue #51): set up (packages, configure, the Release programs and
# calibration core), every test once under ASan + UBSan, the install and QEMU tests in Release, then
# the threaded tests under ThreadSanitizer. Each stage prints its time (README, "The test command").
#   IMUCAL_SKIP_TSAN=1     skips the ThreadSanitizer stage
#   IMUCAL_SKIP_FUZZ=1     leaves the libFuzzer runs out of the ASan + UBSan stage
#   IMUCAL_RELEASE_SUITE=1 the suite uninstrumented instead (no clang needed): every test in the
#                          Release tree, then the fuzz stage; quicker to read a figure, no sanitizer
set -euo pipefail
cd "$(dirname "$0")/.."
stage() {  # stage NAME COMMAND...: runs it and prints how long it took
  local name=$1 start=$SECONDS status=0
  shift
  "$@" || status=$?
  echo "test.sh: $name took $((SECONDS - start)) s (exit $status)"
  return $status
}
# The slowest tests first (issue #51): ctest orders a parallel run by each test's cost from the
# tree's last runs; a new tree has none, so it starts from tests/ctest_costs.txt (the costs of a
# full run, refreshed by tools/refresh_ctest_costs.sh), and a long test no longer starts last.
release_ctest() {  # release_ctest CTEST-ARGS...: ctest in the Release tree
  bash tools/refresh_ctest_costs.sh --seed build
  (cd build && ctest --output-on-failure -j2 --timeout 1500 "$@")
}

if [ "${IMUCAL_RELEASE_SUITE:-0}" = 1 ]; then
  stage setup bash tools/setup.sh
  stage ctest release_ctest
  [ "${IMUCAL_SKIP_TSAN:-0}" != 1 ] && stage tsan bash tools/sanitizers.sh tsan
  [ "${IMUCAL_SKIP_FUZZ:-0}" != 1 ] && stage fuzz bash tools/sanitizers.sh fuzz
  exit 0
fi

# The Release tree holds what the sanitizer trees link (the calibration core), the programs and the
# tests that cannot run instrumented; the test programs are not built there (the next stage runs
# them).
stage setup bash tools/setup.sh --test
# Every test but the install and QEMU sets, once, under ASan + UBSan (clang-16), the slow sets at
# their CI counts and the libFuzzer runs among them; the calibration core linked uninstrumented from
# the Release tree; any sanitizer report of any process fails (tools/sanitizers.sh asan).
stage asan bash tools/sanitizers.sh asan
# The Debian package, the main job from nothing and the SocketCAN probe in a QEMU guest build and
# run their own uninstrumented programs.
stage release release_ctest -L "install|qemu"
# ThreadSanitizer (issue #10): the threaded tests (capture, turntable client, simulator, control
# server, daemon, run controller) and three end-to-end tests whose stationd, stationsim and
# stationctl are TSan builds; any report fails (tools/sanitizers.sh; the single-threaded
# calibration core is linked from build/).
if [ "${IMUCAL_SKIP_TSAN:-0}" != 1 ]; then
  stage tsan bash tools/sanitizers.sh tsan
fi
