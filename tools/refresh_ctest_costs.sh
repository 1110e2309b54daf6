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
    # The tests' lines only (name, runs, seconds), sorted by name so a refresh diffs well; the
    # failed-tests section after "---" is the tree's own business.
    { sed '/^---$/q' "$costs" | grep -v '^---$' | sort; echo "---"; } >"$committed"
    echo "refresh_ctest_costs: $(grep -vc '^---$' "$committed") tests' costs written to $committed"
    ;;
  *)
    echo "usage: tools/refresh_ctest_costs.sh --seed TREE | --save TREE" >&2
    exit 2
    ;;
esac
