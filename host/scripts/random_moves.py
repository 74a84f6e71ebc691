#!/usr/bin/env python3
"""Do Cartesian moves to reachable targets arrive? Random moves on `armctl serve --sim`, from outside.

    python3 host/scripts/random_moves.py target/release/armctl [--arm so101|open-manipulator-x]
        [--moves 60] [--fraction 0.9] [--seed 1] [--speed 0.2] [--timeout 30]

Starts `armctl serve --sim --arm ARM` and drives it through its pty with `armctl --port PTY`, as a
user would. For each move: `joints --q START` to a random joint vector, then `move --to X,Y,Z` to
the tool position (`armctl fk`) of another random joint vector END, so every target is reachable.
Both vectors are drawn uniformly within FRACTION of each joint's range around its middle (seeded,
so a run is repeatable). A move arrived if `move` exited 0 with `error_mm` < 1. Counts arrivals
(by the `path` the answer names), moves refused at once, moves that ran into the timeout, and other
failures; reads the error counters of `status` afterwards and the safety monitor's line serve
prints on stderr when it stops. Prints a summary line, then one JSON object with everything.

A measurement, not a test: the servos are simulated in real time, so it takes minutes and the
times move with the machine's load; it asserts nothing and exits 0 whatever it counts.
"""
import argparse
import json
import os
import random
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("armctl")
parser.add_argument("--arm", default="so101")
parser.add_argument("--moves", type=int, default=60)
parser.add_argument("--fraction", type=float, default=0.9)
parser.add_argument("--seed", type=int, default=1)
parser.add_argument("--speed", type=float, default=0.2)
parser.add_argument("--timeout", type=float, default=30.0)
args = parser.parse_args()
armctl = os.path.abspath(args.armctl)

# A non-zero exit sooner than this is "refused at once": the host's check or the firmware's IK said
# no before anything moved. Later ones ran for a while and then failed, which is another thing.
REFUSED_WITHIN_S = 5.0


def fmt(values):
    return ",".join(f"{v:.6f}" for v in values)


def last_line(text):
    lines = [line for line in text.splitlines() if line.strip()]
    return lines[-1] if lines else ""


