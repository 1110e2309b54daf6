#!/usr/bin/env python3
"""Where a build's time goes, read from a Ninja tree (issue #51).

  tools/build_profile.py BUILD_DIR [--top N] [--markdown]

Prints the time each step took (compile of one translation unit or precompiled header, archive,
link), summed per part (calibration core, other libraries, test programs, programs), per target,
and the slowest translation units and links. A step's time is its CPU time (user + system) where
BUILD_DIR/step_cpu.log has it (tools/timed_step.sh, which tools/build_profile.sh sets as the
launcher), else its wall time from .ninja_log; their sum is the CPU time the build asked for, not
its length, which is the last step's end in .ninja_log. Only the newest entry of each output
counts. tools/build_profile.sh makes such a tree from nothing and calls this.
"""
import argparse
import collections
import os
import re
import sys

from profile_table import table


def read_log(path):
    """The newest (start_ms, end_ms) of every output in a .ninja_log (format v5 or v6)."""
    steps = {}
    with open(path, encoding="utf-8") as log:
        header = log.readline()
        if not header.startswith("# ninja log v"):
            sys.exit(f"{path}:1: not a ninja log (no '# ninja log v' header)")
        for number, line in enumerate(log, start=2):
            fields = line.rstrip("\n").split("\t")
            if len(fields) < 4:
                sys.exit(f"{path}:{number}: expected 5 tab-separated fields, got {len(fields)}")
            steps[fields[3]] = (int(fields[0]), int(fields[1]))
    return steps


OBJECT = re.compile(r"^(?P<dir>.*?)/?CMakeFiles/(?P<target>[^/]+)\.dir/(?P<source>.+)\.(o|gch)$")


def read_cpu(path, tree):
    """output -> CPU seconds from tools/timed_step.sh's log ("user sys output" lines)."""
    cpu = {}
    if not os.path.exists(path):
        return cpu
    prefix = os.path.abspath(tree) + os.sep
    with open(path, encoding="utf-8") as log:
        for line in log:
            fields = line.split(None, 2)
            # /usr/bin/time also writes "Command exited with non-zero status N" lines.
            if len(fields) != 3 or not re.match(r"^[0-9.]+$", fields[0]):
                continue
            output = fields[2].strip()
            if output.startswith(prefix):
                output = output[len(prefix):]
            cpu[output] = float(fields[0]) + float(fields[1])
    return cpu


def classify(output):
    """(kind, target, what) for one ninja output."""
    match = OBJECT.match(output)
    if match:
        target, source = match["target"], match["source"]
        directory = match["dir"]
        source_path = os.path.join(directory, source) if directory else source
        return "compile", target, source_path
    name = os.path.basename(output)
    if name.endswith(".a"):
        return "archive", name[3:-2] if name.startswith("lib") else name, output
    return "link", name, output


def group_of(target):
    if target.startswith("imucal_calib") or target.startswith("imucal_sequences"):
        return "calibration core and sequences (calib/, sequences/)"
    if target.startswith("imucal_") or target.startswith("imucal_alt"):
        return "other libraries (drivers/, db/, station/, tools/report)"
    if target.startswith("room_link_"):
        return "room link checks (tests/rooms)"
    if target.startswith("fuzz_") or target.endswith("_fuzz") or "fuzz" in target:
        return "fuzz targets and replays (tests/fuzz)"
    if target.endswith("_test") or target in ("fleet_station_sim",):
        return "test programs (tests/)"
    if target.endswith("_bench"):
        return "benchmarks"
    return "programs (tools/)"


def seconds(ms):
    return f"{ms / 1000:.1f}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("build_dir")
    parser.add_argument("--top", type=int, default=15, help="rows of the slowest lists (15)")
    parser.add_argument("--markdown", action="store_true", help="tables in Markdown")
    args = parser.parse_args()
    log_path = os.path.join(args.build_dir, ".ninja_log")
    if not os.path.exists(log_path):
        sys.exit(f"{log_path}: no such file (a Ninja tree built by tools/build_profile.sh?)")
    steps = read_log(log_path)
    if not steps:
        sys.exit(f"{log_path}: no steps")
    cpu = read_cpu(os.path.join(args.build_dir, "step_cpu.log"), args.build_dir)
    measure = "CPU" if cpu else "wall"

    start = min(s for s, _ in steps.values())
    end = max(e for _, e in steps.values())
    per_group = collections.defaultdict(lambda: [0, 0, 0])  # compile ms, link+archive ms, TUs
    per_target = collections.defaultdict(lambda: [0, 0, 0])
    units, links = [], []
    for output, (begin, finish) in steps.items():
        kind, target, what = classify(output)
        took = round(cpu[output] * 1000) if output in cpu else finish - begin
        group = group_of(target)
        if kind == "compile":
            per_group[group][0] += took
            per_group[group][2] += 1
            per_target[target][0] += took
            per_target[target][2] += 1
            units.append((took, what, target))
        else:
            per_group[group][1] += took
            per_target[target][1] += took
            links.append((took, what, kind))

    total = sum(a + b for a, b, _ in per_group.values())
    table(args.markdown, f"Build of {args.build_dir}: {seconds(end - start)} s from the first "
          f"step to the last, {seconds(total)} s of steps ({len(steps)} steps)",
          ["part", "compile s", "TUs", "link+archive s", "share"],
          [[g, seconds(c), n, seconds(l), f"{100 * (c + l) / total:.0f} %"]
           for g, (c, l, n) in sorted(per_group.items(), key=lambda kv: -sum(kv[1][:2]))])
    table(args.markdown, f"The {args.top} costliest targets", ["target", "compile s", "TUs", "link s"],
          [[t, seconds(c), n, seconds(l)] for t, (c, l, n) in
           sorted(per_target.items(), key=lambda kv: -(kv[1][0] + kv[1][1]))[:args.top]])
    table(args.markdown, f"The {args.top} slowest translation units", ["s", "source", "target"],
          [[seconds(t), w, g] for t, w, g in sorted(units, reverse=True)[:args.top]])
    table(args.markdown, f"The {args.top} slowest links", ["s", "output", "step"],
          [[seconds(t), w, k] for t, w, k in sorted(links, reverse=True)[:args.top]])
    if units:
        tests = [t for t, _, g in units if group_of(g) == "test programs (tests/)"]
        if tests:
            tests.sort()
            print(f"test programs: {len(tests)} translation units, median {seconds(tests[len(tests) // 2])} s,"
                  f" sum {seconds(sum(tests))} s")


if __name__ == "__main__":
    main()
