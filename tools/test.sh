#!/usr/bin/env bash
# The whole test suite: set up (packages, configure, build), then ctest.
# IMUCAL_SLOW=1 runs the slow Monte Carlo set with its full seed count.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
cd build
ctest --output-on-failure -j2 --timeout 1500