def run(cmd, wall_limit=None):
    """Runs an armctl command; returns (exit code, wall seconds, stdout, stderr, killed)."""
    started = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = False
    try:
        out, err = proc.communicate(timeout=wall_limit)
    except subprocess.TimeoutExpired:
        # A move that outlives its own --timeout by far is hung: Ctrl-C makes armctl stop the arm
        # (it decelerates and holds) rather than leave it going while the next move starts.
        killed = True
        proc.send_signal(signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
    return proc.returncode, time.perf_counter() - started, out, err, killed


def port_cmd(*rest):
    return [armctl, "--port", pty, *rest, "--json"]


def status():
    code, _, out, err, _ = run(port_cmd("status"), wall_limit=30)
    if code != 0:
        raise SystemExit(f"status failed: {last_line(err)}")
    return json.loads(out)


def joint_limits(dof):
    # No command prints the limits of the arm the board runs, but `joints` refuses a value beyond
    # them naming both bounds, before it sends anything; so ask it for 1000 rad in one joint at a
    # time (the others at 0, within every preset's range) and read the bounds off the refusal.
    limits = []
    for i in range(dof):
        q = [0.0] * dof
        q[i] = 1000.0
        code, _, _, err, _ = run(port_cmd("joints", "--q", fmt(q)), wall_limit=30)
        found = re.search(r"outside its limits (\S+?)\.\.=(\S+)", err)
        if code == 0 or not found:
            raise SystemExit(f"could not read joint {i + 1}'s limits: exit {code}, {last_line(err)!r}")
        limits.append((float(found.group(1)), float(found.group(2))))
    return limits


def draw(rng, limits):
    vector = []
    for lo, hi in limits:
        middle, half = (lo + hi) / 2, (hi - lo) / 2 * args.fraction
        vector.append(rng.uniform(middle - half, middle + half))
    return vector


# Serve's stdout and stderr go to files, not pipes: nobody reads them while the moves run, and a
# full pipe would block serve's control loop. Its stderr carries the safety monitor's line at exit.
serve_out = tempfile.NamedTemporaryFile("w+", prefix="random_moves_serve_out_", dir="/tmp", delete=False)
serve_err = tempfile.NamedTemporaryFile("w+", prefix="random_moves_serve_err_", dir="/tmp", delete=False)
serve = subprocess.Popen([armctl, "serve", "--sim", "--arm", args.arm], stdout=serve_out, stderr=serve_err,
                         text=True)
run_started = time.perf_counter()
pty = None
records = []
try:
    # serve prints the pty's path on the first line of stdout once it serves.
    deadline = time.monotonic() + 30
    while pty is None:
        with open(serve_out.name) as f:
            first = f.readline()
        if first.endswith("\n") and first.strip():
            pty = first.strip()
        elif serve.poll() is not None or time.monotonic() > deadline:
            with open(serve_err.name) as f:
                raise SystemExit(f"serve did not print its pty: exit {serve.poll()}, {last_line(f.read())!r}")
        else:
            time.sleep(0.05)

    before = status()
    dof = len(before["measured"])
    limits = joint_limits(dof)
    rng = random.Random(args.seed)

    for n in range(args.moves):
        start, end = draw(rng, limits), draw(rng, limits)
        record = {"n": n, "start": [round(v, 6) for v in start], "end": [round(v, 6) for v in end]}
        records.append(record)
        if serve.poll() is not None:
            record.update(outcome="other", why="serve exited")
            break

        code, _, _, err, _ = run(port_cmd("joints", "--q", fmt(start), "--timeout", str(args.timeout)),
                                 wall_limit=2 * args.timeout + 30)
        if code != 0:
            # Without the start the move would not be the one drawn: count it, don't run it.
            record.update(outcome="other", why=f"joints to start failed (exit {code}): {last_line(err)}")
            continue

        # fk prints its JSON without --json; the tool position is `position` (m, base frame).
        fk = subprocess.run([armctl, "fk", "--arm", args.arm, "--q", fmt(end)], capture_output=True, text=True,
                            check=True)
        target = json.loads(fk.stdout)["position"]
        record["target"] = [round(v, 6) for v in target]

        # armctl's --timeout is controller time; the wall limit is only there to catch a true hang.
        code, wall, out, err, killed = run(
            port_cmd("move", "--to", fmt(target), "--speed", str(args.speed), "--timeout", str(args.timeout)),
            wall_limit=2 * args.timeout + 30)
        record.update(exit=code, wall_s=round(wall, 3))
        answer = None
        if out.strip():
            try:
                answer = json.loads(last_line(out))
            except json.JSONDecodeError:
                record["stdout"] = out.strip()
        if answer is not None:
            record["answer"] = answer
        if err.strip():
            record["stderr"] = last_line(err)

        if code == 0 and answer is not None and answer.get("error_mm") is not None and answer["error_mm"] < 1.0:
            record["outcome"] = "arrived"
        elif killed or wall >= args.timeout:
            record["outcome"] = "timed_out"
        elif code != 0 and wall < REFUSED_WITHIN_S and answer is None:
            record["outcome"] = "refused"
        else:
            record["outcome"] = "other"
        print(f"{args.arm} move {n + 1}/{args.moves}: {record['outcome']}"
              f" ({answer.get('path') if answer else last_line(err)}; {wall:.1f} s)", file=sys.stderr, flush=True)

    after = status()
finally:
    # Ctrl-C is serve's own way out: the arm decelerates and holds, then it prints its figures
    # (the bus's ticks, the safety monitor) and exits. SIGTERM, then SIGKILL, only if it does not.
    if serve.poll() is None:
        serve.send_signal(signal.SIGINT)
        try:
            serve.wait(timeout=30)
        except subprocess.TimeoutExpired:
            serve.terminate()
            try:
                serve.wait(timeout=10)
            except subprocess.TimeoutExpired:
                serve.kill()
                serve.wait()
total_s = time.perf_counter() - run_started

with open(serve_err.name) as f:
    serve_stderr = f.read()
os.unlink(serve_out.name)
os.unlink(serve_err.name)
violations = [line for line in serve_stderr.splitlines() if "violations" in line]
bus_lines = [line for line in serve_stderr.splitlines() if re.match(r"bus: \d+ ticks", line)]

counts = {"moves": len(records)}
for outcome in ("arrived", "refused", "timed_out", "other"):
    counts[outcome] = sum(r.get("outcome") == outcome for r in records)
by_path = {}
for r in records:
    if r.get("outcome") == "arrived":
        path = r["answer"].get("path")
        by_path[path] = by_path.get(path, 0) + 1
arrived = [r for r in records if r.get("outcome") == "arrived"]
refusals = {}
for r in records:
    if r.get("outcome") == "refused":
        refusals[r.get("stderr", "")] = refusals.get(r.get("stderr", ""), 0) + 1
error_deltas = {k: v - before["errors"].get(k, 0) for k, v in after["errors"].items()}

result = {
    "arm": args.arm,
    "settings": {"moves": args.moves, "fraction": args.fraction, "seed": args.seed, "speed": args.speed,
                 "timeout": args.timeout},
    "joint_limits": limits,
    "counts": counts,
    "arrived_by_path": by_path,
    "refused_reasons": refusals,
    "arrived_error_mm": {"median": statistics.median(r["answer"]["error_mm"] for r in arrived),
                         "max": max(r["answer"]["error_mm"] for r in arrived)} if arrived else None,
    "arrived_move_s": {"median": statistics.median(r["wall_s"] for r in arrived),
                       "max": max(r["wall_s"] for r in arrived)} if arrived else None,
    "status_errors_after": after["errors"],
    "status_errors_during_run": error_deltas,
    "status_state_after": after["state"],
    "serve_exit": serve.returncode,
    "serve_safety_monitor": violations,
    "serve_bus": bus_lines,
    "total_s": round(total_s, 1),
    "failures": [r for r in records if r.get("outcome") != "arrived"],
}
paths = ", ".join(f"{v} {k}" for k, v in sorted(by_path.items(), key=lambda kv: -kv[1])) or "none"
print(f"{args.arm}: {counts['arrived']} of {counts['moves']} moves arrived ({paths}); "
      f"{counts['refused']} refused, {counts['timed_out']} timed out, {counts['other']} other; "
      f"line_fallbacks {after['errors'].get('line_fallbacks')}; "
      f"{violations[-1] if violations else 'no safety-monitor line from serve'}; {total_s:.0f} s")
print(json.dumps(result))
