"""armctl_follower as LeRobot sees it: found by LeRobot's plugin mechanism, the features of
so101_follower, actions streamed as keyframes (clamped, and said so), the end effector, the
calibration check against simulated servos written by LeRobot's own code."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

import armctl
from conftest import need_lerobot

need_lerobot()

from lerobot.robots.config import RobotConfig  # noqa: E402
from lerobot.robots.utils import make_robot_from_config  # noqa: E402
from lerobot.utils.import_utils import register_third_party_plugins  # noqa: E402

import lerobot_sim  # noqa: E402


def config(**kw):
    register_third_party_plugins()
    return RobotConfig.get_choice_class("armctl_follower")(**kw)


def test_found_by_lerobots_plugin_mechanism_with_so101_followers_features(tmp_path):
    robot = make_robot_from_config(config(id="t", sim=True, calibration_dir=tmp_path))
    assert type(robot).__name__ == "ArmctlFollower"
    from lerobot.robots.so_follower import SO101Follower, SO101FollowerConfig

    so101 = SO101Follower(SO101FollowerConfig(port="/dev/null", id="t", calibration_dir=tmp_path))
    assert robot.action_features == so101.action_features
    assert robot.observation_features == so101.observation_features


def test_where_the_arm_is_must_be_said_once():
    with pytest.raises(ValueError, match="exactly one of sim, port and bus"):
        config(id="t")
    with pytest.raises(ValueError, match="exactly one"):
        config(id="t", sim=True, port="/dev/x")
    with pytest.raises(ValueError, match="protocol"):
        config(id="t", bus="/dev/x")


def test_actions_become_keyframes_and_come_back_as_sent(tmp_path):
    robot = make_robot_from_config(config(id="t", sim=True, calibration_dir=tmp_path, fps=30))
    robot.connect()
    try:
        obs = robot.get_observation()
        assert set(obs) == set(robot.observation_features)
        sent = None
        for i in range(45):
            action = {k: 0.0 for k in robot.action_features}
            action["shoulder_pan.pos"] = 15.0 * np.sin(np.pi * i / 45)
            action["gripper.pos"] = 60.0
            sent = robot.send_action(action)
            assert abs(sent["shoulder_pan.pos"] - action["shoulder_pan.pos"]) < 1e-4
            time.sleep(1 / 30)
        # Beyond the joint's range: clamped, and the action returned says what was sent.
        jump = dict(sent, **{"elbow_flex.pos": 500.0})
        back = robot.send_action(jump)
        assert back["elbow_flex.pos"] < 500.0
        with pytest.raises(armctl.ArmctlError, match="does not take"):
            robot.send_action(dict(sent, **{"elbow.pos": 1.0}))
        with pytest.raises(armctl.ArmctlError, match="has no wrist_roll.pos"):
            robot.send_action({k: v for k, v in sent.items() if k != "wrist_roll.pos"})
        time.sleep(0.5)
        obs = robot.get_observation()
        assert abs(obs["gripper.pos"] - 60.0) < 3.0
        monitor = robot._arm.monitor()
        assert monitor["violations"] == 0, monitor
    finally:
        robot.disconnect()
    assert not robot.is_connected


@pytest.mark.parametrize("arm", ["so101", "open-manipulator-x"])
def test_a_stream_of_actions_that_stops_ends_on_the_last_action(tmp_path, arm):
    """Ramps at 30, 60 and 90 deg/s through every joint, then no more actions (a policy ending): the
    arm brakes past the last action within its limits and comes back to it, as so101_follower ends
    on its last goal. Goal: within 0.1 deg of the last action within 1 s of it."""
    robot = make_robot_from_config(config(id="t", sim=True, arm=arm, calibration_dir=tmp_path, fps=30))
    robot.connect()
    rng = np.random.default_rng(7)
    try:
        keys = [k for k in robot.action_features if k.endswith(".pos") and not k.startswith("gripper")]
        for speed in (30.0, 60.0, 90.0):
            # Each ramp from the arm's zero (both arms straight out) and up, every joint's angle
            # falling: room for the ramp and the brake, clear of the table, which any ramp down
            # from there reaches (the firmware then stops the arm short of it, rightly).
            if robot._stream is not None and robot._stream.open:
                robot._stream.close()
            robot._arm.move_joints([0.0] * len(keys))
            start = robot.get_observation()
            action = {k: float(start[k]) for k in robot.action_features}
            direction = {k: -1.0 for k in keys}
            scale = {k: rng.uniform(0.3, 1.0) for k in keys}
            scale[keys[int(rng.integers(len(keys)))]] = 1.0
            sent = None
            for i in range(1, 19):
                for k in keys:
                    action[k] = float(start[k]) + direction[k] * scale[k] * speed * i / 30
                sent = robot.send_action(dict(action))
                last_at = time.monotonic()
                time.sleep(1 / 30)
            settled, error = None, None
            while time.monotonic() - last_at < 1.5:
                obs = robot.get_observation()
                error = max(abs(obs[k] - sent[k]) for k in keys)
                if error < 0.1:
                    settled = settled or time.monotonic() - last_at
                else:
                    settled = None
                time.sleep(0.02)
            assert settled is not None and settled <= 1.0, f"{arm} {speed} deg/s: {error:.3f} deg off, settled {settled}; {robot._arm.status().get('last_collision')} {sent}"
            status = robot._arm.status()
            assert np.degrees(status["largest_pass"]) > 0.5, status["largest_pass"]
        monitor = robot._arm.monitor()
        assert monitor["violations"] == 0, monitor
    finally:
        robot.disconnect()


def test_end_effector_actions_are_solved_by_the_core(tmp_path):
    robot = make_robot_from_config(config(id="t", sim=True, calibration_dir=tmp_path, action_space="ee"))
    robot.connect()
    try:
        assert set(robot.action_features) == {"ee.x", "ee.y", "ee.z", "ee.wx", "ee.wy", "ee.wz", "ee.gripper_pos"}
        # A path of poses an SO-101 can take (it has five joints: not every pose is one), as a
        # leader arm's end effector gives them.
        model = armctl.Model("so101")
        from lerobot_robot_armctl.rotation import matrix_to_rotvec

        q_end = np.array([0.2, 0.3, -0.6, 0.4, 0.1])
        for i in range(1, 61):
            pose = model.fk(q_end * i / 60)
            p, w = pose[:3, 3], matrix_to_rotvec(pose[:3, :3])
            robot.send_action({"ee.x": p[0], "ee.y": p[1], "ee.z": p[2], "ee.wx": w[0], "ee.wy": w[1],
                               "ee.wz": w[2], "ee.gripper_pos": 50.0})
            time.sleep(1 / 30)
        time.sleep(1.0)
        obs = robot.get_observation()
        np.testing.assert_allclose([obs["ee.x"], obs["ee.y"], obs["ee.z"]], model.fk(q_end)[:3, 3], atol=3e-3)
        np.testing.assert_allclose([obs["ee.wx"], obs["ee.wy"], obs["ee.wz"]], matrix_to_rotvec(model.fk(q_end)[:3, :3]),
                                   atol=1e-2)
    finally:
        robot.disconnect()


def test_end_effector_steps_sideways_with_the_orientation_held_are_taken(tmp_path):
    """As a gamepad or a phone sends them (issue 43, item 2): position steps from where the tool
    is, the orientation held as the observation gave it. The SO-101's yaw follows its pan; its
    tilt is held."""
    robot = make_robot_from_config(config(id="t", sim=True, calibration_dir=tmp_path, action_space="ee"))
    robot.connect()
    try:
        from lerobot_robot_armctl.rotation import matrix_to_rotvec

        model = armctl.Model("so101")
        bent = model.fk(np.array([-0.4, 0.5, -0.9, 0.6, -0.3]))
        p, w = bent[:3, 3], matrix_to_rotvec(bent[:3, :3])
        for _ in range(30):  # to the bent start, as a path of one pose
            robot.send_action({"ee.x": p[0], "ee.y": p[1], "ee.z": p[2], "ee.wx": w[0], "ee.wy": w[1],
                               "ee.wz": w[2], "ee.gripper_pos": 50.0})
            time.sleep(1 / 30)
        time.sleep(1.0)
        obs = robot.get_observation()
        start = np.array([obs["ee.x"], obs["ee.y"], obs["ee.z"]])
        held = {k: obs[k] for k in ("ee.wx", "ee.wy", "ee.wz")}
        side = np.cross([0.0, 0.0, 1.0], start)
        side /= np.linalg.norm(side)
        for i in range(1, 61):
            x = start + side * 0.05 * i / 60
            robot.send_action({"ee.x": x[0], "ee.y": x[1], "ee.z": x[2], **held, "ee.gripper_pos": 50.0})
            time.sleep(1 / 30)
        time.sleep(1.0)
        obs = robot.get_observation()
        np.testing.assert_allclose([obs["ee.x"], obs["ee.y"], obs["ee.z"]], start + side * 0.05, atol=3e-3)
    finally:
        robot.disconnect()


def test_the_servos_must_hold_the_calibration_the_gripper_too(tmp_path, armctl_bin):
    cal = lerobot_sim.so101_calibration()
    path = lerobot_sim.write_calibration_file(tmp_path / "f.json", cal)
    with lerobot_sim.SimServos(armctl_bin) as servos:
        cfg = dict(id="f", bus=servos.port, protocol="sts", calibration_dir=tmp_path)
        # No file for another id: not calibrated, and connecting without calibrating refuses.
        other = make_robot_from_config(config(**dict(cfg, id="other")))
        assert not other.is_calibrated
        with pytest.raises(armctl.ArmctlError, match="calibrate first"):
            other.connect(calibrate=False)
        # The file, but servos that do not hold it yet: refused, naming a servo.
        robot = make_robot_from_config(config(**cfg))
        assert robot.is_calibrated
        with pytest.raises(armctl.ArmctlError, match="calibration"):
            robot.connect(calibrate=False)
        # Written by LeRobot's own code, all but the gripper's: refused, naming the gripper.
        wrong = json.loads(path.read_text())
        wrong["gripper"]["range_max"] = 3050
        lerobot_sim.write_calibration_file(tmp_path / "g.json", wrong)
        lerobot_sim.calibrate_bus(servos.port, "g", tmp_path)
        with pytest.raises(armctl.ArmctlError, match="gripper"):
            robot.connect(calibrate=False)
        # Then the file's own values: accepted.
        lerobot_sim.calibrate_bus(servos.port, "f", tmp_path)
        robot.connect(calibrate=False)
        try:
            obs = robot.get_observation()
            assert abs(obs["shoulder_pan.pos"]) < 0.1  # the servo's middle, tick 2048
        finally:
            robot.disconnect()


CALIBRATE_CHILD = """
import sys
from lerobot.utils.import_utils import register_third_party_plugins
register_third_party_plugins()
from lerobot.robots.config import RobotConfig
from lerobot.robots.utils import make_robot_from_config
from pathlib import Path
cfg = RobotConfig.get_choice_class("armctl_follower")(id="c", bus=sys.argv[1], protocol="sts", calibration_dir=Path(sys.argv[2]))
robot = make_robot_from_config(cfg)
robot.calibrate()
robot.connect(calibrate=False)
print("connected", robot.get_observation()["shoulder_pan.pos"], flush=True)
robot.disconnect()
"""


def test_calibrate_runs_armctls_procedure_and_writes_lerobots_file(tmp_path, armctl_bin):
    """`calibrate` through LeRobot's robot: the two steps answered on stdin, the hand moving the
    horns in between; LeRobot's file written, the servos holding it, and connecting accepting it."""
    import subprocess
    import sys

    with lerobot_sim.SimServos(armctl_bin) as servos:
        child = subprocess.Popen([sys.executable, "-c", CALIBRATE_CHILD, servos.port, str(tmp_path)],
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        seen = []

        def until(text):
            for line in child.stdout:
                seen.append(line)
                if text in line:
                    return
            raise AssertionError(f"no {text!r} in {seen} {child.stderr.read()}")

        def hand(commands):
            before = len(servos._done_lines)
            for c in commands:
                servos.hand(c)
            deadline = time.monotonic() + 10
            while len(servos._done_lines) < before + len(commands):
                assert time.monotonic() < deadline, servos._done_lines
                time.sleep(0.01)
            assert all(l.startswith("done") for l in servos._done_lines[before:]), servos._done_lines

        try:
            until("step 1 of 2")
            child.stdin.write("\n")
            child.stdin.flush()
            until("step 2 of 2")
            swept = [1, 2, 3, 4, 6]  # the wrist roll gets the whole turn, as in LeRobot
            for a, b, s in [(2048, 1500, 0.25), (1500, 1500, 0.1), (1500, 2600, 0.25), (2600, 2600, 0.1),
                            (2600, 2048, 0.25)]:
                hand([f"sweep {i} {a} {b} {s}" for i in swept])
            child.stdin.write("\n")
            child.stdin.flush()
            out, err = child.communicate(timeout=60)
        finally:
            if child.poll() is None:
                child.kill()
        assert child.returncode == 0, (seen, out, err)
        cal = json.loads((tmp_path / "c.json").read_text())
        assert list(cal) == lerobot_sim.SO101_MOTORS
        for name in ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "gripper"):
            # Homed at the middle (2048 reads 2047), so the stops read one tick lower.
            assert (cal[name]["homing_offset"], cal[name]["range_min"], cal[name]["range_max"]) == (1, 1499, 2599), cal
        assert (cal["wrist_roll"]["range_min"], cal["wrist_roll"]["range_max"]) == (0, 4095)
        assert (tmp_path / "c.toml").is_file()
        assert "connected" in out, out
