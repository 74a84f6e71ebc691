"""``armctl_follower``: a LeRobot robot whose every action is a timed keyframe on the armctl
firmware core's player (a board, ``armctl serve``, the core in this process on a USB adapter's
servos, or simulated servos), named and scaled as ``so101_follower``'s.

LeRobot finds it by its distribution's name (``lerobot_robot_``...): importing this package
registers the config as ``--robot.type=armctl_follower``."""

from .armctl_follower import ArmctlFollower
from .config_armctl_follower import ArmctlFollowerConfig

__all__ = ["ArmctlFollower", "ArmctlFollowerConfig"]
