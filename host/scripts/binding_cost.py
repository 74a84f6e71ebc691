#!/usr/bin/env python3
"""What a call through the Python binding costs: per-call wall time of `Model.fk`, of a stream's
`send` on a simulated SO-101, and of `Arm.status()`; optionally of `armctl ik --batch`.

    python host/scripts/binding_cost.py [--n N] [--rate HZ] [--json]
    python host/scripts/binding_cost.py --make-targets FILE [--targets 2000]
    python host/scripts/binding_cost.py --ik-batch FILE --armctl target/release/armctl [--runs 5]

Uses only the public API of the `armctl` package (armctl/__init__.py), so the same script measures
any build of it: run it with the Python of the venv the package is installed in. Every figure is
the wall time of one call (perf_counter around the call and nothing else), summarised by its
median (and p90) over N calls; the machine's load moves them, so run it more than once.

- fk: `Model("so101").fk(q)` at uniform random joint values within the limits (seeded).
- send: `Arm(sim=True)` (the simulated SO-101 driven by the core in real time), `arm.stream(rate)`,
  then `s.send(q)` paced at the rate, q a small sine (0.1 rad) about the pose the arm rests in,
  clamped into the limits. A send may wait on the link: the raw time of the call is reported.
- status: `arm.status()` with no stream open (the drive command's request and its dict), and
  `status_in_stream`: `arm.status()` between the sends of an open stream.
- ik_batch (with --ik-batch): wall time of `armctl ik --arm so101 --batch FILE > /dev/null`, the
  median of --runs runs. --make-targets writes FILE: --targets lines of {"position": [...]} made by
  `Model.fk` at seeded random joint values within the limits (reachable by construction).
"""
from __future__ import annotations

import argparse
import json
import math
import random
import statistics
import subprocess
import sys
import time


def summary(samples_s: list[float]) -> dict[str, float]:
    """Median, p90, min and max of per-call times, in microseconds."""
    us = sorted(x * 1e6 for x in samples_s)
    p90 = us[min(len(us) - 1, math.ceil(0.9 * len(us)) - 1)]
    return {"n": len(us), "median_us": round(statistics.median(us), 2), "p90_us": round(p90, 2),
            "min_us": round(us[0], 2), "max_us": round(us[-1], 2)}


def random_q(limits, rng: random.Random, margin: float = 0.95) -> list[float]:
    out = []
    for lo, hi in limits:
        mid, half = (lo + hi) / 2, (hi - lo) / 2 * margin
        out.append(rng.uniform(mid - half, mid + half))
    return out


def bench_fk(armctl, n: int, seed: int) -> dict[str, float]:
    model = armctl.Model("so101")
    rng = random.Random(seed)
    qs = [random_q(model.limits.tolist(), rng) for _ in range(n)]
    for q in qs[:20]:  # warm-up
        model.fk(q)
    times = []
    for q in qs:
        t0 = time.perf_counter()
        model.fk(q)
        times.append(time.perf_counter() - t0)
    return summary(times)


def bench_arm(armctl, n_send: int, n_status: int, rate: float) -> dict[str, dict]:
    figures: dict[str, dict] = {}
    with armctl.Arm(sim=True) as arm:
        limits = arm.limits.tolist()
        rest = [float(x) for x in arm.status()["measured"]]
        for _ in range(10):  # warm-up
            arm.status()
        times = []
        for _ in range(n_status):
            t0 = time.perf_counter()
            arm.status()
            times.append(time.perf_counter() - t0)
        figures["status"] = summary(times)

        def target(i: int) -> list[float]:
            # One cycle a second, 0.1 rad, starting at rest (alternate joints in opposite senses).
            phase = 2 * math.pi * i / rate
            return [min(max(r + 0.1 * math.sin(phase) * (-1) ** j, lo + 0.02), hi - 0.02)
                    for j, (r, (lo, hi)) in enumerate(zip(rest, limits))]

        period = 1.0 / rate
        sends, status_in_stream = [], []
        with arm.stream(rate=rate) as s:
            next_at = time.perf_counter()
            for i in range(n_send):
                q = target(i)
                t0 = time.perf_counter()
                s.send(q)
                sends.append(time.perf_counter() - t0)
                # A status read between keyframes (as a LeRobot observation is), every other period.
                if i % 2 == 1 and len(status_in_stream) < n_status:
                    t0 = time.perf_counter()
                    arm.status()
                    status_in_stream.append(time.perf_counter() - t0)
                next_at += period
                delay = next_at - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
                else:
                    next_at = time.perf_counter()
        figures["send"] = summary(sends)
        figures["send"]["rate_hz"] = rate
        figures["status_in_stream"] = summary(status_in_stream)
        stream_figures = s.figures or {}
        figures["stream_close"] = {k: v for k, v in stream_figures.items() if not isinstance(v, (list, dict))}
    return figures


