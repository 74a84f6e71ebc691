#!/usr/bin/env python3
"""Smoothness of a policy-like action stream on the same simulated servos: LeRobot's SO101Follower
(each action written straight to the servos as their goal) against armctl_follower (each action a
timed keyframe on the firmware core's player).

The stream: 30 actions a second for 20 s along a smooth joint path (sums of sines, 25 degrees and
less, starting at rest at zero), plus Gaussian noise of 0.5 degrees on every action, plus a 2-degree
jump every 30 actions (each chunk of 30 re-anchored 1 degree off the path, alternately above and
below: a policy's chunks re-anchored on a stale observation). Seeded: both robots get the same
actions at the same times.

Each robot drives fresh simulated servos (`armctl sim servos --pty --arm so101 --burst-ms 1`,
calibrated by LeRobot's `write_calibration`), which record their positions every 2 ms and judge
every goal against the calibrated arm's limits. From the recording of the five body joints, over
the stream's seconds 1 to 19:
- RMS jerk and peak acceleration of the positions (finite differences, deg/s^3 and deg/s^2, over
  the joints) on a 20 ms grid: two control periods of armctl's core, so that its goals' 100 Hz
  staircase and their rounding to whole ticks (half a tick each way: on a 10 ms grid that alone is
  about 1e5 deg/s^3 RMS, motion no arm's inertia passes) do not drown the motion; the 10 ms
  figures are in the JSON too;
- the lag: the shift of the noiseless path that fits the positions best (least squares), ms, and
  the RMS error left at that shift, degrees;
- the safety monitor's goals checked and violations.

Goals (issue 29): RMS jerk at least 5x lower than LeRobot's, 0 violations on armctl_follower's
side, lag within one action period plus 20 ms.

    python host/scripts/smoothness.py [--armctl target/release/armctl] [--servos physical] [--json]

Needs lerobot, armctl and lerobot_robot_armctl installed (see docs/python.md). The clocks: the path's
time zero is the moment the first action is sent; the recording's clock starts when the servos
start; the offset between them is taken from the moment the servos' pseudo-terminal is announced,
which is late by the time to read a line from a pipe (well under a millisecond on an idle machine).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import lerobot_sim  # noqa: E402

RATE = 30.0
SECONDS = 20.0
NOISE_DEG = 0.5
JUMP_DEG = 2.0
CHUNK = 30
JOINTS = lerobot_sim.SO101_MOTORS[:5]
WINDOW = (1.0, 19.0)
GRID = 0.020
FINE_GRID = 0.010


def path_deg(t: np.ndarray) -> np.ndarray:
    """The noiseless path, degrees, (len(t), 5): at rest at zero at t = 0 (1 - cos terms)."""
    t = np.asarray(t, dtype=np.float64)[:, None]
    amp = np.array([25.0, 20.0, 20.0, 15.0, 25.0])
    period = np.array([6.0, 5.0, 7.0, 4.0, 5.5])
    second = np.array([0.3, 0.25, 0.2, 0.3, 0.2])
    w = 2 * np.pi / period
    return amp * (0.5 * (1 - np.cos(w * t)) - second * np.sin(w * t) ** 2 * np.sin(0.5 * w * t))


def actions(seed: int = 29) -> tuple[np.ndarray, np.ndarray]:
    """Times (s) and actions (degrees, (n, 5)): the path, the noise and the chunk offsets."""
    rng = np.random.default_rng(seed)
    n = int(RATE * SECONDS)
    t = np.arange(n) / RATE
    offset = np.where((np.arange(n) // CHUNK) % 2 == 0, 0.5, -0.5)[:, None] * JUMP_DEG
    offset[:CHUNK] = 0.0  # the first chunk starts on the path, at rest
    noise = rng.normal(0.0, NOISE_DEG, size=(n, len(JOINTS)))
    noise[0] = 0.0
    return t, path_deg(t) + offset + noise


def run_stream(robot, t: np.ndarray, a: np.ndarray) -> float:
    """Sends the actions at their times (observation, then action, as a policy loop does);
    returns the monotonic time of the first."""
    start = time.monotonic() + 0.2
    for i, ti in enumerate(t):
        due = start + ti
        while (left := due - time.monotonic()) > 0.002:
            time.sleep(left - 0.001)
        while time.monotonic() < due:
            pass
        robot.get_observation()
        action = {f"{n}.pos": float(v) for n, v in zip(JOINTS, a[i])}
        action["gripper.pos"] = 50.0
        robot.send_action(action)
    return start


def analyse(record: Path, t0: float, cal: dict) -> dict:
    """The figures of one recording; `t0` is the path's zero on the recording's clock."""
    data = np.genfromtxt(record, delimiter=",", names=True)
    t = data["t"] - t0
    deg = np.stack([(data[f"pos_{i + 1}"] - (cal[n]["range_min"] + cal[n]["range_max"]) / 2.0) * 360.0 / 4095.0
                    for i, n in enumerate(JOINTS)], axis=1)
    def on(step: float) -> tuple[np.ndarray, np.ndarray]:
        g = np.arange(WINDOW[0], WINDOW[1], step)
        return g, np.stack([np.interp(g, t, deg[:, j]) for j in range(deg.shape[1])], axis=1)

    def derivatives(p: np.ndarray, step: float) -> tuple[float, float]:
        acc = np.diff(p, 2, axis=0) / step**2
        jerk = np.diff(p, 3, axis=0) / step**3
        return float(np.sqrt(np.mean(jerk**2))), float(np.max(np.abs(acc)))

    grid, p = on(GRID)
    jerk, acc = derivatives(p, GRID)
    fine_jerk, fine_acc = derivatives(on(FINE_GRID)[1], FINE_GRID)
    best = None
    for lag_ms in np.arange(0.0, 300.0, 1.0):
        err = p - path_deg(grid - lag_ms * 1e-3)
        rms = float(np.sqrt(np.mean(err**2)))
        if best is None or rms < best[1]:
            best = (float(lag_ms), rms)
    return {
        "rms_jerk_deg_s3": jerk,
        "peak_acceleration_deg_s2": acc,
        "rms_jerk_10ms_grid_deg_s3": fine_jerk,
        "peak_acceleration_10ms_grid_deg_s2": fine_acc,
        "lag_ms": best[0],
        "rms_error_at_lag_deg": best[1],
    }


def one(kind: str, armctl_bin: str, work: Path, t: np.ndarray, a: np.ndarray, servos: str) -> dict:
    cal = lerobot_sim.so101_calibration()
    cal_dir = work / kind
    cal_file = lerobot_sim.write_calibration_file(cal_dir / "bench.json", cal)
    record = work / f"{kind}.csv"
    # so101_follower reads the positions and writes the goals once an action: its control period
    # is the actions', which the monitor judges its steps over (armctl's core: its own 10 ms).
    period_ms = 1000.0 / RATE if kind == "lerobot" else None
    physical = servos == "physical"
    servos = lerobot_sim.SimServos(armctl_bin, calibration=cal_file, record=record, period_ms=period_ms,
                                   servos=servos)
    announced = time.monotonic()
    try:
        lerobot_sim.calibrate_bus(servos.port, "bench", cal_dir)
        if kind == "lerobot":
            from lerobot.robots.so_follower import SO101Follower, SO101FollowerConfig

            robot = SO101Follower(SO101FollowerConfig(port=servos.port, id="bench", calibration_dir=cal_dir))
        else:
            from lerobot_robot_armctl import ArmctlFollower, ArmctlFollowerConfig

            # On physical servos the firmware compensates their sag (the core sets them up with
            # LeRobot's P of 16, as it does real ones); so101_follower has nothing of the kind.
            robot = ArmctlFollower(ArmctlFollowerConfig(bus=servos.port, protocol="sts", id="bench",
                                                        calibration_dir=cal_dir, fps=RATE,
                                                        gravity_compensation=physical or None))
        robot.connect(calibrate=False)
        underruns = None
        try:
            start = run_stream(robot, t, a)
            time.sleep(0.5)
            if kind == "armctl":
                # The player's own account: where it ran out of keyframes it braked (and, since
                # issue 43, went back to the last one), so the motion differs only there.
                underruns = robot._arm.status()["errors"]["underruns"]
        finally:
            robot.disconnect()
    finally:
        monitor = servos.stop()
    figures = analyse(record, start - announced, cal)
    figures["goals_checked"] = monitor["goals"]
    figures["violations"] = monitor["violations"]
    figures["first_violations"] = monitor["first_violations"]
    if underruns is not None:
        figures["underruns"] = underruns
    return figures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--armctl", default=None, help="the armctl binary (default: target/release, else debug)")
    parser.add_argument("--json", action="store_true", help="print one line of JSON")
    parser.add_argument("--keep", type=Path, default=None, help="keep the recordings in this folder")
    parser.add_argument("--servos", choices=("ideal", "physical"), default="ideal",
                        help="the simulated servos: ideal, or physical ones that carry the arm (docs/servo-model.md)")
    args = parser.parse_args()
    armctl_bin = args.armctl or lerobot_sim.default_armctl()
    t, a = actions()
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        results = {kind: one(kind, armctl_bin, work, t, a, args.servos) for kind in ("lerobot", "armctl")}
    ratio = results["lerobot"]["rms_jerk_deg_s3"] / results["armctl"]["rms_jerk_deg_s3"]
    budget = 1000.0 / RATE + 20.0
    goals = {
        "jerk_ratio": ratio, "jerk_ratio_goal": 5.0, "jerk_met": ratio >= 5.0,
        "violations_met": results["armctl"]["violations"] == 0,
        "lag_budget_ms": budget, "lag_met": results["armctl"]["lag_ms"] <= budget,
    }
    if args.json:
        print(json.dumps({"rate_hz": RATE, "seconds": SECONDS, "servos": args.servos, **results, "goals": goals}))
        return 0
    print(f"{args.servos} servos, {RATE:.0f} Hz for {SECONDS:.0f} s, noise {NOISE_DEG} deg, a {JUMP_DEG} deg jump every "
          f"{CHUNK} actions; figures over seconds {WINDOW[0]:.0f}-{WINDOW[1]:.0f}, five body joints, {GRID * 1e3:.0f} ms grid")
    print(f"{'':22} {'RMS jerk':>14} {'peak accel':>12} {'lag':>8} {'RMS err':>8} {'goals':>7} {'violations':>10}")
    for kind, name in (("lerobot", "SO101Follower"), ("armctl", "armctl_follower")):
        r = results[kind]
        print(f"{name:22} {r['rms_jerk_deg_s3']:>10.0f} °/s³ {r['peak_acceleration_deg_s2']:>8.0f} °/s² "
              f"{r['lag_ms']:>5.0f} ms {r['rms_error_at_lag_deg']:>6.2f} ° {r['goals_checked'] or 0:>7} "
              f"{r['violations']:>10}")
    print(f"jerk {ratio:.1f}x lower (goal 5x: {'met' if goals['jerk_met'] else 'MISSED'}); violations on "
          f"armctl_follower: {results['armctl']['violations']} ({'met' if goals['violations_met'] else 'MISSED'}); lag "
          f"{results['armctl']['lag_ms']:.0f} ms against {budget:.0f} ms ({'met' if goals['lag_met'] else 'MISSED'}); "
          f"player underruns: {results['armctl'].get('underruns')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
