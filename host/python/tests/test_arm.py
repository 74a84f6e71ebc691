"""The package's Arm, driven as the drive commands drive it: against the simulated arm (the core
on this PC in real time, with the safety monitor) and against `armctl serve --sim` through a port,
every call, the stream, and bad input raising the command line's own message."""

from __future__ import annotations

import subprocess
import time

import numpy as np
import pytest

import armctl


@pytest.fixture(scope="module")
def arm():
    a = armctl.Arm(sim="so101")
    yield a
    a.close()


def test_status_says_where_the_arm_is(arm):
    s = arm.status()
    assert s["arm"] == "so101"
    assert len(s["measured"]) == 5 and len(s["tool"]) == 3
    assert arm.joint_names[0] == "shoulder_pan" and arm.dof == 5 and arm.has_gripper
    assert arm.servo_ids == [1, 2, 3, 4, 5, 6]
    assert arm.sim_port.startswith("/dev/")


def test_move_to_arrives_and_says_how(arm):
    r = arm.move_to([0.2, 0.05, 0.15], speed=0.2)
    assert r["command"] == "move" and r["path"] in ("line", "joint", "line, then joints")
    assert r["error_mm"] < 1.0
    tool = np.array(arm.status()["tool"])
    assert np.linalg.norm(tool - [0.2, 0.05, 0.15]) < 1e-3


def test_move_joints_and_the_gripper_and_torque(arm):
    q = [0.2, 0.1, -0.3, 0.2, 0.1]
    r = arm.move_joints(q, duration=1.0)
    assert r["max_error"] < 2e-3
    np.testing.assert_allclose(arm.joints(), q, atol=2e-3)
    g = arm.gripper(30)
    assert abs(g["opening"] - 30) < 2
    assert arm.gripper("open")["opening"] > 95
    assert arm.torque(False)["state"] == "TorqueOff"
    assert arm.torque(True)["state"] in ("Idle", "Hold")
    assert arm.stop()["command"] == "stop"


def test_a_stream_plays_timed_keyframes_within_the_limits(arm):
    arm.move_joints([0, 0, 0, 0, 0], duration=1.0)
    lim = arm.limits
    with arm.stream(rate=50) as s:
        for i in range(50):
            q = np.array([0.3, 0.2, -0.2, 0.1, 0.0]) * np.sin(np.pi * i / 50)
            t, sent, g = s.send(q, gripper=40.0)
            np.testing.assert_allclose(sent, q, atol=1e-9)
            assert g == 40.0
            time.sleep(0.02)
        # A reading beyond a joint's range is clamped to it, and to one step (the speed limit,
        # 2 rad/s, over a period) from the last keyframe.
        last = sent[0]
        t, sent, g = s.send([5.0, 0, 0, 0, 0])
        assert sent[0] < lim[0, 1] and abs(sent[0] - (last + 2.0 / 50)) < 1e-6
        # Bad readings change nothing and the stream goes on.
        with pytest.raises(armctl.ArmctlError, match="nothing was sent"):
            s.send([0.0, 0.0])
        with pytest.raises(armctl.ArmctlError, match="nothing was sent"):
            s.send([np.nan, 0, 0, 0, 0])
        with pytest.raises(armctl.ArmctlError, match="a stream is open"):
            arm.move_joints([0, 0, 0, 0, 0])
        s.send([0, 0, 0, 0, 0])
    f = s.figures
    assert f["keyframes"] == 52 and f["limited_values"] >= 1
    monitor = arm.monitor()
    assert monitor["goals"] > 0 and monitor["violations"] == 0, monitor


def test_a_pose_stream_is_solved_by_the_firmware(arm):
    arm.move_joints([0, 0.3, -0.6, 0.3, 0], duration=1.0)
    start = np.array(arm.status()["tool"])
    with arm.stream(rate=30) as s:
        with pytest.raises(armctl.ArmctlError, match="a stream is open already"):
            arm.stream(rate=30)
        for i in range(31):
            s.send_pose(start + [0.0, 0.03 * i / 30, 0.0], gripper=50.0)
            time.sleep(1 / 30)
            if i == 15:
                # A pose beyond reach is refused by the firmware; nothing changes, the stream goes on.
                with pytest.raises(armctl.ArmctlError, match="unreachable"):
                    s.send_pose([0.9, 0.0, 0.2])
                assert s.open
    assert s.figures["keyframes"] == 31, s.figures
    time.sleep(0.3)
    np.testing.assert_allclose(arm.status()["tool"], start + [0, 0.03, 0], atol=2e-3)


