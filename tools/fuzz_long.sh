#!/usr/bin/env bash
# Longer fuzzing of every target (tests/fuzz/README.md): fuzz_long.sh [SECONDS per target, 600].
# Builds the clang fuzz tree in build-fuzz if needed; prints one line per target with libFuzzer's
# execution count and peak memory, the figures recorded in the README.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-600}
if [ ! -d build-fuzz ]; then
  CC=clang-16 CXX=clang++-16 cmake -S . -B build-fuzz -DIMUCAL_FUZZ=ON \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER_LAUNCHER=ccache >/dev/null
fi
cmake --build build-fuzz -j2 >/dev/null
for bin in build-fuzz/fuzz/fuzz_*; do
  target=${bin##*/fuzz_}
  bash tests/fuzz/run_fuzz.sh "$bin" tests/fuzz "$target" "$seconds"
done
