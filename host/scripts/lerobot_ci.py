#!/usr/bin/env python3
"""LeRobot's own command-line tools against simulated SO-101 arms: CI's end-to-end check that
`armctl_follower` is a LeRobot robot like any other.

    python host/scripts/lerobot_ci.py --armctl target/debug/armctl [--keep DIR] [--servos physical]

Runs `lerobot-teleoperate`, `lerobot-record` and `lerobot-replay` (the ones installed next to this
Python, as subprocesses, with stdin closed, no network, no upload, no sounds, no display, and
HF_HOME, HF_LEROBOT_HOME and HF_LEROBOT_CALIBRATION inside a temporary folder) with an SO-101
leader arm (`so101_leader`) on simulated servos moved by a scripted hand, and a follower on fresh
simulated servos for every run (`armctl sim servos --arm so101 --calibration FILE --record CSV`:
the safety monitor judges every goal against the calibrated arm's joint and speed limits, and the
servos' positions are recorded every 2 ms). Every servo bus is calibrated the way LeRobot does it
(its `write_calibration` writes the calibration file's values, centred on tick 2048, into the
servos), so no tool prompts. Steps, one line each:

1. setup: the leader's servos and the calibration files of the leader and the follower;
2. teleoperate: `lerobot-teleoperate` of armctl_follower by the leader for 5 s; exit 0, the
   follower followed (shoulder_pan moved over 20 degrees), 0 violations;
3. record: `lerobot-record` of 2 episodes of 4 s (1 s reset) with armctl_follower and the leader,
   no video; exit 0, the dataset has 2 episodes whose `action` and `observation.state` are named
   as so101_follower's, each holding the hand's motion; 0 violations;
4. replay on armctl_follower: `lerobot-replay` of episode 0; the follower's tracking of the
   episode's actions, from the servos' recording: the time shift (0-300 ms) that fits best, the RMS
   and largest error at that shift per body joint; passes if the largest RMS error is within
   ARMCTL_RMS_BOUND_DEG, the final position within FINAL_BOUND_DEG of the last action, and the
   monitor found 0 violations;
5. replay on so101_follower (LeRobot's own robot, writing each action as the servos' goal) onto
   fresh servos: the same figures, checked against the looser SO101_RMS_BOUND_DEG (its servos chase
   a step every frame); its violations are only reported.

The hand (the leader's servos are limp: LeRobot turns their torque off) plays one motion per
episode, started when lerobot-record says "Recording episode N": from rest (every horn at tick
2048, 0 degrees), shoulder_pan to +31 then -22 degrees and back, shoulder_lift, elbow_flex and
wrist_flex out and back, the gripper open and back, in 3.4 s, then rest until the episode ends;
so every episode starts and ends at rest, where fresh servos stand, and a replay starts without a
jump. During teleoperate it plays the motion over and over.

Clocks: the recording's clock starts when the servos start (taken as the moment their pty is
announced); the replay's first action is sent right after lerobot-replay logs "Replaying episode",
whose arrival here is timed (Python's stderr is line-buffered, PYTHONUNBUFFERED is set); action i
is due 1/fps * i later. The tracking error at a shift s compares action i with the recorded
position at (first action + i/fps + s).

With `--servos physical` the followers' servos carry the arm under gravity, sag and lag
(docs/servo-model.md; the leader's stay ideal: a hand holds them) and armctl_follower asks for
gravity compensation; the bounds stay those of the ideal servos.

Exit code 0 only if every check passes.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.dont_write_bytecode = True  # no __pycache__ left in host/scripts by importing lerobot_sim
sys.path.insert(0, str(Path(__file__).resolve().parent))
import lerobot_sim  # noqa: E402

FPS = 30
LEADER_ID = "ci_leader"
FOLLOWER_ID = "ci_follower"
REPO_ID = "local/armctl_ci"
TELEOP_S = 5
EPISODES = 2
EPISODE_S = 4
RESET_S = 1
MOTORS = lerobot_sim.SO101_MOTORS
BODY = MOTORS[:5]
NAMES = [f"{m}.pos" for m in MOTORS]
# The bounds, from the measured figures with margin. Over 10 runs on these simulated servos,
# armctl_follower tracked the replayed actions within 0.66-1.09 degrees RMS (shoulder_pan, the worst
# joint; the others 0.1-0.3) at a best shift of 73-94 ms (the player's keyframes are the actions,
# each due one lead, 41 ms, after it is sent, then the servos' own lag), the largest errors, 2.6-3.7
# degrees, where the hand reverses shoulder_pan (70 deg/s of velocity change in an instant): the
# player rounds the corner within the joint's acceleration limit. so101_follower's goals are the
# actions themselves: 0.07-0.15 degrees RMS at 46-54 ms on the simulator, whose servos reach each
# step within the frame; its bound is the looser one all the same, as real servos chasing a step
# every frame lag more.
ARMCTL_RMS_BOUND_DEG = 2.0
SO101_RMS_BOUND_DEG = 3.0
FINAL_BOUND_DEG = 1.0
SHIFT_SEARCH_MS = (0, 300)
# The teleoperated follower must have followed the hand's shoulder_pan (53 degrees of travel).
MOVED_DEG = 20.0
# Every subprocess must end within this (the whole script takes about 1 to 2 minutes).
TIMEOUT_S = 90.0

# The hand's motion, in the leader's ticks: (start s, servo id, from, to, seconds). Each servo's
# sweeps follow on from each other (a sweep starts by putting the horn at FROM).
MOTION = [
    (0.20, 1, 2048, 2400, 1.0), (1.22, 1, 2400, 1800, 1.4), (2.64, 1, 1800, 2048, 0.8),
    (0.40, 2, 2048, 2250, 1.2), (1.62, 2, 2250, 2048, 1.2),
    (0.20, 3, 2048, 2300, 1.4), (1.62, 3, 2300, 2048, 1.4),
    (0.60, 4, 2048, 1850, 1.0), (1.62, 4, 1850, 2048, 1.0),
    (0.20, 6, 2048, 2900, 1.2), (1.42, 6, 2900, 2048, 1.2),
]
MOTION_S = 3.5


def log(line: str) -> None:
    print(line, flush=True)


class Hand:
    """A hand turning the leader's limp horns on a thread: one `MOTION` per `play()`, or over and
    over while `continuous` is set."""

    def __init__(self, servos: lerobot_sim.SimServos):
        self.servos = servos
        self.cycles = 0
        self.continuous = threading.Event()
        self._pending = threading.Semaphore(0)
        self._stop = threading.Event()
        self._idle = threading.Event()
        self._idle.set()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def play(self) -> None:
        self._idle.clear()
        self._pending.release()

    def start_continuous(self) -> None:
        self._idle.clear()
        self.continuous.set()

    def _run(self) -> None:
        while not self._stop.is_set():
            if self.continuous.is_set() or self._pending.acquire(timeout=0.02):
                self._idle.clear()
                self._cycle()
            else:
                self._idle.set()

    def _cycle(self) -> None:
        start = time.monotonic()
        for at, sid, a, b, s in sorted(MOTION):
            while (left := start + at - time.monotonic()) > 0:
                if self._stop.wait(min(left, 0.05)):
                    return
            self.servos.hand(f"sweep {sid} {a} {b} {s}")
        while (left := start + MOTION_S - time.monotonic()) > 0:
            if self._stop.wait(min(left, 0.05)):
                return
        self.cycles += 1

    def wait_idle(self, timeout: float = 10.0) -> None:
        self.continuous.clear()
        self._idle.wait(timeout)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)

    def errors(self) -> list[str]:
        """The servos' `error:` replies to the hand's commands. A sweep followed by the next one
        before LeRobot has read the horn at its end is reported `cut short` (harmless: the horn
        got there); any other error means the hand could not turn the horn (torque on)."""
        return [line for line in self.servos._done_lines if line.startswith("error")]


class Tool:
    """A LeRobot command-line tool as a subprocess of its own session: stdin closed, stdout and
    stderr merged into a log, each line timed on arrival and passed to `on_line`."""

    def __init__(self, name: str, args: list[str], env: dict, log_path: Path, on_line=None):
        self.name = name
        self.log_path = log_path
        self.lines: list[tuple[float, str]] = []
        self.on_line = on_line
        self.started = time.monotonic()
        self.process = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, env=env, text=True, errors="replace",
                                        start_new_session=True)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        with open(self.log_path, "w") as out:
            for line in self.process.stdout:
                now = time.monotonic()
                line = line.rstrip("\n")
                self.lines.append((now, line))
                out.write(line + "\n")
                if self.on_line is not None:
                    try:
                        self.on_line(now, line)
                    except Exception as e:  # a callback's bug must not stop the log
                        out.write(f"[lerobot_ci: on_line failed: {e}]\n")

    def wait(self, timeout: float = TIMEOUT_S) -> int:
        try:
            rc = self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            rc = None
        self._reader.join(timeout=5)
        self.seconds = time.monotonic() - self.started
        return rc

    def kill(self) -> None:
        if self.process.poll() is not None:
            return
        for sig, grace in ((signal.SIGINT, 5.0), (signal.SIGKILL, 5.0)):
            try:
                os.killpg(self.process.pid, sig)
            except ProcessLookupError:
                return
            try:
                self.process.wait(timeout=grace)
                return
            except subprocess.TimeoutExpired:
                continue

    def first(self, pattern: str) -> float | None:
        rx = re.compile(pattern)
        return next((t for t, line in self.lines if rx.search(line)), None)

    def tail(self, n: int = 25) -> str:
        return "\n".join("    | " + line for _, line in self.lines[-n:])


class Follower:
    """Fresh simulated follower servos, calibrated with the follower's file, the monitor judging
    the calibrated arm, recording their positions."""

    def __init__(self, armctl: str, cal_file: Path, record: Path, period_ms: float | None = None,
                 servos: str | None = None):
        self.record = record
        self.servos = lerobot_sim.SimServos(armctl, calibration=cal_file, record=record, period_ms=period_ms,
                                            servos=servos)
        self.announced = time.monotonic()
        self.monitor: dict | None = None
        try:
            lerobot_sim.calibrate_bus(self.servos.port, cal_file.stem, cal_file.parent)
        except BaseException:
            self.stop()
            raise

    @property
    def port(self) -> str:
        return self.servos.port

    def stop(self) -> dict:
        if self.monitor is None:
            self.monitor = self.servos.stop()
        return self.monitor

    def positions_deg(self, cal: dict) -> tuple[np.ndarray, np.ndarray]:
        """The recording: times on this script's monotonic clock, and (n, 6) positions in LeRobot's
        units (body joints degrees about the middle of their range, the gripper 0-100)."""
        data = np.genfromtxt(self.record, delimiter=",", names=True)
        t = data["t"] + self.announced
        cols = []
        for i, name in enumerate(MOTORS):
            lo, hi = cal[name]["range_min"], cal[name]["range_max"]
            pos = data[f"pos_{i + 1}"]
            if name == "gripper":
                cols.append((pos - lo) / (hi - lo) * 100.0)
            else:
                cols.append((pos - (lo + hi) / 2.0) * 360.0 / 4095.0)
        return t, np.stack(cols, axis=1)


def tool_path(name: str) -> str:
    path = Path(sys.executable).parent / name
    if not path.is_file():
        raise RuntimeError(f"no {name} next to {sys.executable}: is LeRobot installed in this environment?")
    return str(path)


def robot_args(kind: str, port: str, cal_dir: Path, physical: bool = False) -> list[str]:
    if kind == "armctl_follower":
        # On physical servos the firmware compensates their sag (as smoothness.py asks).
        compensation = ["--robot.gravity_compensation=true"] if physical else []
        return ["--robot.type=armctl_follower", f"--robot.bus={port}", "--robot.protocol=sts",
                f"--robot.id={FOLLOWER_ID}", f"--robot.calibration_dir={cal_dir}", f"--robot.fps={FPS}",
                *compensation]
    return [f"--robot.type={kind}", f"--robot.port={port}", f"--robot.id={FOLLOWER_ID}",
            f"--robot.calibration_dir={cal_dir}"]


def teleop_args(port: str, cal_dir: Path) -> list[str]:
    return ["--teleop.type=so101_leader", f"--teleop.port={port}", f"--teleop.id={LEADER_ID}",
            f"--teleop.calibration_dir={cal_dir}"]


def read_dataset(root: Path) -> tuple[dict, "object"]:
    import pandas as pd

    info = json.loads((root / "meta" / "info.json").read_text())
    files = sorted((root / "data").rglob("*.parquet"))
    if not files:
        raise RuntimeError(f"no parquet files under {root / 'data'}")
    frames = pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)
    return info, frames


def tracking(t_rec: np.ndarray, pos: np.ndarray, t_first: float, actions: np.ndarray) -> dict:
    """The tracking of `actions` (due at t_first + i/FPS): the shift (ms, searched over
    SHIFT_SEARCH_MS) with the least RMS error over the body joints, and there per body joint the
    RMS and largest error (degrees), and the gripper's (0-100)."""
    due = t_first + np.arange(len(actions)) / FPS
    best = None
    for shift_ms in np.arange(SHIFT_SEARCH_MS[0], SHIFT_SEARCH_MS[1] + 1, 1.0):
        at = due + shift_ms * 1e-3
        p = np.stack([np.interp(at, t_rec, pos[:, j]) for j in range(len(MOTORS))], axis=1)
        err = p - actions
        total = float(np.sqrt(np.mean(err[:, : len(BODY)] ** 2)))
        if best is None or total < best[0]:
            best = (total, float(shift_ms), err)
    _, shift, err = best
    rms = np.sqrt(np.mean(err**2, axis=0))
    peak = np.max(np.abs(err), axis=0)
    n = len(BODY)
    return {"shift_ms": shift, "rms": rms[:n], "max": peak[:n], "worst_rms": float(rms[:n].max()),
            "worst_max": float(peak[:n].max()), "gripper_rms": float(rms[n]), "gripper_max": float(peak[n]),
            "err": err[:, :n]}


