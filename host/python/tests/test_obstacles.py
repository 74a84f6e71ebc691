"""The surroundings from Python: obstacles given to Arm (dicts and tuples), the table left out,
obstacles added and removed for the commands that follow, and bad ones refused with ValueError
before anything moves or changes."""

from __future__ import annotations

import math

import numpy as np
import pytest

import armctl

BOX = ("box", [0.25, 0.1, 0.05], [0.06, 0.06, 0.1])
BALL = {"shape": "sphere", "centre": [0.15, -0.12, 0.1], "radius": 0.03, "name": "ball"}


def names(arm):
    return [o["name"] for o in arm.obstacles]


def test_obstacles_given_to_the_arm_are_its_surroundings():
    with armctl.Arm(sim="so101", obstacles=[BOX, BALL]) as arm:
        assert names(arm) == ["table", "box", "ball"]
        box = arm.obstacles[1]
        assert box["shape"] == "box"
        np.testing.assert_allclose(box["centre"], BOX[1])
        np.testing.assert_allclose(box["size"], BOX[2])
        g = arm.collision
        assert g["margin"] > 0 and len(g["bodies"]) > 0
        assert all(b["link"] is None or 0 <= b["link"] < arm.dof for b in g["bodies"])
        # The arm still drives among them.
        r = arm.move_joints([0.1, 0.0, 0.0, 0.0, 0.0], duration=1.0)
        assert r["max_error"] < 2e-3
    with armctl.Arm(sim="so101", table=False, obstacles=[("table", -0.05)]) as arm:
        assert [o["shape"] for o in arm.obstacles] == ["table"]
        assert arm.obstacles[0]["height"] == -0.05


@pytest.mark.parametrize(
    "bad, words",
    [
        (("box", [0.2, 0, 0], [0.1, float("nan"), 0.1]), "size[1]: NaN is not a finite number"),
        (("box", [0.2, 0, 0], [0.1, -0.1, 0.1]), "size[1]: -0.1 m is not a size"),
        (("sphere", [0.2, 0, 0], 0.0), "radius: 0 m is not a size"),
        (("sphere", [math.inf, 0, 0], 0.1), "centre[0]: inf is not a finite number"),
        (("sphere", [0.2, 0, 0]), "expected 2 values after the shape"),
        (("cone", [0, 0, 0]), "one of box, sphere"),
        ({"shape": "box", "centre": [0, 0, 0]}, "missing field \"size\""),
        ({"shape": "sphere", "centre": np.array([0.1, 0, 0]), "radius": 0.02, "colour": "red"}, "unknown field \"colour\""),
    ],
)
def test_a_bad_obstacle_raises_value_error_before_anything_opens(bad, words):
    with pytest.raises(ValueError) as e:
        armctl.Arm(sim="so101", obstacles=[bad])
    assert words in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_obstacles_added_and_removed_for_the_commands_that_follow():
    with armctl.Arm(sim="so101") as arm:
        assert names(arm) == ["table"]
        # The firmware takes new geometry with the arm, which it takes with the torque off only.
        arm.torque(False)
        assert arm.add_obstacle(BOX) == "box"
        assert arm.add_obstacle({"shape": "capsule", "a": np.zeros(3), "b": [0, 0, 0.3], "radius": 0.01,
                                 "name": "post"}) == "post"
        assert names(arm) == ["table", "box", "post"]
        before = arm.obstacles
        for bad in [("box", [0.2, 0, 0], [0.1, float("nan"), 0.1]), ("box", [0.2, 0, 0], [-1, 1, 1]),
                    {"shape": "sphere", "centre": [0, 0, 0.5], "radius": 0.1, "name": "post"}]:
            with pytest.raises(ValueError):
                arm.add_obstacle(bad)
        assert arm.obstacles == before, "a refused obstacle changes nothing"
        with pytest.raises(ValueError, match="no obstacle named shelf"):
            arm.remove_obstacle("shelf")
        arm.remove_obstacle("box")
        assert names(arm) == ["table", "post"]
        arm.clear_obstacles()
        assert names(arm) == ["table"]
        arm.remove_obstacle("table")
        assert names(arm) == []
        r = arm.move_joints([0.0, 0.2, 0.0, 0.0, 0.0], duration=1.0)
        assert r["max_error"] < 2e-3


def test_an_obstacle_hidden_from_the_firmware_stops_the_move_naming_the_joint():
    # In the tool's path as the pan turns to 0.5 rad; the firmware's check knows nothing of it.
    hidden = ("sphere", [0.38, -0.095, 0.226], 0.03)
    for servos in ["ideal", "physical"]:
        with armctl.Arm(sim="so101", servos=servos, hidden_obstacles=[hidden]) as arm:
            assert names(arm) == ["table"], "the firmware is not told of it"
            with pytest.raises(armctl.ArmctlError) as e:
                arm.move_joints([0.5, 0.0, 0.0, 0.0, 0.0], duration=1.0)
            assert str(e.value).startswith("shoulder_pan stopped"), str(e.value)
    with pytest.raises(armctl.ArmctlError) as e:
        armctl.Arm(bus="/dev/null", protocol="sts", hidden_obstacles=[hidden])
    assert "--hidden-obstacle puts an obstacle in the simulated world only" in str(e.value), str(e.value)
