#!/usr/bin/env bash
# The whole test suite: set up (packages, configure, build), ctest, then the sanitizer stages.
# IMUCAL_SKIP_TSAN=1 skips the ThreadSanitizer stage; IMUCAL_SKIP_ASAN=1 replaces the ASan + UBSan
# stage (the whole suite, fuzzing included) by the fuzzing alone; IMUCAL_SKIP_FUZZ=1 with it skips
# that too.
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
stage ctest bash -c 'cd build && ctest --output-on-failure -j2 --timeout 1500'

# ThreadSanitizer (issue #10): the threaded tests (capture, turntable client, simulator, control
# server, daemon, run controller) and three end-to-end tests whose stationd, stationsim and
# stationctl are TSan builds; any report fails (tools/sanitizers.sh; the single-threaded
# calibration core is linked from build/).
if [ "${IMUCAL_SKIP_TSAN:-0}" != 1 ]; then
  stage tsan bash tools/sanitizers.sh tsan
fi

# ASan + UBSan (issue #22 item 5): the whole suite built with clang-16 under both (tree
# build-asan), all but the slow sets (not yet measured there), the libFuzzer targets fuzzed for
# 30 s each among its tests (tests/fuzz/README.md); any report of any process fails
# (tools/sanitizers.sh).
# IMUCAL_SKIP_ASAN=1 runs only the fuzzing under them (tree build-fuzz).
if [ "${IMUCAL_SKIP_ASAN:-0}" != 1 ]; then
  stage asan bash tools/sanitizers.sh asan
elif [ "${IMUCAL_SKIP_FUZZ:-0}" != 1 ]; then
  stage fuzz bash tools/sanitizers.sh fuzz
fi
