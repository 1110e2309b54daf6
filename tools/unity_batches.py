#!/usr/bin/env python3
"""Whether a unity build pays, room by room (issue #51).

  tools/unity_batches.py TREE TARGET [TARGET...]

For each unity batch of the given targets in TREE (a tree configured with IMUCAL_UNITY_BUILD=ON,
its compile_commands.json), compiles the batch once and each of its files alone with the same
command, and prints the CPU seconds of both and their ratio. Sequential: a few minutes per heavy
room. Both halves run under the same machine load, so the ratio holds on a busy machine.
"""
import json
import os
import re
import resource
import subprocess
import sys


def cpu_of(command, cwd):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(command, shell=True, cwd=cwd, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    tree, targets = sys.argv[1], sys.argv[2:]
    path = os.path.join(tree, "compile_commands.json")
    if not os.path.exists(path):
        sys.exit(f"{path}: no such file (configure {tree} with CMake first)")
    found = False
    for entry in json.load(open(path, encoding="utf-8")):
        if "/Unity/" not in entry["file"]:
            continue
        if not any(f"/{t}.dir/" in entry["command"] for t in targets):
            continue
        found = True
        sources = re.findall(r'#include "([^"]+)"', open(entry["file"], encoding="utf-8").read())
        # The command without a launcher, dependency files or the tree's object.
        command = re.sub(r"^\S*(timed_step\.sh|ccache|env)\s+(CCACHE_\S+\s+)?(ccache\s+)?", "",
                         entry["command"])
        command = re.sub(r" -MD -MT \S+ -MF \S+", " ", command)
        command = re.sub(r" -o \S+", " -o /dev/null", command)
        batch = cpu_of(command, entry["directory"])
        alone = sum(cpu_of(command.replace(entry["file"], s), entry["directory"]) for s in sources)
        name = entry["file"].split("/CMakeFiles/")[1].split(".dir/")[0]
        print(f"{name} {os.path.basename(entry['file'])}: {len(sources)} files, batch {batch:.1f} "
              f"CPU-s, alone {alone:.1f} CPU-s, ratio {batch / alone:.2f}", flush=True)
    if not found:
        sys.exit(f"no unity batch of {', '.join(targets)} in {path}")


if __name__ == "__main__":
    main()
