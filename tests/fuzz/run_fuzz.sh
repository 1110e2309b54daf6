#!/usr/bin/env bash
# One bounded libFuzzer run: run_fuzz.sh BINARY FUZZ_DIR TARGET SECONDS.
# New inputs go to a temporary directory (the seed corpus in the repo is read, never written); a
# crash input is kept in $IMUCAL_FUZZ_ARTIFACTS (default /tmp/imucal-fuzz-artifacts) and the run
# fails. Prints libFuzzer's execution count ("stat::number_of_executed_units").
set -euo pipefail
bin=$1 dir=$2 target=$3 seconds=$4
work=$(mktemp -d "${TMPDIR:-/tmp}/fuzz-$target-XXXXXX")
artifacts=${IMUCAL_FUZZ_ARTIFACTS:-/tmp/imucal-fuzz-artifacts}/$target
mkdir -p "$artifacts"
trap 'rm -rf "$work"' EXIT
dict=()
[ -f "$dir/dict/$target.dict" ] && dict=(-dict="$dir/dict/$target.dict")
"$bin" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
  -artifact_prefix="$artifacts/" "${dict[@]}" "$work" "$dir/corpus/$target" "$dir/regressions/$target" 2>"$work.log" || {
  tail -50 "$work.log"; rm -f "$work.log"; echo "fuzz $target: FAILED, input kept in $artifacts"; exit 1; }
grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "$work.log" | sed "s/^/fuzz $target: /"
rm -f "$work.log"