def make_targets(armctl, path: str, count: int, seed: int) -> None:
    model = armctl.Model("so101")
    rng = random.Random(seed)
    limits = model.limits.tolist()
    with open(path, "w") as out:
        for _ in range(count):
            pose = model.fk(random_q(limits, rng))
            out.write(json.dumps({"position": [float(x) for x in pose[:3, 3]]}) + "\n")


def bench_ik_batch(armctl_bin: str, path: str, runs: int) -> dict[str, float]:
    lines = sum(1 for _ in open(path))
    walls = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run([armctl_bin, "ik", "--arm", "so101", "--batch", path],
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        walls.append(time.perf_counter() - t0)
    return {"runs": runs, "lines": lines, "median_ms": round(statistics.median(walls) * 1e3, 2),
            "all_ms": [round(w * 1e3, 2) for w in walls],
            "median_us_per_line": round(statistics.median(walls) * 1e6 / lines, 2)}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=2000, help="fk calls (default 2000)")
    p.add_argument("--sends", type=int, default=500, help="stream sends (default 500: 10 s at 50 Hz)")
    p.add_argument("--statuses", type=int, default=300, help="status calls (default 300)")
    p.add_argument("--rate", type=float, default=50.0, help="stream rate, Hz (default 50)")
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--skip-arm", action="store_true", help="fk only (no simulated arm)")
    p.add_argument("--make-targets", metavar="FILE", help="write so101 ik --batch targets and exit")
    p.add_argument("--targets", type=int, default=2000, help="lines for --make-targets (default 2000)")
    p.add_argument("--ik-batch", metavar="FILE", help="also time armctl ik --arm so101 --batch FILE")
    p.add_argument("--armctl", default="target/release/armctl", help="the armctl binary for --ik-batch")
    p.add_argument("--runs", type=int, default=5, help="runs of ik --batch (default 5)")
    p.add_argument("--json", action="store_true", help="print only the JSON object")
    args = p.parse_args()

    import armctl

    if args.make_targets:
        make_targets(armctl, args.make_targets, args.targets, args.seed)
        print(f"wrote {args.targets} targets to {args.make_targets}", file=sys.stderr)
        return 0

    result: dict = {"armctl": armctl.__version__, "armctl_module": armctl.__file__,
                    "python": sys.version.split()[0]}
    result["fk"] = bench_fk(armctl, args.n, args.seed)
    if not args.skip_arm:
        result.update(bench_arm(armctl, args.sends, args.statuses, args.rate))
    if args.ik_batch:
        result["ik_batch"] = bench_ik_batch(args.armctl, args.ik_batch, args.runs)

    print(json.dumps(result))
    if not args.json:
        print(f"\n{'call':<24}{'n':>6}{'median us':>12}{'p90 us':>12}{'min us':>10}{'max us':>12}")
        for key in ("fk", "send", "status", "status_in_stream"):
            if key in result:
                f = result[key]
                print(f"{key:<24}{f['n']:>6}{f['median_us']:>12.1f}{f['p90_us']:>12.1f}"
                      f"{f['min_us']:>10.1f}{f['max_us']:>12.1f}")
        if "ik_batch" in result:
            f = result["ik_batch"]
            print(f"ik --batch ({f['lines']} lines): median {f['median_ms']:.1f} ms over {f['runs']} runs "
                  f"({f['median_us_per_line']:.1f} us a line); all {f['all_ms']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
