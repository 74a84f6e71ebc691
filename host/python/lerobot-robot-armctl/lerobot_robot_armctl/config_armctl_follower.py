"""The configuration of ``armctl_follower`` (``--robot.type=armctl_follower``)."""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.cameras import CameraConfig
from lerobot.robots.config import RobotConfig


@RobotConfig.register_subclass("armctl_follower")
@dataclass
class ArmctlFollowerConfig(RobotConfig):
    """Where the arm is, exactly one of:

    - ``sim``: simulated servos (the firmware core on this PC in real time, with the simulator's
      safety monitor); nothing to calibrate;
    - ``port``: a board running the firmware, or ``armctl serve``'s link;
    - ``bus`` with ``protocol`` (``sts`` or ``dxl2``): the firmware core in this process, on its
      own thread, against the servos of a USB adapter, calibrated by LeRobot's file.
    """

    # The arm: a preset (so101, open-manipulator-x) or an arm file (.toml) with a [servos] table.
    arm: str = "so101"
    sim: bool = False
    port: str | None = None
    bus: str | None = None
    protocol: str | None = None
    baud: int | None = None
    # LeRobot's calibration file of the servos (with `bus`); by default the file of `id` in this
    # robot's calibration directory, which `calibrate` writes.
    calibration_file: str | None = None
    # The rate actions come at (LeRobot's --fps): each is due one period plus 8 ms after it is sent
    # unless `lead_ms` says otherwise, and no joint moves more than its speed limit over a period.
    fps: float = 30.0
    lead_ms: float | None = None
    # As so101_follower's: the largest change of a joint from one action to the next, in degrees
    # (one value, or one per motor name); None leaves the speed limit over one period.
    max_relative_target: float | dict[str, float] | None = None
    disable_torque_on_disconnect: bool = True
    # The firmware's gravity compensation (docs/servo-model.md): None is armctl.Arm's default (on
    # with physical simulated servos, off elsewhere); True asks for it on a real arm's servos.
    gravity_compensation: bool | None = None
    cameras: dict[str, CameraConfig] = field(default_factory=dict)
    # "joint": `shoulder_pan.pos` ... in degrees and `gripper.pos` 0-100, as so101_follower;
    # "ee": `ee.x, ee.y, ee.z` (m) and `ee.wx, ee.wy, ee.wz` (rotation vector, rad) with
    # `ee.gripper_pos`, solved by the firmware's IK (on an arm of fewer than six joints, the
    # orientation up to a turn about the base's z: the tool's tilt is held, its yaw follows the pan).
    action_space: str = "joint"

    def __post_init__(self):
        super().__post_init__()
        places = [name for name, given in (("sim", self.sim), ("port", self.port), ("bus", self.bus)) if given]
        if len(places) != 1:
            raise ValueError(f"armctl_follower: give exactly one of sim, port and bus (got {places or 'none'})")
        if self.bus and not self.protocol:
            raise ValueError("armctl_follower: bus needs protocol: sts (Feetech) or dxl2 (Dynamixel)")
        if self.action_space not in ("joint", "ee"):
            raise ValueError(f"armctl_follower: action_space {self.action_space!r}: joint or ee")
        if not (self.fps > 0 and self.fps <= 1000):
            raise ValueError(f"armctl_follower: fps {self.fps} must be above 0 and at most 1000")
