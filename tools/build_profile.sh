#!/usr/bin/env bash
# Where a cold build's time goes (issue #51): configures a tree from nothing the way tools/setup.sh
# does (Release, test programs at -O1, gold), builds it with Ninja at -j2 without ccache (each step's
# CPU time logged by tools/timed_step.sh), and prints tools/build_profile.py's tables: per part, per
# target, the slowest translation units and links, and the build's wall time.
#   tools/build_profile.sh [TREE]   (default build-profile; it is deleted first)
# Extra CMake arguments through IMUCAL_PROFILE_CMAKE_ARGS. Needs ninja-build (tools/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
tree=${1:-build-profile}
rm -rf "$tree"
launcher="$PWD/tools/timed_step.sh"
# shellcheck disable=SC2086
cmake -S . -B "$tree" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_EXE_LINKER_FLAGS=-fuse-ld=gold \
  -DIMUCAL_TEST_OPTIMIZE=-O1 -DCMAKE_CXX_COMPILER_LAUNCHER="$launcher" \
  -DCMAKE_CXX_LINKER_LAUNCHER="$launcher" ${IMUCAL_PROFILE_CMAKE_ARGS:-} >/dev/null
start=$SECONDS
# Each step's CPU time goes to step_cpu.log (tools/timed_step.sh): the figures hold on a busy machine.
IMUCAL_STEP_LOG="$PWD/$tree/step_cpu.log" cmake --build "$tree" -j2 >"$tree/build.log" 2>&1 || {
  tail -40 "$tree/build.log" >&2
  exit 1
}
echo "build_profile: cold build of $tree took $((SECONDS - start)) s"
python3 tools/build_profile.py "$tree" --top 20