def _quaternion_wxyz(r):
    """The unit quaternion (w first) of the rotation matrix `r`."""
    w = np.sqrt(max(0.0, 1 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    return [w, x, y, z]


def test_sideways_pose_steps_with_the_orientation_held_move_a_five_joint_arm(arm):
    """Issue 43, item 2: from a bent start, 46 small steps sideways (across the arm's reach, so
    the pan turns) with the start's orientation sent each time. A five-joint arm cannot hold the
    full orientation while its pan turns; the firmware holds the tilt and lets the yaw follow the
    pan, so every step is taken (before, 45 of 46 were refused as unreachable)."""
    arm.move_joints([0.3, 0.4, -0.8, 0.5, 0.2], duration=1.0)
    model = armctl.Model("so101")
    pose = model.fk(arm.status()["measured"])
    start, quaternion = pose[:3, 3], _quaternion_wxyz(pose[:3, :3])
    side = np.cross([0.0, 0.0, 1.0], start)
    side /= np.linalg.norm(side)
    with arm.stream(rate=30) as s:
        for i in range(1, 47):
            s.send_pose(start + side * 0.04 * i / 46, quaternion)
            time.sleep(1 / 30)
    assert s.figures["keyframes"] == 46, s.figures
    time.sleep(0.5)
    reached = model.fk(arm.status()["measured"])
    np.testing.assert_allclose(reached[:3, 3], start + side * 0.04, atol=2e-3)
    # Tilted as at the start: the base's z seen from the tool (the rotation's last row) is the same.
    np.testing.assert_allclose(reached[2, :3], pose[2, :3], atol=1e-2)


@pytest.mark.parametrize(
    "call, cli_args",
    [
        (lambda a: a.move_to([float("nan"), 0.0, 0.2]), ["move", "--to", "NaN,0.0,0.2"]),
        (lambda a: a.move_to([3.0, 0.0, 0.2]), ["move", "--to", "3.0,0.0,0.2"]),
        (lambda a: a.move_to([0.2, 0.0, 0.2], [1.0, 1.0, 0.0, 0.0]), ["move", "--to", "0.2,0.0,0.2", "--quat", "1.0,1.0,0.0,0.0"]),
        (lambda a: a.move_joints([5.0, 0, 0, 0, 0]), ["joints", "--q", "5.0,0,0,0,0"]),
        (lambda a: a.move_joints([0.0, 0.0]), ["joints", "--q", "0.0,0.0"]),
        (lambda a: a.gripper(150.0), ["gripper", "set", "150"]),
    ],
)
def test_bad_input_raises_the_command_lines_message_and_moves_nothing(arm, cli, call, cli_args):
    before = arm.status()["setpoints"]
    with pytest.raises(armctl.ArmctlError) as e:
        call(arm)
    code, _, err = cli("--sim", *cli_args)
    assert code != 0
    # The same words; the command line's fresh simulated arm starts limp, so a refused move may
    # add "(torque is off again, as it was)".
    said = err.strip().splitlines()[-1].removeprefix("error: ")
    assert said.startswith(str(e.value)), (said, str(e.value))
    np.testing.assert_allclose(arm.status()["setpoints"], before, atol=1e-6)


def test_opening_errors_are_one_line():
    with pytest.raises(armctl.ArmctlError, match="/dev/no-such-port") as e:
        armctl.Arm(port="/dev/no-such-port")
    assert "\n" not in str(e.value)
    with pytest.raises(armctl.ArmctlError, match="--protocol"):
        armctl.Arm(bus="/dev/no-such-port")
    with pytest.raises(armctl.ArmctlError, match="protocol"):
        armctl.Arm(bus="/dev/no-such-port", protocol="can")
    with pytest.raises(armctl.ArmctlError, match="unknown arm"):
        armctl.Arm(sim="no-such-arm")


def test_through_a_port_served_by_armctl_serve(armctl_bin):
    serve = subprocess.Popen([armctl_bin, "serve", "--sim"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        port = serve.stdout.readline().strip()
        assert port.startswith("/dev/"), serve.stderr.read()
        with armctl.Arm(port=port) as a:
            assert a.name == "so101"
            r = a.move_joints([0.1, 0.0, 0.0, 0.0, 0.0], duration=0.5)
            assert r["max_error"] < 2e-3
            assert a.monitor() is None  # the servos are serve's: its monitor reports there
    finally:
        serve.terminate()
        serve.wait(timeout=10)


def same_to_the_last_bit(python, cli, where="answer"):
    """Python's answer against the command line's JSON line: the same keys, and every number the
    same value. A number the firmware sent as an f32 is exactly that f32 in Python; the command
    line writes it as the shortest text of the f32, which reads back as a nearby f64: the two are
    then the same f32 to the last bit."""
    if isinstance(cli, dict):
        assert isinstance(python, dict) and sorted(python) == sorted(cli), (where, python, cli)
        for key in cli:
            same_to_the_last_bit(python[key], cli[key], f"{where}.{key}")
    elif isinstance(cli, list):
        assert isinstance(python, list) and len(python) == len(cli), (where, python, cli)
        for i, (p, c) in enumerate(zip(python, cli)):
            same_to_the_last_bit(p, c, f"{where}[{i}]")
    elif isinstance(cli, float) and python != cli:
        assert float(np.float32(python)) == python, (where, python, "differs and is no f32")
        assert np.float32(python) == np.float32(cli), (where, python, cli)
    else:
        assert type(python) is type(cli) and python == cli, (where, python, cli)


def test_answers_are_the_command_lines_to_the_last_bit(armctl_bin, cli_json):
    # One simulated arm behind `armctl serve`, at rest, asked the same by both front ends in turn
    # (the port takes one client at a time).
    serve = subprocess.Popen([armctl_bin, "serve", "--sim"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        port = serve.stdout.readline().strip()
        assert port.startswith("/dev/"), serve.stderr.read()
        q = [0.1, 0.2, -0.3, 0.1, 0.0]
        with armctl.Arm(port=port) as a:
            a.move_joints(q, duration=0.5)
        for call, args in [
            (lambda a: a.torque(True), ["torque", "on"]),
            (lambda a: a.stop(), ["stop"]),
            (lambda a: a.move_joints(q), ["joints", "--q", ",".join(map(str, q))]),
            (lambda a: a.status(), ["status"]),
        ]:
            with armctl.Arm(port=port) as a:
                python = call(a)
            line = cli_json("--port", port, "--json", *args)
            if args[0] == "status":
                # What changes from one poll to the next: the clocks, the loop's timing, the
                # link's counters; the arm at rest, its queue and its last move do not.
                for key in ("time", "play_time", "timing", "errors", "ik"):
                    python.pop(key), line.pop(key)
            python.pop("time_s", None), line.pop("time_s", None)  # how long each took
            same_to_the_last_bit(python, line, args[0])
    finally:
        serve.terminate()
        serve.wait(timeout=10)


def test_play_timed_keyframes_with_the_gripper_and_a_file(arm, tmp_path):
    arm.move_joints([0, 0, 0, 0, 0], duration=1.0)
    times = [0.0, 0.6, 1.2]
    q = [[0, 0, 0, 0, 0], [0.3, 0.1, -0.2, 0.1, 0.0], [0.1, 0.0, 0.0, 0.0, 0.2]]
    r = arm.play(times=times, positions=q, gripper=[50, 20, 70])
    assert r["command"] == "play", r
    np.testing.assert_allclose(arm.joints(), q[-1], atol=2e-3)
    assert abs(arm.status()["gripper"]["opening"] - 70) < 3
    f = tmp_path / "k.csv"
    f.write_text("t,q1,q2,q3,q4,q5\n0,0.1,0,0,0,0.2\n0.5,0,0,0,0,0\n")
    arm.play(str(f))
    np.testing.assert_allclose(arm.joints(), [0, 0, 0, 0, 0], atol=2e-3)
    # Arrays are checked as a file's rows are, each keyframe named by its number; nothing moves.
    before = arm.joints()
    with pytest.raises(armctl.ArmctlError, match="keyframes: line 2"):
        arm.play(times=[0, 1], positions=[[0, 0, 0, 0, 0], [9, 0, 0, 0, 0]])
    with pytest.raises(armctl.ArmctlError, match="not later"):
        arm.play(times=[0, 0], positions=[[0, 0, 0, 0, 0], [0.1, 0, 0, 0, 0]])
    with pytest.raises(armctl.ArmctlError, match="not an opening in percent"):
        arm.play(times=[0, 1], positions=[[0, 0, 0, 0, 0], [0.1, 0, 0, 0, 0]], gripper=[50, 101])
    with pytest.raises(armctl.ArmctlError, match="1 openings for 2 keyframes"):
        arm.play(times=[0, 1], positions=[[0, 0, 0, 0, 0], [0.1, 0, 0, 0, 0]], gripper=[50])
    with pytest.raises(armctl.ArmctlError, match="keyframes: line 1: NaN is not a finite number"):
        arm.play(times=[0, 1], positions=[[0, np.nan, 0, 0, 0], [0.1, 0, 0, 0, 0]])
    np.testing.assert_allclose(arm.joints(), before, atol=1e-3)
    with pytest.raises(armctl.ArmctlError, match="cannot read keyframe file"):
        arm.play(str(tmp_path / "missing.csv"))


# The child takes SIGINT as a terminal's Python does, whatever it inherited: a test run started
# in the background of a shell without job control (`cmd &` in a script) ignores SIGINT, and
# Python then installs no KeyboardInterrupt handler at all.
CTRL_C_CHILD = """
import json, signal, sys, time, armctl
signal.signal(signal.SIGINT, signal.default_int_handler)
arm = armctl.Arm(sim="so101")
arm.move_joints([0, 0, 0, 0, 0], duration=0.5)
print("moving", flush=True)
try:
    arm.move_joints([1.0, 0, 0, 0, 0], duration=8.0)
    print(json.dumps({"interrupted": False}))
except KeyboardInterrupt:
    s = arm.status()
    print(json.dumps({"interrupted": True, "state": s["state"], "q": s["measured"]}))
"""


def test_ctrl_c_during_a_move_stops_the_arm_and_raises_keyboard_interrupt():
    import json
    import signal
    import sys

    child = subprocess.Popen([sys.executable, "-c", CTRL_C_CHILD], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "moving"
        time.sleep(1.5)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        out, _ = child.communicate(timeout=20)
        took = time.monotonic() - sent
    finally:
        if child.poll() is None:
            child.kill()
    answer = json.loads(out.strip().splitlines()[-1])
    assert answer["interrupted"], answer
    assert answer["state"] == "Idle", answer
    # Stopped on the way (a stop decelerates within the limits), far from the target of 1 rad.
    assert 0.02 < answer["q"][0] < 0.8, answer
    assert took < 10, took


def test_an_arm_used_from_another_thread_refuses_in_one_line_and_works_in_its_own(arm):
    """Python programs drive arms from threads (a GUI, a camera loop): a call from a thread other
    than the one that opened the Arm raises ArmctlError, not pyo3's PanicException (a
    BaseException that `except Exception` misses), and sends nothing; an Arm opened in a worker
    thread is driven there."""
    import threading

    caught: list[BaseException] = []
    before = arm.status()["setpoints"]

    def elsewhere():
        try:
            arm.move_joints([0.3, 0, 0, 0, 0])
        except Exception as e:  # noqa: BLE001 - what it raises is the point
            caught.append(e)

    t = threading.Thread(target=elsewhere, name="camera-loop")
    t.start()
    t.join(30)
    assert len(caught) == 1 and isinstance(caught[0], armctl.ArmctlError), caught
    message = str(caught[0])
    assert "camera-loop" in message and "nothing was sent" in message and "\n" not in message, message
    np.testing.assert_allclose(arm.status()["setpoints"], before, atol=1e-6)

    answers: list[object] = []

    def own():
        with armctl.Arm(sim="so101") as mine:
            answers.append(mine.move_joints([0.2, 0, 0, 0, 0], duration=0.3)["command"])

    worker = threading.Thread(target=own)
    worker.start()
    worker.join(60)
    assert answers == ["joints"], answers


def test_physical_servos_sag_and_bad_choices_raise():
    """`servos="physical"` gives the simulated arm servos that carry its links (docs/servo-model.md):
    without gravity compensation the tool ends below its target, with it (the default on them)
    within 2 mm, 200 g at the tool too; a payload needs them, and one beyond their stall torque is
    refused before anything opens, as is compensation asked of ideal servos."""
    with armctl.Arm(sim="so101", servos="physical", gravity_compensation=False) as a:
        r = a.move_to([0.25, 0.05, 0.15], speed=0.2)
        assert r["error_mm"] > 2.0 and r["reached"][2] < 0.15, r
    with armctl.Arm(sim="so101", servos="physical", payload_kg=0.2) as a:
        r = a.move_to([0.25, 0.05, 0.15], speed=0.2)
        assert r["error_mm"] < 2.0, r
    with pytest.raises(armctl.ArmctlError, match="servos physical"):
        armctl.Arm(sim="so101", gravity_compensation=True)
    with pytest.raises(armctl.ArmctlError, match="physical servos only"):
        armctl.Arm(sim="so101", payload_kg=0.2)
    with pytest.raises(armctl.ArmctlError, match="stall torque"):
        armctl.Arm(sim="so101", servos="physical", payload_kg=3.0)
    with pytest.raises(armctl.ArmctlError, match="ideal or physical"):
        armctl.Arm(sim="so101", servos="sideways")
