#!/usr/bin/env bash
# ctest's schedule from nothing (issue #51). ctest -j runs the costliest tests first by the costs it
# keeps in TREE/Testing/Temporary/CTestCostData.txt; a new tree has none and runs them in file order,
# so a ten-minute test can start last and leave one core idle meanwhile.
#   tools/refresh_ctest_costs.sh --seed TREE   TREE without costs of its own gets tests/ctest_costs.txt
#   tools/refresh_ctest_costs.sh --save TREE   tests/ctest_costs.txt from TREE's costs (after a full run)
set -euo pipefail
cd "$(dirname "$0")/.."
committed=tests/ctest_costs.txt
case "${1:-}" in
  --seed)
    costs="$2/Testing/Temporary/CTestCostData.txt"
    if [ ! -s "$costs" ] && [ -f "$committed" ]; then
      mkdir -p "$(dirname "$costs")"
      cp "$committed" "$costs"
    fi
    ;;
  --save)
    costs="$2/Testing/Temporary/CTestCostData.txt"
    [ -s "$costs" ] || { echo "refresh_ctest_costs: $costs: no costs (run ctest in $2 first)" >&2; exit 1; }
    # The lines of the tests the tree has now (name, runs, seconds; a seed's tests since renamed
    # dropped), sorted by name so a refresh diffs well; the failed-tests section after "---" is the
    # tree's own business.
    names=$(cd "$2" && ctest --show-only=json-v1 | python3 -c \
      'import json, sys; print("\n".join(t["name"] for t in json.load(sys.stdin)["tests"]))')
    { sed '/^---$/q' "$costs" | grep -v '^---$' |
        awk -v names="$names" 'BEGIN { n = split(names, list, "\n"); for (i = 1; i <= n; i++) known[list[i]] = 1 }
          { name = $0; sub(/ [0-9]+ [0-9.e+-]+$/, "", name); if (name in known) print }' | sort
      echo "---"; } >"$committed"
    echo "refresh_ctest_costs: $(grep -vc '^---$' "$committed") tests' costs written to $committed"
    ;;
  *)
    echo "usage: tools/refresh_ctest_costs.sh --seed TREE | --save TREE" >&2
    exit 2
    ;;
esac
