#!/usr/bin/env bash
# The whole test suite: set up (packages, configure, build), then ctest.
# IMUCAL_SLOW=1 runs the slow Monte Carlo set with its full seed count; IMUCAL_SKIP_TSAN=1 and
# IMUCAL_SKIP_FUZZ=1 skip the ThreadSanitizer and fuzzing stages.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
(cd build && ctest --output-on-failure -j2 --timeout 1500)

# ThreadSanitizer (issue #10): the threaded tests (capture, turntable client, simulator, control
# server, daemon, run controller) and three end-to-end tests whose stationd, stationsim and
# stationctl are TSan builds; any report fails (tools/sanitizers.sh; the single-threaded
# calibration core is linked from build/). About 5 min on 2 cores. IMUCAL_SKIP_TSAN=1 skips it.
if [ "${IMUCAL_SKIP_TSAN:-0}" != 1 ]; then
  bash tools/sanitizers.sh tsan
fi

# Fuzzing (issue #10, tests/fuzz/README.md): the libFuzzer targets built with clang-16 under
# ASan + UBSan (only they and the libraries they need), then a bounded run of each (30 s).
if [ "${IMUCAL_SKIP_FUZZ:-0}" != 1 ]; then
  CC=clang-16 CXX=clang++-16 cmake -S . -B build-fuzz -DIMUCAL_FUZZ=ON -DCMAKE_BUILD_TYPE=None \
    -DCMAKE_CXX_FLAGS=-O1 -DCMAKE_CXX_COMPILER_LAUNCHER=ccache >/dev/null
  cmake --build build-fuzz -j2 --target fuzz_targets
  (cd build-fuzz && ctest -L fuzz -j2 --output-on-failure)
fi
