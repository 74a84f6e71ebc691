#!/usr/bin/python3
"""armctl's IK against KDL's Levenberg-Marquardt solver (ChainIkSolverPos_LMA) on the same targets:
the figures for "at least 10x KDL end to end with a short tail".

    /usr/bin/python3 host/scripts/ik_vs_kdl.py target/release/armctl [--arms ur5e,puma560] [--n 1000]
                                                [--runs 5] [--seed 1] [--solvers numeric,auto]
                                                [--kdl-eps 1e-5,1e-7]

Run it with Debian's /usr/bin/python3, which has PyKDL (`apt-get install python3-pykdl`); a pyenv or
virtualenv python3 earlier on PATH usually has not. Standard library plus PyKDL, nothing else.

For each arm: N reachable full-pose targets, the forward kinematics (`armctl fk`) of joint vectors
drawn uniformly within the limits (seeded, so the same every time), written as JSON lines to the
temporary directory. armctl solves them with `ik --batch FILE --solver S > /dev/null` for S in
numeric and auto, RUNS times each; KDL solves them in RUNS passes with the same chain built from
standard DH (checked against `armctl fk` first) and the C++ defaults eps 1e-5, maxiter 500,
eps_joints 1e-15, seeded at the middle of the limits as armctl is. Every figure is the median over the
runs; the last line of output is one JSON object with all of them.

KDL's eps bounds the norm of the error twist weighted by L = (1, 1, 1, 0.01, 0.01, 0.01), so at eps
1e-5 it stops with up to 1e-3 rad of orientation error, short of armctl's 1e-5 rad; PyKDL takes another
L only as a numpy array. Hence a second KDL row, eps 1e-7 (--kdl-eps), whose answers do reach armctl's
tolerances: the like-for-like one. The ratio columns are against the first --kdl-eps.

KDL's time is the CartToJnt call alone (through pybind11, so a fraction of a microsecond of binding
is in it), against armctl's per-solve time and its end to end time per line (whole command, target
file read, results written). That is the comparison most favourable to KDL.

A benchmark, not a test: the figures move with the machine's load; quote the medians.
"""
import argparse
import json
import math
import os
import random
import re
import statistics
import subprocess
import sys
import tempfile
import time

try:
    import PyKDL
except ImportError:
    sys.exit("no PyKDL in this Python (%s): run with /usr/bin/python3 after `apt-get install python3-pykdl`"
             % sys.executable)

TAU = 2.0 * math.pi
HALF_PI = 0.5 * math.pi

# Standard DH rows (a, alpha, d) and joint limits (rad), as in kinematics/src/presets.rs; armctl has no
# command that prints an arm's limits, so they are copied here. The tool frame is the last DH frame.
ARMS = {
    "ur5e": {
        "dh": [(0.0, HALF_PI, 0.1625), (-0.425, 0.0, 0.0), (-0.3922, 0.0, 0.0),
               (0.0, HALF_PI, 0.1333), (0.0, -HALF_PI, 0.0997), (0.0, 0.0, 0.0996)],
        "limits": [(-TAU, TAU)] * 6,
    },
    "puma560": {
        "dh": list(zip([0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0],
                       [HALF_PI, 0.0, -HALF_PI, HALF_PI, -HALF_PI, 0.0],
                       [0.67183, 0.0, 0.15005, 0.4318, 0.0, 0.0])),
        "limits": [(-math.radians(x), math.radians(x)) for x in (160, 110, 135, 266, 100, 266)],
    },
}

POSITION_TOLERANCE = 1e-5  # m; armctl's default in f64, and KDL's eps
ORIENTATION_TOLERANCE = 1e-5  # rad; armctl's default in f64
FK_CHECK_POSES = 20
FK_CHECK_TOLERANCE = 1e-9

SUMMARY = re.compile(
    r"(?P<converged>\d+)/(?P<total>\d+) converged .*?, (?P<rejected>\d+) rejected lines; "
    r"per solve mean (?P<mean>[0-9.]+) us, median (?P<median>[0-9.]+) us, p99 (?P<p99>[0-9.]+) us; "
    r"end to end (?P<e2e>[0-9.]+) us per line")


def p99(sorted_values):
    """Nearest-rank 99th percentile, as armctl computes it."""
    return sorted_values[max(0, math.ceil(0.99 * len(sorted_values)) - 1)]


