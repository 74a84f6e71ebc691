#!/usr/bin/env python3
"""The `ik --batch` figures in docs/kinematics.md: per-line time from outside the process, less the solve
mean the same run prints.

    python3 host/scripts/batch_overhead.py target/release/armctl [LINES] [RUNS]

Makes LINES (default 5000) reachable ur5e full-pose targets once, as forward kinematics of joint
vectors drawn uniformly within 95 % of the limits (seeded, so the file is the same every time), in
ur5e-LINES.jsonl beside this script's working directory; then times RUNS (default 9) runs of
`armctl ik --arm ur5e --batch FILE > /dev/null` with Python's perf_counter around the process.
A benchmark, not a test: the figures move with the machine's load; quote the medians.
"""
import json
import os
import random
import re
import statistics
import subprocess
import sys
import time

armctl = sys.argv[1]
lines = int(sys.argv[2]) if len(sys.argv) > 2 else 5000
runs = int(sys.argv[3]) if len(sys.argv) > 3 else 9
targets = f"ur5e-{lines}.jsonl"

if not os.path.exists(targets):
    random.seed(7)
    limits = [(-6.283, 6.283)] * 2 + [(-3.141, 3.141)] + [(-6.283, 6.283)] * 3
    with open(targets, "w") as out:
        for _ in range(lines):
            q = [random.uniform(a * 0.95, b * 0.95) for a, b in limits]
            fk = subprocess.run([armctl, "fk", "--arm", "ur5e", "--q", ",".join(f"{x:.9f}" for x in q)],
                                capture_output=True, text=True, check=True)
            v = json.loads(fk.stdout)
            out.write(json.dumps({"position": v["position"], "quaternion_wxyz": v["quaternion_wxyz"]}) + "\n")

outside, inside = [], []
for _ in range(runs):
    started = time.perf_counter()
    run = subprocess.run([armctl, "ik", "--arm", "ur5e", "--batch", targets],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, check=True)
    wall_per_line = (time.perf_counter() - started) * 1e6 / lines
    mean = float(re.search(r"per solve mean ([0-9.]+)", run.stderr).group(1))
    median, p99 = re.search(r"median ([0-9.]+) us, p99 ([0-9.]+)", run.stderr).groups()
    not_solving = float(re.search(r"of which ([0-9.]+)", run.stderr).group(1))
    outside.append(wall_per_line - mean)
    inside.append(not_solving)
    print(f"solve mean {mean:.2f} us, median {median} us, p99 {p99} us; wall {wall_per_line:.2f} us a line, "
          f"{wall_per_line - mean:.2f} us not solving (inside the command: {not_solving:.2f} us)")
print(f"median over {runs} runs: {statistics.median(outside):.2f} us a line not solving, from outside "
      f"({statistics.median(inside):.2f} us inside the command)")
