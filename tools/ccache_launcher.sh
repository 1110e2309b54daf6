#!/usr/bin/env bash
# Prints the CMake compiler launcher every build tree uses (tools/setup.sh, tools/sanitizers.sh):
# ccache, told that the test programs' precompiled header may be cached (issue #51; ccache's manual,
# "Precompiled headers": pch_defines and time_macros, and for clang the include files' times), as
# a CMake list. Prints nothing when ccache is not installed.
command -v ccache >/dev/null || exit 0
echo "env;CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime;ccache"
