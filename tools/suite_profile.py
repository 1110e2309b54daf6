#!/usr/bin/env python3
"""Where the suite's time goes (issue #51): per test program and per test, from a tree's ctest costs.

  tools/suite_profile.py BUILD_DIR [--log CTEST_OUTPUT] [--top N] [--markdown]

Reads BUILD_DIR/Testing/Temporary/CTestCostData.txt (each test's mean seconds over the tree's
runs, which ctest keeps; a tree seeded by tools/refresh_ctest_costs.sh counts the seed as a run),
or with --log one run's times from what ctest printed (its "Test #N: NAME ... Passed X sec" lines), and `ctest --show-only=json-v1` (which program runs each test) and prints
the suite's total, per label, per test program and the slowest tests. With -j2 the suite's length
is about half its total when the slowest tests start first (tools/refresh_ctest_costs.sh).
"""
import argparse
import collections
import json
import os
import re
import subprocess
import sys

from profile_table import table


def read_costs(path):
    costs = {}
    with open(path, encoding="utf-8") as data:
        for number, line in enumerate(data, start=1):
            line = line.strip()
            if line == "---":
                break
            # A name may hold spaces (a parameterised test's "# GetParam() = ..."): the last two
            # fields are the runs and the seconds.
            fields = line.rsplit(None, 2)
            if len(fields) != 3:
                sys.exit(f"{path}:{number}: expected 'name runs seconds', got {line!r}")
            try:
                costs[fields[0]] = float(fields[2])
            except ValueError:
                sys.exit(f"{path}:{number}: seconds {fields[2]!r} is not a number")
    return costs


LOG_LINE = re.compile(r"Test +#\d+: (?P<name>.+?) \.{3,}.*?(?P<secs>[0-9.]+) sec$")


def read_log(path):
    """Each test's seconds in one ctest run, from its printed output."""
    costs = {}
    with open(path, encoding="utf-8", errors="replace") as log:
        for line in log:
            match = LOG_LINE.search(line.rstrip())
            if match:
                costs[match["name"].strip()] = float(match["secs"])
    if not costs:
        sys.exit(f"{path}: no 'Test #N: NAME ... sec' lines (ctest's output?)")
    return costs


def read_tests(tree):
    listing = subprocess.run(["ctest", "--show-only=json-v1"], cwd=tree, check=True,
                             capture_output=True, text=True).stdout
    tests = {}
    for test in json.loads(listing)["tests"]:
        command = test.get("command") or ["?"]
        program = os.path.basename(command[0])
        if program in ("cmake", "bash") and len(command) > 1:
            program = f"{program} {os.path.basename(command[-1])}"
        labels = []
        for prop in test.get("properties", []):
            if prop["name"] == "LABELS":
                labels = prop["value"]
        tests[test["name"]] = (program, labels)
    return tests


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("build_dir")
    parser.add_argument("--log", help="one run's times from ctest's printed output")
    parser.add_argument("--top", type=int, default=20)
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    if args.log:
        costs = read_log(args.log)
    else:
        cost_path = os.path.join(args.build_dir, "Testing", "Temporary", "CTestCostData.txt")
        if not os.path.exists(cost_path):
            sys.exit(f"{cost_path}: no such file (run ctest in {args.build_dir} first)")
        costs = read_costs(cost_path)
    tests = read_tests(args.build_dir)
    known = {name: cost for name, cost in costs.items() if name in tests}
    total = sum(known.values())
    per_program = collections.defaultdict(lambda: [0.0, 0])
    per_label = collections.defaultdict(lambda: [0.0, 0])
    for name, cost in known.items():
        program, labels = tests[name]
        per_program[program][0] += cost
        per_program[program][1] += 1
        for label in labels or ["(none)"]:
            per_label[label][0] += cost
            per_label[label][1] += 1
    never_ran = sorted(set(tests) - set(costs))
    print(f"{len(tests)} tests in {len({p for p, _ in tests.values()})} programs; "
          f"{total:.0f} s of test time over the {len(known)} with a cost "
          f"(about {total / 2:.0f} s at -j2 when well packed)")
    if never_ran:
        print(f"{len(never_ran)} without a cost yet (never run in this tree), e.g. {never_ran[0]}")
    table(args.markdown, "Per label", ["label", "tests", "s", "share"],
          [[label, n, f"{s:.0f}", f"{100 * s / total:.0f} %"]
           for label, (s, n) in sorted(per_label.items(), key=lambda kv: -kv[1][0])])
    table(args.markdown, f"The {args.top} costliest test programs", ["program", "tests", "s", "share"],
          [[p, n, f"{s:.0f}", f"{100 * s / total:.1f} %"]
           for p, (s, n) in sorted(per_program.items(), key=lambda kv: -kv[1][0])[:args.top]])
    table(args.markdown, f"The {args.top} slowest tests", ["s", "test", "program"],
          [[f"{c:.0f}", name, tests[name][0]]
           for name, c in sorted(known.items(), key=lambda kv: -kv[1])[:args.top]])


if __name__ == "__main__":
    main()
