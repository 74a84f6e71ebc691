"""Simulated SO-101 servo buses for LeRobot's own code and for armctl_follower: `armctl sim servos`
on a pseudo-terminal, calibrated the way LeRobot calibrates (its `write_calibration` writes the
file's homing offsets and limits into the servos), with the safety monitor judging the calibrated
mapping and, if asked, the servos' positions recorded every 2 ms.

Used by the smoothness benchmark (smoothness.py), the LeRobot runs of CI (lerobot_ci.py) and the
Python package's tests. Needs the `armctl` binary (`--armctl`, default target/debug/armctl) and,
for `calibrate_bus`, LeRobot.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import threading
from pathlib import Path

SO101_MOTORS = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]


def so101_calibration(half_range: int = 1000) -> dict[str, dict[str, int]]:
    """A LeRobot calibration of an SO-101 as `lerobot-calibrate` writes it, with every body joint's
    range centred on the servo's middle (2048), so that 0 degrees is where a fresh simulated servo
    stands: homing offset 0, `half_range` ticks each side; the wrist roll the whole turn; the
    gripper 1900 (closed) to 3100 (open)."""
    cal = {}
    for i, name in enumerate(SO101_MOTORS, start=1):
        if name == "wrist_roll":
            lo, hi = 0, 4095
        elif name == "gripper":
            lo, hi = 1900, 3100
        else:
            lo, hi = 2048 - half_range, 2048 + half_range
        cal[name] = {"id": i, "drive_mode": 0, "homing_offset": 0, "range_min": lo, "range_max": hi}
    return cal


def write_calibration_file(path: Path, cal: dict) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(cal, indent=4))
    return path


class SimServos:
    """`armctl sim servos --pty --arm so101` in a process of its own: `port` is its pty."""

    def __init__(self, armctl: str, calibration: Path | None = None, record: Path | None = None,
                 burst_ms: float | None = 1.0, arm: str = "so101", period_ms: float | None = None,
                 servos: str | None = None):
        """`period_ms`: the control period of whatever drives the servos, which the safety monitor
        judges each goal step over (a tick is a read of the positions followed by goal writes):
        the firmware core's 10 ms by default; LeRobot's so101_follower reads and writes once a
        frame, 1000 / fps. `servos`: `ideal` (the default) or `physical` (docs/servo-model.md)."""
        args = [armctl, "sim", "servos", "--pty", "--arm", arm]
        if servos is not None:
            args += ["--servos", servos]
        if period_ms is not None:
            args += ["--period-ms", f"{period_ms:.3f}"]
        if calibration is not None:
            args += ["--calibration", str(calibration)]
        if record is not None:
            args += ["--record", str(record)]
        if burst_ms is not None:
            args += ["--burst-ms", str(burst_ms)]
        self.process = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                        stderr=subprocess.PIPE, text=True)
        line = self.process.stdout.readline().strip()
        if not line.startswith("/dev/"):
            err = self.process.stderr.read()
            raise RuntimeError(f"armctl sim servos did not start: {line!r} {err.strip()}")
        self.port = line
        self._err: list[str] = []
        self._reader = threading.Thread(target=self._read_err, daemon=True)
        self._reader.start()
        self._done_lines: list[str] = []
        self._out_reader = threading.Thread(target=self._read_out, daemon=True)
        self._out_reader.start()

    def _read_err(self):
        for line in self.process.stderr:
            self._err.append(line.rstrip("\n"))

    def _read_out(self):
        for line in self.process.stdout:
            self._done_lines.append(line.rstrip("\n"))

    def hand(self, command: str) -> None:
        """A hand's command on stdin (`move ID TICKS`, `sweep ID FROM TO SECONDS`); not waited for."""
        self.process.stdin.write(command + "\n")
        self.process.stdin.flush()

    def stop(self) -> dict:
        """Stops the servos (SIGINT: the recording is flushed) and says what the monitor found."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self._reader.join(timeout=2)
        violations = [l for l in self._err if l.startswith("violation:")]
        summary = next((l for l in self._err if l.startswith("safety monitor:")), None)
        goals = None
        if summary:
            goals = int(summary.split(":", 1)[1].split()[0])
        count = len(violations)
        if any(l.startswith("more than") for l in self._err) and summary:
            count = int(summary.split("checked,")[1].split()[0])
        return {"goals": goals, "violations": count, "first_violations": violations[:5], "stderr": self._err}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


def calibrate_bus(port: str, robot_id: str, calibration_dir: Path) -> None:
    """Writes the calibration file of `robot_id` in `calibration_dir` into the servos on `port`
    with LeRobot's own code (what `lerobot-calibrate` does last), so that LeRobot's
    `is_calibrated` and armctl's calibration check both accept the servos."""
    from lerobot.robots.so_follower import SO101Follower, SO101FollowerConfig

    robot = SO101Follower(SO101FollowerConfig(port=port, id=robot_id, calibration_dir=calibration_dir))
    robot.bus.connect()
    try:
        robot.bus.write_calibration(robot.calibration)
        if not robot.bus.is_calibrated:
            raise RuntimeError(f"the servos on {port} do not hold the calibration just written")
    finally:
        robot.bus.disconnect(True)


def default_armctl() -> str:
    here = Path(__file__).resolve().parents[2]
    for candidate in (os.environ.get("ARMCTL"), here / "target/release/armctl", here / "target/debug/armctl"):
        if candidate and Path(candidate).is_file():
            return str(candidate)
    raise RuntimeError("no armctl binary: build it (cargo build --release -p armctl) or set ARMCTL")