def joints_text(values: np.ndarray) -> str:
    return "/".join(f"{v:.2f}" for v in values)


class Checks:
    def __init__(self):
        self.results: list[tuple[str, bool]] = []

    def add(self, name: str, ok: bool) -> bool:
        self.results.append((name, bool(ok)))
        return bool(ok)

    @property
    def passed(self) -> bool:
        return bool(self.results) and all(ok for _, ok in self.results)


def verdict(ok: bool) -> str:
    return "ok" if ok else "FAILED"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--armctl", default=None, help="the armctl binary (default: target/release, else debug)")
    parser.add_argument("--keep", type=Path, default=None,
                        help="work in this folder and keep it (logs, recordings, dataset) instead of a temporary one")
    parser.add_argument("--servos", choices=("ideal", "physical"), default="ideal",
                        help="the followers' simulated servos: ideal, or physical ones that carry the arm")
    args = parser.parse_args()
    physical = args.servos == "physical"
    armctl_bin = str(Path(args.armctl).resolve()) if args.armctl else lerobot_sim.default_armctl()
    if not os.access(armctl_bin, os.X_OK):
        log(f"summary: no armctl binary at {armctl_bin} (cargo build -p armctl) -> FAILED")
        return 1
    began = time.monotonic()

    tmp_ctx = None
    if args.keep:
        work = args.keep.resolve()
        if work.exists():
            shutil.rmtree(work)
        work.mkdir(parents=True)
    else:
        tmp_ctx = tempfile.TemporaryDirectory(prefix="lerobot_ci_")
        work = Path(tmp_ctx.name)

    # LeRobot's and Hugging Face's folders inside the work folder, no network, no display: for the
    # tools and for this process's own use of LeRobot (calibrate_bus).
    env_over = {
        "HF_HOME": str(work / "hf"),
        "HF_LEROBOT_HOME": str(work / "lerobot"),
        "HF_LEROBOT_CALIBRATION": str(work / "calibration"),
        "HF_HUB_OFFLINE": "1",
        "HF_DATASETS_OFFLINE": "1",
        "HF_HUB_DISABLE_TELEMETRY": "1",
        "TRANSFORMERS_OFFLINE": "1",
        "WANDB_MODE": "disabled",
        "PYTHONUNBUFFERED": "1",
    }
    os.environ.update(env_over)
    os.environ.pop("DISPLAY", None)
    os.environ.pop("WAYLAND_DISPLAY", None)
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")

    checks = Checks()
    figures: dict = {}
    leader = None
    hand = None
    followers: list[Follower] = []
    tools: list[Tool] = []
    cal = lerobot_sim.so101_calibration()
    robot_cal_dir = work / "calibration" / "robots" / "follower"
    teleop_cal_dir = work / "calibration" / "teleoperators" / "so_leader"
    follower_cal = lerobot_sim.write_calibration_file(robot_cal_dir / f"{FOLLOWER_ID}.json", cal)
    leader_cal = lerobot_sim.write_calibration_file(teleop_cal_dir / f"{LEADER_ID}.json", cal)
    dataset_root = work / "dataset"

    def follower(name: str, period_ms: float | None = None) -> Follower:
        f = Follower(armctl_bin, follower_cal, work / f"{name}.csv", period_ms, args.servos)
        followers.append(f)
        return f

    def run(name: str, cmd: list[str], on_line=None) -> tuple[Tool, int | None]:
        tool = Tool(name, cmd, env, work / f"{name}.log", on_line)
        tools.append(tool)
        rc = tool.wait()
        if rc != 0:
            how = "timed out (stopped)" if rc is None else f"exited with {rc}"
            log(f"  {name} {how} after {tool.seconds:.1f} s; the end of its log ({tool.log_path}):")
            log(tool.tail())
        return tool, rc

    try:
        # ---- 1. setup -------------------------------------------------------------------------
        t0 = time.monotonic()
        leader = lerobot_sim.SimServos(armctl_bin)
        lerobot_sim.calibrate_bus(leader.port, LEADER_ID, teleop_cal_dir)
        hand = Hand(leader)
        for name in ("lerobot-teleoperate", "lerobot-record", "lerobot-replay"):
            tool_path(name)
        checks.add("setup", True)
        log(f"setup: leader servos on {leader.port} calibrated from {leader_cal.name}, follower file "
            f"{follower_cal.name} (ticks 1048-3048 body, gripper 1900-3100), LeRobot's tools in "
            f"{Path(sys.executable).parent}, work in {work} ({time.monotonic() - t0:.1f} s)")

        # ---- 2. teleoperate ---------------------------------------------------------------------
        f = follower("teleoperate")
        cmd = [tool_path("lerobot-teleoperate"), *robot_args("armctl_follower", f.port, robot_cal_dir, physical),
               *teleop_args(leader.port, teleop_cal_dir), f"--fps={FPS}", f"--teleop_time_s={TELEOP_S}",
               "--display_data=false"]
        hand.start_continuous()
        tool, rc = run("teleoperate", cmd)
        hand.wait_idle()
        time.sleep(0.2)
        mon = f.stop()
        hz = [float(m.group(1)) for _, line in tool.lines if (m := re.search(r"\((\d+) Hz\)", line))]
        start_s = (tool.first(r"Teleop loop time") or tool.started) - tool.started
        moved = 0.0
        if f.record.is_file() and f.record.stat().st_size > 0:
            _, p = f.positions_deg(cal)
            moved = float(p[:, 0].max() - p[:, 0].min())
        ok = rc == 0 and moved >= MOVED_DEG and mon["violations"] == 0
        checks.add("teleoperate", ok)
        figures["teleoperate"] = {"seconds": tool.seconds, "hz_median": float(np.median(hz)) if hz else None,
                                  "moved_deg": moved, "goals": mon["goals"], "violations": mon["violations"]}
        log(f"teleoperate: lerobot-teleoperate armctl_follower <- so101_leader {TELEOP_S} s: exit {rc} in "
            f"{tool.seconds:.1f} s ({start_s:.1f} s to the first loop), loop "
            f"{np.median(hz) if hz else float('nan'):.0f} Hz median over {len(hz)}, "
            f"follower's shoulder_pan travelled {moved:.1f} deg (>= {MOVED_DEG:.0f}), monitor {mon['goals']} goals "
            f"{mon['violations']} violations -> {verdict(ok)}")
        for v in mon["first_violations"]:
            log(f"  {v}")

        # ---- 3. record --------------------------------------------------------------------------
        f = follower("record")
        cmd = [tool_path("lerobot-record"), *robot_args("armctl_follower", f.port, robot_cal_dir, physical),
               *teleop_args(leader.port, teleop_cal_dir),
               f"--dataset.repo_id={REPO_ID}", f"--dataset.root={dataset_root}",
               f"--dataset.num_episodes={EPISODES}", f"--dataset.episode_time_s={EPISODE_S}",
               f"--dataset.reset_time_s={RESET_S}", f"--dataset.fps={FPS}",
               "--dataset.single_task=Follow the scripted leader", "--dataset.video=false",
               "--dataset.push_to_hub=false", "--display_data=false", "--play_sounds=false"]

        def on_record(_, line: str) -> None:
            if "Recording episode" in line:
                hand.play()

        tool, rc = run("record", cmd, on_record)
        hand.wait_idle()
        mon = f.stop()
        slow = sum(1 for _, line in tool.lines if "running slower" in line)
        start_s = (tool.first(r"Recording episode") or tool.started) - tool.started
        problems = []
        episodes = {}
        info = frames = None
        if rc == 0:
            try:
                info, frames = read_dataset(dataset_root)
                if info.get("total_episodes") != EPISODES:
                    problems.append(f"total_episodes {info.get('total_episodes')}")
                for key in ("action", "observation.state"):
                    names = info["features"].get(key, {}).get("names")
                    if names != NAMES:
                        problems.append(f"{key} names {names}")
                for e, ep in frames.groupby("episode_index"):
                    act = np.stack(ep.sort_values("frame_index")["action"].to_numpy())
                    obs = np.stack(ep.sort_values("frame_index")["observation.state"].to_numpy())
                    if act.shape[1] != len(NAMES) or obs.shape[1] != len(NAMES):
                        problems.append(f"episode {e}: action {act.shape}, observation.state {obs.shape}")
                    episodes[int(e)] = {"frames": len(ep), "pan_travel": float(np.ptp(act[:, 0])),
                                        "obs_pan_travel": float(np.ptp(obs[:, 0]))}
                    if np.ptp(act[:, 0]) < MOVED_DEG or np.ptp(obs[:, 0]) < MOVED_DEG:
                        problems.append(f"episode {e} holds no motion (shoulder_pan action travel "
                                        f"{np.ptp(act[:, 0]):.1f}, observed {np.ptp(obs[:, 0]):.1f} deg)")
                if sorted(episodes) != list(range(EPISODES)):
                    problems.append(f"episodes in the data: {sorted(episodes)}")
            except Exception as e:
                problems.append(f"the dataset: {e!r}")
        ok = rc == 0 and not problems and mon["violations"] == 0
        checks.add("record", ok)
        figures["record"] = {"seconds": tool.seconds, "episodes": episodes, "goals": mon["goals"],
                             "violations": mon["violations"], "slow_loop_warnings": slow}
        ep_text = ", ".join(f"ep{e} {v['frames']} frames pan {v['pan_travel']:.0f}/{v['obs_pan_travel']:.0f} deg"
                            for e, v in sorted(episodes.items()))
        log(f"record: lerobot-record {EPISODES} x {EPISODE_S} s armctl_follower <- so101_leader: exit {rc} in "
            f"{tool.seconds:.1f} s ({start_s:.1f} s to the first episode), {ep_text or 'no episodes'} "
            f"(action/observed travel), action and "
            f"observation.state named as so101_follower's: "
            f"{'?' if info is None else 'NO' if any('names' in p for p in problems) else 'yes'}, "
            f"{slow} slow-loop warnings, monitor {mon['goals']} goals {mon['violations']} violations -> {verdict(ok)}")
        for p in problems:
            log(f"  {p}")
        for v in mon["first_violations"]:
            log(f"  {v}")

        # ---- 4./5. replay -----------------------------------------------------------------------
        if frames is None or 0 not in episodes:
            checks.add("replay armctl_follower", False)
            checks.add("replay so101_follower", False)
            log("replay: skipped, no dataset from record")
        else:
            ep0 = frames[frames["episode_index"] == 0].sort_values("frame_index")
            actions = np.stack(ep0["action"].to_numpy()).astype(np.float64)
            for kind, bound, strict in (("armctl_follower", ARMCTL_RMS_BOUND_DEG, True),
                                        ("so101_follower", SO101_RMS_BOUND_DEG, False)):
                # so101_follower writes each action as the goals, once a frame: the monitor judges
                # its steps over a frame; armctl's core steps them at its own 10 ms.
                f = follower(f"replay_{kind}", 1000.0 / FPS if kind == "so101_follower" else None)
                cmd = [tool_path("lerobot-replay"), *robot_args(kind, f.port, robot_cal_dir, physical),
                       f"--dataset.repo_id={REPO_ID}", f"--dataset.root={dataset_root}", "--dataset.episode=0",
                       "--play_sounds=false"]
                tool, rc = run(f"replay_{kind}", cmd)
                time.sleep(0.3)
                mon = f.stop()
                t_first = tool.first(r"Replaying episode")
                tr = None
                final = None
                if rc == 0 and t_first is not None:
                    t_rec, pos = f.positions_deg(cal)
                    tr = tracking(t_rec, pos, t_first, actions)
                    if args.keep:
                        # Per action: its time from the first, the action and the error at the best shift.
                        cols = np.column_stack([np.arange(len(actions)) / FPS, actions[:, : len(BODY)], tr["err"]])
                        header = ",".join(["t", *[f"action_{m}" for m in BODY], *[f"err_{m}" for m in BODY]])
                        np.savetxt(work / f"replay_{kind}_errors.csv", cols, delimiter=",", header=header,
                                   comments="", fmt="%.4f")
                    rest = pos[t_rec >= t_rec[-1] - 0.2]
                    final = np.abs(rest.mean(axis=0) - actions[-1])
                ok = (rc == 0 and tr is not None and tr["worst_rms"] <= bound
                      and float(final[: len(BODY)].max()) <= FINAL_BOUND_DEG
                      and (mon["violations"] == 0 or not strict))
                checks.add(f"replay {kind}", ok)
                figures[f"replay_{kind}"] = {
                    "seconds": tool.seconds, "goals": mon["goals"], "violations": mon["violations"],
                    **({"shift_ms": tr["shift_ms"], "rms_deg": tr["rms"].tolist(), "max_deg": tr["max"].tolist(),
                        "final_deg": final.tolist(), "gripper_rms": tr["gripper_rms"],
                        "gripper_max": tr["gripper_max"]} if tr else {})}
                if tr is None:
                    log(f"replay {kind}: exit {rc} in {tool.seconds:.1f} s, "
                        f"{'no tracking figures' if rc == 0 else 'failed'} -> FAILED")
                    continue
                viol = (f"{mon['violations']} violations" + ("" if strict else " (reported only)"))
                log(f"replay {kind}: lerobot-replay episode 0 ({len(actions)} actions): exit {rc} in "
                    f"{tool.seconds:.1f} s ({t_first - tool.started:.1f} s to the first action), best shift "
                    f"{tr['shift_ms']:.0f} ms, RMS error per body joint "
                    f"{joints_text(tr['rms'])} deg (worst {tr['worst_rms']:.2f} <= {bound}), max "
                    f"{joints_text(tr['max'])} deg, final {float(final[:len(BODY)].max()):.2f} deg "
                    f"(<= {FINAL_BOUND_DEG}), gripper RMS {tr['gripper_rms']:.2f} max {tr['gripper_max']:.2f} final "
                    f"{final[-1]:.2f} (0-100), monitor {mon['goals']} goals {viol} "
                    f"-> {verdict(ok)}")
                for v in mon["first_violations"][: 5 if strict else 2]:
                    log(f"  {v}")

        refused = [e for e in hand.errors() if "cut short" not in e]
        if refused:
            log(f"  the hand's commands were refused {len(refused)} times: {refused[:3]}")
    except Exception as e:
        checks.add(f"error: {e!r}", False)
        log(f"error: {e!r}")
    finally:
        if hand is not None:
            hand.stop()
        for tool in tools:
            tool.kill()
        for f in followers:
            f.stop()
        if leader is not None:
            leader.stop()
        if args.keep:
            (work / "figures.json").write_text(json.dumps(figures, indent=1, default=float))
        if tmp_ctx is not None:
            tmp_ctx.cleanup()

    failed = [name for name, ok in checks.results if not ok]
    log(f"summary: {len(checks.results) - len(failed)}/{len(checks.results)} checks passed"
        f"{' (failed: ' + ', '.join(failed) + ')' if failed else ''} in {time.monotonic() - began:.0f} s"
        f"{'; kept ' + str(work) if args.keep else ''}")
    return 0 if checks.passed else 1


if __name__ == "__main__":
    sys.exit(main())