def rotation_angle(ra, rb):
    """Angle of ra^T rb (3x3 nested lists). atan2 of the skew part keeps it accurate near zero, where
    acos of the trace (and KDL's GetRotAngle, which rounds below ~1e-6 to 0) cannot resolve 1e-9."""
    r = [[sum(ra[k][i] * rb[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    s = 0.5 * math.sqrt((r[2][1] - r[1][2]) ** 2 + (r[0][2] - r[2][0]) ** 2 + (r[1][0] - r[0][1]) ** 2)
    return math.atan2(s, 0.5 * (r[0][0] + r[1][1] + r[2][2] - 1.0))


def kdl_rotation(frame):
    return [[frame.M[i, j] for j in range(3)] for i in range(3)]


def armctl_fk(armctl, arm, q):
    # --q=... so that a leading minus sign is not taken for an option; repr round-trips the float.
    done = subprocess.run([armctl, "fk", "--arm", arm, "--q=" + ",".join(repr(x) for x in q)],
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout)


def make_targets(armctl, arm, n, seed):
    """N (q, fk) pairs and the batch file of their poses. `armctl fk` takes one q a call, so one
    process each: about 4 ms apiece."""
    rng = random.Random(seed)
    limits = ARMS[arm]["limits"]
    pairs = []
    for _ in range(n):
        q = [rng.uniform(lo, hi) for lo, hi in limits]
        pairs.append((q, armctl_fk(armctl, arm, q)))
    path = os.path.join(tempfile.gettempdir(), f"ik_vs_kdl-{arm}-{n}-seed{seed}.jsonl")
    with open(path, "w") as out:
        for _, fk in pairs:
            out.write(json.dumps({"position": fk["position"], "quaternion_wxyz": fk["quaternion_wxyz"]}) + "\n")
    return pairs, path


def kdl_chain(arm):
    # Segment(Joint(RotZ), Frame.DH(a, alpha, d, 0)) is Rz(q) Tz(d) Tx(a) Rx(alpha): one standard DH row.
    chain = PyKDL.Chain()
    for a, alpha, d in ARMS[arm]["dh"]:
        chain.addSegment(PyKDL.Segment(PyKDL.Joint(PyKDL.Joint.RotZ), PyKDL.Frame.DH(a, alpha, d, 0.0)))
    return chain


def jnt_array(q):
    array = PyKDL.JntArray(len(q))
    for i, x in enumerate(q):
        array[i] = x
    return array


def check_chain(arm, chain, pairs):
    """KDL's FK of the first poses' q against armctl's: the two must be the same arm, else the
    comparison means nothing."""
    fk = PyKDL.ChainFkSolverPos_recursive(chain)
    worst_position = worst_rotation = 0.0
    for q, theirs in pairs[:FK_CHECK_POSES]:
        frame = PyKDL.Frame()
        fk.JntToCart(jnt_array(q), frame)
        worst_position = max(worst_position, math.dist([frame.p[i] for i in range(3)], theirs["position"]))
        worst_rotation = max(worst_rotation, rotation_angle(kdl_rotation(frame), theirs["rotation"]))
    if worst_position > FK_CHECK_TOLERANCE or worst_rotation > FK_CHECK_TOLERANCE:
        sys.exit(f"{arm}: the KDL chain does not match `armctl fk` (worst of {FK_CHECK_POSES} poses: "
                 f"{worst_position:.3g} m, {worst_rotation:.3g} rad; tolerance {FK_CHECK_TOLERANCE:g}); "
                 f"fix the DH rows in ARMS before comparing solvers")
    print(f"{arm}: KDL chain agrees with armctl fk on {FK_CHECK_POSES} poses (worst {worst_position:.2g} m, "
          f"{worst_rotation:.2g} rad)", file=sys.stderr)


def wraps_into(q, limits):
    """True if every joint can be moved by whole turns into its limits (KDL's LMA knows no limits;
    a revolute joint's value is only defined modulo 2 pi)."""
    for x, (lo, hi) in zip(q, limits):
        if x + math.ceil((lo - x) / TAU) * TAU > hi:
            return False
    return True


def run_kdl(arm, chain, pairs, runs, eps):
    limits = ARMS[arm]["limits"]
    solver = PyKDL.ChainIkSolverPos_LMA(chain, eps=eps, maxiter=500, eps_joints=1e-15)
    fk = PyKDL.ChainFkSolverPos_recursive(chain)
    # Everything but the call is built beforehand so that the timer holds CartToJnt alone.
    targets = []
    for _, pose in pairs:
        w, x, y, z = pose["quaternion_wxyz"]
        targets.append((PyKDL.Frame(PyKDL.Rotation.Quaternion(x, y, z, w), PyKDL.Vector(*pose["position"])),
                        pose["rotation"]))
    seed = jnt_array([0.5 * (lo + hi) for lo, hi in limits])
    q_out = PyKDL.JntArray(len(limits))
    reached = PyKDL.Frame()
    passes = []
    for _ in range(runs):
        times, reaching, within, codes = [], 0, 0, {}
        for frame, rotation in targets:
            started = time.perf_counter_ns()
            code = solver.CartToJnt(seed, frame, q_out)
            times.append((time.perf_counter_ns() - started) / 1e3)
            codes[code] = codes.get(code, 0) + 1
            q = [q_out[i] for i in range(len(limits))]
            fk.JntToCart(q_out, reached)
            if ((reached.p - frame.p).Norm() <= POSITION_TOLERANCE
                    and rotation_angle(rotation, kdl_rotation(reached)) <= ORIENTATION_TOLERANCE):
                reaching += 1
                within += wraps_into(q, limits)
        times.sort()
        passes.append({"mean": statistics.fmean(times), "median": statistics.median(times), "p99": p99(times),
                       "reaching": reaching, "within_limits": within,
                       "codes": {solver.strError(c): k for c, k in sorted(codes.items())}})
    figures = {key: statistics.median(p[key] for p in passes)
               for key in ("mean", "median", "p99", "reaching", "within_limits")}
    # The solver is deterministic, so every pass returns the same codes; the first pass stands for all.
    figures["return_codes"] = passes[0]["codes"]
    return figures


def run_armctl(armctl, arm, path, n, solver, runs):
    command = [armctl, "ik", "--arm", arm, "--batch", path, "--solver", solver]
    # One run with the output kept, to check it against the summary; not timed (a pipe is not /dev/null).
    checked = subprocess.run(command, capture_output=True, text=True)
    if checked.returncode not in (0, 1) or not SUMMARY.search(checked.stderr):
        sys.exit(f"`{' '.join(command)}` failed ({checked.returncode}): {checked.stderr.strip()}")
    limits = ARMS[arm]["limits"]
    results = [json.loads(line) for line in checked.stdout.splitlines()]
    converged = [r for r in results if r.get("status") == "converged"]
    summary = SUMMARY.search(checked.stderr)
    problems = []
    if len(results) != n:
        problems.append(f"{len(results)} result lines for {n} targets")
    if len(converged) != int(summary["converged"]):
        problems.append(f"{len(converged)} lines say converged, the summary {summary['converged']}")
    outside = [r["line"] for r in converged if not all(lo <= x <= hi for x, (lo, hi) in zip(r["q"], limits))]
    if outside:
        problems.append(f"{len(outside)} converged lines outside the limits (lines {outside[:5]}...)")
    loose = [r["line"] for r in converged if r["position_error"] > POSITION_TOLERANCE
             or r["orientation_error"] > ORIENTATION_TOLERANCE]
    if loose:
        problems.append(f"{len(loose)} converged lines report errors above the tolerances (lines {loose[:5]}...)")
    for problem in problems:
        print(f"{arm} {solver}: CHECK FAILED: {problem}", file=sys.stderr)
    # Which method answered (auto: the closed form or its DLS fallback); older builds do not say.
    by_solver = {}
    for r in converged:
        method = r.get("solver", solver)
        by_solver[method] = by_solver.get(method, 0) + 1

    figures = []
    for _ in range(runs):
        started = time.perf_counter()
        done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        wall = (time.perf_counter() - started) * 1e6 / n
        line = SUMMARY.search(done.stderr)
        if done.returncode not in (0, 1) or not line:
            sys.exit(f"`{' '.join(command)}` failed ({done.returncode}): {done.stderr.strip()}")
        figures.append({"converged": int(line["converged"]), "rejected": int(line["rejected"]),
                        "mean": float(line["mean"]), "median": float(line["median"]), "p99": float(line["p99"]),
                        "end_to_end": float(line["e2e"]), "wall": wall})
    result = {key: statistics.median(f[key] for f in figures) for key in figures[0]}
    result.update(within_limits=len(converged) - len(outside), answered_by=by_solver, check_problems=problems)
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("armctl", help="path to the armctl binary (target/release/armctl)")
    parser.add_argument("--arms", default="ur5e,puma560")
    parser.add_argument("--n", type=int, default=1000, help="targets per arm")
    parser.add_argument("--runs", type=int, default=5, help="runs (armctl) and passes (KDL) to take the median of")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--solvers", default="numeric,auto", help="armctl --solver values to compare")
    parser.add_argument("--kdl-eps", default="1e-5,1e-7",
                        help="KDL LMA eps values, one row each; the ratios are against the first")
    args = parser.parse_args()
    arms, solvers = args.arms.split(","), args.solvers.split(",")
    kdl_eps = [float(x) for x in args.kdl_eps.split(",")]
    for arm in arms:
        if arm not in ARMS:
            sys.exit(f"no DH rows for {arm}: known arms are {', '.join(ARMS)}")

    report = {"n": args.n, "runs": args.runs, "seed": args.seed, "armctl": args.armctl, "arms": {}}
    for arm in arms:
        started = time.perf_counter()
        pairs, path = make_targets(args.armctl, arm, args.n, args.seed)
        print(f"{arm}: {args.n} targets in {path} ({time.perf_counter() - started:.1f} s)", file=sys.stderr)
        chain = kdl_chain(arm)
        check_chain(arm, chain, pairs)
        kdls = {eps: run_kdl(arm, chain, pairs, args.runs, eps) for eps in kdl_eps}
        ours = {solver: run_armctl(args.armctl, arm, path, args.n, solver, args.runs) for solver in solvers}
        for eps, kdl in kdls.items():
            for figures in ours.values():
                figures.setdefault("ratios", {})[f"kdl_eps_{eps:g}"] = {
                    "kdl_mean_over_end_to_end": kdl["mean"] / figures["end_to_end"],
                    "kdl_mean_over_solve_mean": kdl["mean"] / figures["mean"],
                    "kdl_p99_over_p99": kdl["p99"] / figures["p99"]}
        report["arms"][arm] = {"targets": path, **{f"kdl_lma_eps_{eps:g}": k for eps, k in kdls.items()},
                               **{f"armctl_{s}": f for s, f in ours.items()}}

        print(f"\n{arm}, {args.n} targets, median of {args.runs} runs; solve rate = reaches within "
              f"{POSITION_TOLERANCE:g} m and {ORIENTATION_TOLERANCE:g} rad\n")
        first = f"kdl_eps_{kdl_eps[0]:g}"
        print(f"| arm | solver | solve rate | within limits | mean us | median us | p99 us | end to end us/line "
              f"| wall us/line | KDL (eps {kdl_eps[0]:g}) mean / armctl end to end "
              f"| KDL (eps {kdl_eps[0]:g}) mean / armctl solve mean |")
        print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        pct = lambda k: f"{100.0 * k / args.n:.1f} %"
        for eps, kdl in kdls.items():
            print(f"| {arm} | KDL LMA eps {eps:g} | {pct(kdl['reaching'])} | {pct(kdl['within_limits'])} "
                  f"| {kdl['mean']:.2f} | {kdl['median']:.2f} | {kdl['p99']:.2f} | - | - | - | - |")
        for solver, f in ours.items():
            print(f"| {arm} | armctl {solver} | {pct(f['converged'])} | {pct(f['within_limits'])} | {f['mean']:.2f} "
                  f"| {f['median']:.2f} | {f['p99']:.2f} | {f['end_to_end']:.2f} | {f['wall']:.2f} "
                  f"| {f['ratios'][first]['kdl_mean_over_end_to_end']:.1f}x "
                  f"| {f['ratios'][first]['kdl_mean_over_solve_mean']:.1f}x |")
        print("\nKDL times are the CartToJnt call alone; wall = the armctl process timed from outside; within "
              "limits for KDL = after wrapping by whole turns")
        for eps, kdl in kdls.items():
            ratios = "; ".join(f"armctl {s}: mean / end to end {r['kdl_mean_over_end_to_end']:.1f}x, "
                               f"mean / solve mean {r['kdl_mean_over_solve_mean']:.1f}x, p99 / p99 "
                               f"{r['kdl_p99_over_p99']:.1f}x"
                               for s, r in ((s, f["ratios"][f"kdl_eps_{eps:g}"]) for s, f in ours.items()))
            print(f"KDL eps {eps:g}: return codes {kdl['return_codes']}; KDL over {ratios}")
        for solver, f in ours.items():
            print(f"armctl {solver}: converged answers by {f['answered_by']}; output check "
                  f"{'FAILED: ' + '; '.join(f['check_problems']) if f['check_problems'] else 'passed'}")
        sys.stdout.flush()
    print(json.dumps(report))


if __name__ == "__main__":
    main()
