#!/usr/bin/env bash
# Prints the CMake compiler launcher every build tree uses (tools/setup.sh, tools/sanitizers.sh),
# as a CMake list; nothing when ccache is not installed.
# - CCACHE_SLOPPINESS: the test programs' precompiled header may be cached (issue #51; ccache's
#   manual, "Precompiled headers": pch_defines and time_macros, and for clang the include files'
#   times).
# - CCACHE_BASEDIR, the repository: a unity batch's source is generated inside its tree
#   (TREE/.../Unity/unity_0_cxx.cxx) and ccache hashes the input file's path and the -I paths; made
#   relative, the same batch in another tree beside build/ with the same flags is the same entry.
#   So the main job's tree (tests/install/main_job_test.cpp builds it beside build/) is served from
#   the Release tree's objects: without it that test compiled the four programs from nothing,
#   1 300 s of a cold CI run (2026-11-29); with it, three libraries' batches 25.7 s -> 0.6 s.
command -v ccache >/dev/null || exit 0
root=$(cd "$(dirname "$0")/.." && pwd)
echo "env;CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime;CCACHE_BASEDIR=$root;ccache"
