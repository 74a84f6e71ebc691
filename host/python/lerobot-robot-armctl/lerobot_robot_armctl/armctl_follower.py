"""``ArmctlFollower``: LeRobot's robot interface over an arm driven by the armctl firmware core.

Unlike ``so101_follower``, which writes each action straight to the servos as their goal, every
``send_action`` here is a keyframe on the core's player, due one lead after it was sent on the
core's playback clock (``armctl teleop``'s stream): the player interpolates between keyframes at
its control rate within the joints' velocity and acceleration limits, so the jumps of a policy's
chunk boundaries and late or missed steps are smoothed, and no goal leaves the joint limits.

Units are ``so101_follower``'s: body joints in degrees about the calibrated middle of their range
(LeRobot's ``MotorNormMode.DEGREES``), the gripper 0 (closed) to 100 (open). With a LeRobot
calibration the core maps a joint's radians to ticks exactly as LeRobot maps its degrees (the
middle of the range at zero, 4095 ticks a turn), so a degree here is a degree there and a dataset
recorded with either robot replays on the other.
"""

from __future__ import annotations

import logging
from functools import cached_property
from pathlib import Path
from typing import Any

import armctl
import numpy as np
from lerobot.cameras.utils import make_cameras_from_configs
from lerobot.robots.robot import Robot
from lerobot.utils.decorators import check_if_already_connected, check_if_not_connected

from .config_armctl_follower import ArmctlFollowerConfig
from .rotation import matrix_to_rotvec, rotvec_to_quaternion_wxyz

logger = logging.getLogger(__name__)

EE_KEYS = ("ee.x", "ee.y", "ee.z", "ee.wx", "ee.wy", "ee.wz")


