"""Type stubs of the native module (the project's Rust crates, bound with PyO3). Use the
``armctl`` package's classes, which take and give numpy arrays; these take and give lists."""

from typing import Any, Optional

__version__: str

class ArmctlError(Exception):
    """A request armctl refused or could not carry out; the message is the command line's."""

class Model:
    def __init__(self, arm: str, tip: Optional[str] = None, calibration: Optional[str] = None) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def limits(self) -> list[tuple[float, float]]: ...
    @property
    def has_gripper(self) -> bool: ...
    @property
    def closed_form(self) -> Optional[str]: ...
    def fk(self, q: list[float]) -> list[list[float]]: ...
    def frames(self, q: list[float]) -> list[list[list[float]]]: ...
    def jacobian(self, q: list[float]) -> list[list[float]]: ...
    def ik(
        self,
        position: list[float],
        quaternion_wxyz: Optional[list[float]] = None,
        seed: Optional[list[float]] = None,
        solver: str = "auto",
        position_tolerance: Optional[float] = None,
        orientation_tolerance: Optional[float] = None,
    ) -> tuple[list[float], str, float, float, str]: ...

class TreeModel:
    @property
    def name(self) -> str: ...
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def limits(self) -> list[tuple[float, float]]: ...
    @property
    def effector_names(self) -> list[str]: ...
    def fk(self, q: list[float]) -> list[list[list[float]]]: ...
    def frames(self, q: list[float]) -> list[list[list[float]]]: ...
    def jacobian(self, q: list[float]) -> list[list[list[float]]]: ...
    def ik(
        self,
        targets: list[tuple[str, list[float], Optional[list[float]]]],
        seed: Optional[list[float]] = None,
        priority: Optional[list[str]] = None,
        position_tolerance: Optional[float] = None,
        orientation_tolerance: Optional[float] = None,
    ) -> tuple[list[float], str, list[tuple[str, bool, float, Optional[float], int]], int]: ...

def model(arm: str, tip: Optional[str] = None, calibration: Optional[str] = None) -> Model | TreeModel:
    """A chain's Model, or a TreeModel for a URDF with several leaves and no tip."""

def sample(
    times: list[float],
    positions: list[list[float]],
    rate: float,
    method: str = "catmull-rom",
    velocities: Optional[list[list[float]]] = None,
    ends: str = "zero",
) -> tuple[list[float], list[list[float]], list[list[float]], list[list[float]]]: ...

class Arm:
    def __init__(
        self,
        *,
        sim: bool = False,
        port: Optional[str] = None,
        bus: Optional[str] = None,
        protocol: Optional[str] = None,
        arm: Optional[str] = None,
        calibration: Optional[str] = None,
        baud: Optional[int] = None,
        obstacles: Optional[list[Any]] = None,
        table: bool = True,
        servos: Optional[str] = None,
        payload_kg: Optional[float] = None,
        gravity_compensation: Optional[bool] = None,
        hidden_obstacles: Optional[list[Any]] = None,
    ) -> None: ...
    @property
    def obstacles(self) -> list[dict[str, Any]]: ...
    @property
    def collision(self) -> dict[str, Any]: ...
    def add_obstacle(self, obstacle: Any) -> str: ...
    def remove_obstacle(self, name: str) -> None: ...
    def clear_obstacles(self) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def limits(self) -> list[tuple[float, float]]: ...
    @property
    def has_gripper(self) -> bool: ...
    @property
    def connected(self) -> str: ...
    @property
    def servo_ids(self) -> list[int]: ...
    @property
    def sim_port(self) -> Optional[str]: ...
    @property
    def streaming_now(self) -> bool: ...
    def status(self) -> dict[str, Any]: ...
    def move_to(
        self,
        position: list[float],
        quaternion_wxyz: Optional[list[float]] = None,
        speed: Optional[float] = None,
        duration: Optional[float] = None,
        path: str = "auto",
        timeout: float = 60.0,
    ) -> dict[str, Any]: ...
    def move_joints(
        self, q: list[float], speed: Optional[float] = None, duration: Optional[float] = None, timeout: float = 60.0
    ) -> dict[str, Any]: ...
    def play(
        self,
        path: Optional[str] = None,
        times: Optional[list[float]] = None,
        positions: Optional[list[list[float]]] = None,
        gripper: Optional[list[float]] = None,
        name: str = "keyframes",
        timeout: float = 30.0,
    ) -> dict[str, Any]: ...
    def stop(self) -> dict[str, Any]: ...
    def torque(self, on: bool) -> dict[str, Any]: ...
    def gripper(
        self, action: str, percent: Optional[float] = None, effort: Optional[float] = None, timeout: float = 10.0
    ) -> dict[str, Any]: ...
    def stream_begin(
        self, rate: float, lead_ms: Optional[float] = None, max_step: Optional[list[float]] = None
    ) -> None: ...
    def stream_joints(self, q: list[float], gripper: Optional[float] = None) -> tuple[float, list[float], Optional[float]]: ...
    def stream_pose(
        self, position: list[float], quaternion_wxyz: Optional[list[float]] = None, gripper: Optional[float] = None
    ) -> tuple[float, Optional[float]]: ...
    def stream_end(self) -> dict[str, Any]: ...
    def monitor(self) -> Optional[dict[str, Any]]: ...
    def close(self, torque_off: bool = False) -> None: ...

def calibrate(
    bus: str,
    protocol: str,
    arm: str,
    out: str,
    lerobot_json: Optional[str] = None,
    baud: Optional[int] = None,
) -> None:
    """LeRobot's calibration procedure on ``arm``'s servos on ``bus`` (``armctl calibrate``): each
    step waits for a line on standard input; writes the servos, the arm file ``out`` and LeRobot's
    file ``lerobot_json``."""
