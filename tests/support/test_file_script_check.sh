#!/usr/bin/env bash
# tests/support/test_file_script_check.sh BUILD_TESTS_DIR: build/tests/<folder>_<file>_test runs
# that file's tests only, and a --gtest_filter narrows them (tools/run_test_file.sh) — also from a
# folder full of files, where a '*' once expanded to file names and selected nothing, so that the
# TSan stage ran no test while saying "passed" (2026-11-29).
set -euo pipefail
tests=$(cd "$1" && pwd)
cd "$tests"  # a folder of many files
listed() { "$tests/calib_grade_test" "$@" --gtest_list_tests | awk '/^[^ ]/ {s = $1} /^  / {print s $1}'; }
fail() { echo "FAIL: $*" >&2; exit 1; }
all=$(listed)
[ -n "$all" ] || fail "the file's script lists no test"
grep -qv '^Grade' <<<"$all" && fail "tests of other files: $(grep -v '^Grade' <<<"$all" | head -3)"
grep -q '^GradeLegacy\.' <<<"$all" || fail "GradeLegacy missing from the file's tests"
minus=$(listed --gtest_filter='-GradeLegacy.*')
[ -n "$minus" ] || fail "a negative filter selected nothing"
grep -q '^GradeLegacy\.' <<<"$minus" && fail "the negative filter kept GradeLegacy"
[ "$(wc -l <<<"$minus")" -lt "$(wc -l <<<"$all")" ] || fail "the negative filter removed nothing"
grep -q '^GradeLimits\.' <<<"$minus" || fail "the negative filter dropped GradeLimits"
only=$(listed --gtest_filter='*Limits.*')
[ "$(grep -c . <<<"$only")" -ge 1 ] && ! grep -qv '^GradeLimits\.' <<<"$only" ||
  fail "a positive filter: $only"
none=$(listed --gtest_filter='NoSuchSuite.*')
[ -z "$none" ] || fail "a filter matching nothing selected: $none"
echo "file scripts: $(wc -l <<<"$all") tests of grade_test.cpp; filters narrow them"