class ArmctlFollower(Robot):
    """A follower arm driven through the armctl firmware core (see the module doc)."""

    config_class = ArmctlFollowerConfig
    name = "armctl_follower"

    def __init__(self, config: ArmctlFollowerConfig):
        super().__init__(config)
        self.config = config
        # The arm's description, for the features before connecting (and the end effector's FK).
        self._model = armctl.Model(config.arm)
        self._joint_names = self._model.joint_names
        self._has_gripper = self._model.has_gripper
        self.cameras = make_cameras_from_configs(config.cameras)
        self._arm: armctl.Arm | None = None
        self._stream: armctl.Stream | None = None

    # ---- features -------------------------------------------------------------------------------

    @property
    def _motors_ft(self) -> dict[str, type]:
        names = list(self._joint_names) + (["gripper"] if self._has_gripper else [])
        return {f"{name}.pos": float for name in names}

    @property
    def _ee_ft(self) -> dict[str, type]:
        keys = list(EE_KEYS) + (["ee.gripper_pos"] if self._has_gripper else [])
        return {key: float for key in keys}

    @property
    def _cameras_ft(self) -> dict[str, tuple]:
        return {name: (c.height, c.width, 3) for name, c in self.config.cameras.items()}

    @cached_property
    def observation_features(self) -> dict[str, type | tuple]:
        ee = {key: float for key in EE_KEYS} if self.config.action_space == "ee" else {}
        return {**self._motors_ft, **ee, **self._cameras_ft}

    @cached_property
    def action_features(self) -> dict[str, type]:
        return self._ee_ft if self.config.action_space == "ee" else self._motors_ft

    # ---- connection and calibration -------------------------------------------------------------

    @property
    def is_connected(self) -> bool:
        return self._arm is not None and all(cam.is_connected for cam in self.cameras.values())

    @property
    def _calibration_path(self) -> Path:
        if self.config.calibration_file:
            return Path(self.config.calibration_file)
        return self.calibration_fpath

    @property
    def is_calibrated(self) -> bool:
        """Simulated servos and a board need none here (a board runs the arm file it was sent).
        Servos on a USB adapter need LeRobot's file, which connecting checks they hold."""
        if not self.config.bus:
            return True
        return self._calibration_path.is_file()

    def _open(self) -> armctl.Arm:
        c = self.config
        return armctl.Arm(
            sim=c.sim, port=c.port, bus=c.bus, protocol=c.protocol, arm=c.arm, baud=c.baud,
            calibration=str(self._calibration_path) if c.bus else None,
            gravity_compensation=c.gravity_compensation,
        )

    @check_if_already_connected
    def connect(self, calibrate: bool = True) -> None:
        if not self.is_calibrated:
            if not calibrate:
                raise armctl.ArmctlError(f"{self}: no calibration file {self._calibration_path}: calibrate first")
            self.calibrate()
        try:
            self._arm = self._open()
        except armctl.ArmctlError as e:
            # The servos do not hold the file's calibration (a replaced servo, another arm).
            if not (calibrate and self.config.bus and "calibration" in str(e)):
                raise
            logger.warning("%s: %s; calibrating again", self, e)
            self.calibrate()
            self._arm = self._open()
        for cam in self.cameras.values():
            cam.connect()
        logger.info("%s connected (%s)", self, self._arm.name)

    def calibrate(self) -> None:
        """The project's calibration (``armctl calibrate``, LeRobot's procedure): writes the servos,
        LeRobot's file for this robot's id and an arm file beside it. Prompts on the terminal."""
        if not self.config.bus:
            logger.info("%s: nothing to calibrate (simulated servos, or a board that runs its arm file)", self)
            return
        was_connected = self._arm is not None
        if was_connected:
            self._close_arm(torque_off=True)
        path = self._calibration_path
        path.parent.mkdir(parents=True, exist_ok=True)
        armctl.calibrate(self.config.bus, self.config.protocol, self.config.arm, str(path.with_suffix(".toml")),
                         str(path), self.config.baud)
        self._load_calibration(path)
        print("Calibration saved to", path)
        if was_connected:
            self._arm = self._open()

    def configure(self) -> None:
        """Nothing: the firmware core sets its servos up when it connects."""

    # ---- observations and actions ---------------------------------------------------------------

    @check_if_not_connected
    def get_observation(self) -> dict[str, Any]:
        status = self._arm.status()
        q = np.asarray(status["measured"], dtype=np.float64)
        obs: dict[str, Any] = {f"{n}.pos": float(np.degrees(v)) for n, v in zip(self._joint_names, q)}
        if self._has_gripper:
            opening = (status.get("gripper") or {}).get("opening", 0.0)
            # LeRobot reads the gripper within its calibrated range: 0 to 100.
            obs["gripper.pos"] = float(min(100.0, max(0.0, opening)))
        if self.config.action_space == "ee":
            pose = self._model.fk(q)
            obs.update(zip(EE_KEYS, [*pose[:3, 3], *matrix_to_rotvec(pose[:3, :3])]))
        for name, cam in self.cameras.items():
            obs[name] = cam.read_latest()
        return obs

    def _max_steps(self) -> list[float] | None:
        m = self.config.max_relative_target
        if m is None:
            return None
        if isinstance(m, dict):
            missing = [n for n in self._joint_names if n not in m]
            if missing:
                raise armctl.ArmctlError(f"max_relative_target names no value for {', '.join(missing)}")
            return [float(np.radians(m[n])) for n in self._joint_names]
        return [float(np.radians(m))]

    def _stream_open(self) -> armctl.Stream:
        # A stream that a failed send ended (the arm was stopped, and that send raised why) is
        # opened again by the next action.
        if self._stream is None or not self._stream.open:
            self._stream = self._arm.stream(rate=self.config.fps, lead_ms=self.config.lead_ms,
                                            max_step=self._max_steps())
        return self._stream

    def _unknown(self, action: dict[str, Any], known: set[str]) -> None:
        extra = sorted(set(action) - known)
        if extra:
            raise armctl.ArmctlError(f"{self}: action keys it does not take: {', '.join(extra)} (nothing was sent)")

    @check_if_not_connected
    def send_action(self, action: dict[str, Any]) -> dict[str, Any]:
        """One action as the next keyframe of the stream; returns what was sent, after the
        joint-range and step clamps (degrees and 0-100, as given)."""
        if self.config.action_space == "ee":
            return self._send_pose(action)
        self._unknown(action, set(self._motors_ft))
        missing = [f"{n}.pos" for n in self._joint_names if f"{n}.pos" not in action]
        if missing:
            raise armctl.ArmctlError(f"{self}: the action has no {', '.join(missing)} (nothing was sent)")
        q = np.radians([float(action[f"{n}.pos"]) for n in self._joint_names])
        gripper = action.get("gripper.pos")
        _, sent, g = self._stream_open().send(q, None if gripper is None else float(gripper))
        out = {f"{n}.pos": float(np.degrees(v)) for n, v in zip(self._joint_names, sent)}
        if g is not None:
            out["gripper.pos"] = g
        return out

    def _send_pose(self, action: dict[str, Any]) -> dict[str, Any]:
        self._unknown(action, set(self._ee_ft))
        missing = [k for k in EE_KEYS if k not in action]
        if missing:
            raise armctl.ArmctlError(f"{self}: the action has no {', '.join(missing)} (nothing was sent)")
        position = [float(action[k]) for k in EE_KEYS[:3]]
        rotvec = [float(action[k]) for k in EE_KEYS[3:]]
        gripper = action.get("ee.gripper_pos")
        _, g = self._stream_open().send_pose(position, rotvec_to_quaternion_wxyz(rotvec),
                                             None if gripper is None else float(gripper))
        out = dict(zip(EE_KEYS, position + rotvec))
        if g is not None:
            out["ee.gripper_pos"] = g
        return out

    # ---- the end --------------------------------------------------------------------------------

    def _close_arm(self, torque_off: bool) -> None:
        arm, self._arm = self._arm, None
        try:
            if self._stream is not None:
                # The player ends at rest on the last keyframe, and the arm holds there.
                self._stream.close()
        finally:
            self._stream = None
            if arm is not None:
                arm.close(torque_off=torque_off)

    @check_if_not_connected
    def disconnect(self) -> None:
        self._close_arm(torque_off=self.config.disable_torque_on_disconnect)
        for cam in self.cameras.values():
            cam.disconnect()
        logger.info("%s disconnected", self)
