#!/usr/bin/env bash
# tools/run_test_file.sh PROGRAM FILE_FILTER [ARGS...]: runs the tests of one test file inside its
# room's test program (issue #51; build/tests/<room>_<file> scripts call it, tools/test_filter.sh
# writes them). A --gtest_filter among ARGS narrows the file's tests (gtest's own flag would replace
# the file's filter and select in the whole room): the file's tests are listed, the given patterns
# (positive, then after '-' negative, ':'-separated, * and ?) are matched against each name here,
# and the program runs the names that pass.
set -euo pipefail
prog=$1 file_filter=$2
shift 2
user="" args=()
for a in "$@"; do
  case $a in
    --gtest_filter=*) user=${a#--gtest_filter=} ;;
    *) args+=("$a") ;;
  esac
done
[ -n "$user" ] || exec "$prog" --gtest_filter="$file_filter" "${args[@]}"

matches() {  # matches NAME PATTERNS: true if NAME matches one of the ':'-separated glob PATTERNS
  local name=$1 p patterns
  IFS=: read -ra patterns <<<"$2"  # read, not word splitting: no pattern expands to file names
  for p in "${patterns[@]}"; do
    # shellcheck disable=SC2053
    [[ -n $p && $name == $p ]] && return 0
  done
  return 1
}
positive=${user%%-*} negative=""
[[ $user == *-* ]] && negative=${user#*-}
[ -n "$positive" ] || positive='*'
selected=""
while read -r name; do
  matches "$name" "$positive" || continue
  [ -n "$negative" ] && matches "$name" "$negative" && continue
  selected+="$name:"
done < <("$prog" --gtest_filter="$file_filter" --gtest_list_tests |
         awk '/^[^ ]/ {suite = $1} /^  / {print suite $1}')
# Nothing selected: "-*" (gtest then runs no test, as the one-file program would have).
filter=${selected%:}
exec "$prog" --gtest_filter="${filter:--*}" "${args[@]}"
