#!/usr/bin/env bash
# A compiler and linker launcher that records each step's CPU time (issue #51, tools/build_profile.sh):
# appends "user_s sys_s output" to $IMUCAL_STEP_LOG, then the step's own exit status. CPU time, not
# the wall time Ninja logs, so that a figure holds on a machine busy with other work.
set -u
out=""
prev=""
for arg in "$@"; do
  [ "$prev" = "-o" ] && out=$arg
  prev=$arg
done
exec /usr/bin/time -a -o "${IMUCAL_STEP_LOG:?IMUCAL_STEP_LOG: where to log}" -f "%U %S $out" "$@"
