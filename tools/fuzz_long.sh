#!/usr/bin/env bash
# Longer fuzzing of every target (tests/fuzz/README.md): fuzz_long.sh [SECONDS per target, 600].
# Builds the targets in their clang ASan + UBSan tree (build-fuzz, tools/sanitizers.sh fuzz);
# prints one line per target with libFuzzer's execution count and peak memory (README figures).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-600}
IMUCAL_BUILD_ONLY=1 bash tools/sanitizers.sh fuzz >/dev/null
for bin in build-fuzz/fuzz/fuzz_*; do
  target=${bin##*/fuzz_}
  bash tests/fuzz/run_fuzz.sh "$bin" tests/fuzz "$target" "$seconds"
done
