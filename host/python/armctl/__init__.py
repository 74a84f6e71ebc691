"""armctl from Python: the project's kinematics on numpy arrays, and its arms driven through the
firmware core, as the ``armctl`` command line drives them.

>>> import armctl
>>> so101 = armctl.Model("so101")
>>> pose = so101.fk([0, 0.3, -0.5, 0.2, 0])           # 4 x 4 homogeneous matrix
>>> q = so101.ik(pose[:3, 3], seed=[0, 0.2, -0.4, 0.1, 0])
>>> with armctl.Arm(sim="so101") as arm:              # the firmware core on simulated servos
...     arm.move_to([0.2, 0.0, 0.15])
...     with arm.stream(rate=30) as s:                # every value a timed keyframe on the player
...         s.send(q, gripper=40.0)

Every refusal is an :class:`ArmctlError` carrying the command line's one-line message. Nothing is
implemented twice: the native module ``armctl._armctl`` calls the project's Rust crates.
"""

from __future__ import annotations

import threading
from typing import Any, Iterable, Sequence

import numpy as np
import numpy.typing as npt

from . import _armctl
from ._armctl import ArmctlError, calibrate

__all__ = ["Arm", "ArmctlError", "IkResult", "Model", "Stream", "Trajectory", "TreeIkResult", "TreeModel", "calibrate",
           "sample", "__version__"]
__version__: str = _armctl.__version__

Array = npt.NDArray[np.float64]


def _numbers(values: npt.ArrayLike, what: str, finite: bool = True) -> Array:
    """``values`` as a float array, checked as the command line checks its numbers: real numbers
    only (a bool, a string or a complex number is refused, not converted), every one finite unless
    ``finite`` is False (an arm's requests check that themselves, in the command line's words)."""
    try:
        a = np.asarray(values)
    except (TypeError, ValueError) as e:  # ragged nesting, objects numpy cannot read
        raise ArmctlError(f"{what}: expected numbers, {e}") from None
    if a.dtype.kind not in "iuf":
        got = {"b": "booleans", "c": "complex numbers", "U": "text", "S": "bytes"}.get(a.dtype.kind, "other objects")
        raise ArmctlError(f"{what}: expected real numbers, got {got}")
    a = a.astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(a)) if finite else ()
    if len(bad):
        raise ArmctlError(f"{what}: value {bad[0] + 1} ({a.flat[bad[0]]}) is not a finite number")
    return a


def _vector(values: npt.ArrayLike, what: str, length: int | None = None, finite: bool = True) -> list[float]:
    """A 1-D float vector as a list, its length checked (see :func:`_numbers`)."""
    a = _numbers(values, what, finite)
    if a.ndim != 1:
        raise ArmctlError(f"{what}: expected a 1-D array, got shape {a.shape}")
    if length is not None and a.shape[0] != length:
        raise ArmctlError(f"{what}: expected {length} values, got {a.shape[0]}")
    return a.tolist()


def _rows(values: npt.ArrayLike, what: str, width: int) -> Array | None:
    """A batch ``(n, width)`` checked as :func:`_numbers` (n may be 0), or None for one vector."""
    a = _numbers(values, what)
    if a.ndim == 1:
        return None
    if a.ndim != 2 or a.shape[1] != width:
        raise ArmctlError(f"{what}: expected shape ({width},) or (n, {width}), got {a.shape}")
    return a


class IkResult:
    """One IK answer: joint values and how well they reach the target."""

    __slots__ = ("q", "status", "position_error", "orientation_error", "method")

    def __init__(self, q: Array, status: str, position_error: float, orientation_error: float, method: str):
        self.q = q
        #: ``converged``, ``best_effort``, ``iteration_limit``, or why the input was refused.
        self.status = status
        #: Tool position error at ``q``, m.
        self.position_error = position_error
        #: Tool orientation error at ``q``, rad (0 for a position target).
        self.orientation_error = orientation_error
        #: ``analytic`` (the closed form) or the numerical method's name.
        self.method = method

    @property
    def converged(self) -> bool:
        """Within the limits and reaching the target within both tolerances (checked by FK)."""
        return self.status == "converged"

    def __repr__(self) -> str:
        return (f"IkResult(q={np.array2string(self.q, precision=4)}, status={self.status!r}, "
                f"position_error={self.position_error:.2e}, method={self.method!r})")


class Model:
    """An arm's kinematics: a preset (``so101``, ``open-manipulator-x``, ``ur5e``, ``puma560``,
    ``iiwa14``, ``planar:N``), a URDF file (``tip`` names the link the chain ends at) or an arm
    file (``.toml``), with a LeRobot ``calibration`` file if given.

    A URDF with several leaves and no ``tip`` is a tree: ``Model`` then gives a :class:`TreeModel`
    (several end effectors on shared joints), as ``armctl fk --arm FILE.urdf`` reads it."""

    def __new__(cls, arm: str, tip: str | None = None, calibration: str | None = None):
        native = _armctl.model(str(arm), tip, None if calibration is None else str(calibration))
        tree = isinstance(native, _armctl.TreeModel)
        if cls is TreeModel and not tree:
            raise ArmctlError(f"{arm} is a chain, not a tree (a URDF with several leaves and no tip): use armctl.Model")
        self = super().__new__(TreeModel if tree else cls)
        self._m = native
        return self

    def __init__(self, arm: str, tip: str | None = None, calibration: str | None = None):
        """Read by ``__new__``, which chooses between a chain and a tree."""

    @property
    def name(self) -> str:
        return self._m.name

    @property
    def dof(self) -> int:
        return len(self._m.joint_names)

    @property
    def joint_names(self) -> list[str]:
        return self._m.joint_names

    @property
    def limits(self) -> Array:
        """``(dof, 2)``: lower and upper limit per joint, rad or m."""
        return np.array(self._m.limits, dtype=np.float64).reshape(-1, 2)

    @property
    def has_gripper(self) -> bool:
        """Whether the arm has a gripper (a servo outside the chain, 0 % closed to 100 % open)."""
        return self._m.has_gripper

    @property
    def closed_form(self) -> str | None:
        """The closed-form IK shape of the arm's geometry, or None (numerical IK only)."""
        return self._m.closed_form

    def fk(self, q: npt.ArrayLike) -> Array:
        """The tool pose at ``q``: a 4 x 4 homogeneous matrix; ``(n, dof)`` gives ``(n, 4, 4)``."""
        batch = _rows(q, "q", self.dof)
        if batch is not None:
            return np.array([self._m.fk(row.tolist()) for row in batch]).reshape(len(batch), 4, 4)
        return np.array(self._m.fk(_vector(q, "q", self.dof)))

    def frames(self, q: npt.ArrayLike) -> Array:
        """Every joint frame at ``q``, base first: ``(dof, 4, 4)``."""
        return np.array(self._m.frames(_vector(q, "q", self.dof)))

    def jacobian(self, q: npt.ArrayLike) -> Array:
        """The 6 x dof geometric Jacobian at ``q`` (linear velocity rows first); ``(n, dof)`` gives
        ``(n, 6, dof)``."""
        batch = _rows(q, "q", self.dof)
        if batch is not None:
            return np.array([self._m.jacobian(row.tolist()) for row in batch]).reshape(len(batch), 6, self.dof)
        return np.array(self._m.jacobian(_vector(q, "q", self.dof)))

    def solve(self, position: npt.ArrayLike, quaternion_wxyz: npt.ArrayLike | None = None,
              seed: npt.ArrayLike | None = None, solver: str = "auto",
              position_tolerance: float | None = None, orientation_tolerance: float | None = None) -> IkResult:
        """Solves one target and says how it went (never raises for an unreachable target)."""
        q, status, pe, oe, method = self._m.ik(
            _vector(position, "position", 3),
            None if quaternion_wxyz is None else _vector(quaternion_wxyz, "quaternion_wxyz", 4),
            None if seed is None else _vector(seed, "seed", self.dof),
            solver, position_tolerance, orientation_tolerance)
        return IkResult(np.array(q), status, pe, oe, method)

    def ik(self, position: npt.ArrayLike, quaternion_wxyz: npt.ArrayLike | None = None,
           seed: npt.ArrayLike | None = None, solver: str = "auto", warm: bool = True) -> Array:
        """Joint values reaching ``position`` (m; a pose with ``quaternion_wxyz``, w first).

        A batch: ``position`` of shape ``(n, 3)`` (and ``quaternion_wxyz`` ``(n, 4)``) gives
        ``(n, dof)``; with ``warm`` each target is seeded with the answer before it, as a path is.
        Raises :class:`ArmctlError` naming the first target that does not converge."""
        p = _rows(position, "position", 3)
        if p is None:
            r = self.solve(position, quaternion_wxyz, seed, solver)
            if not r.converged:
                shown = np.array2string(np.asarray(position, dtype=np.float64), precision=4)
                raise ArmctlError(f"target {shown} m not reached: {r.status}, {r.position_error * 1e3:.2f} mm short")
            return r.q
        quats = None if quaternion_wxyz is None else _numbers(quaternion_wxyz, "quaternion_wxyz")
        if quats is not None and quats.shape != (p.shape[0], 4):
            raise ArmctlError(f"quaternion_wxyz: expected shape ({p.shape[0]}, 4), got {quats.shape}")
        out = np.empty((p.shape[0], self.dof))
        s = seed
        for i, target in enumerate(p):
            r = self.solve(target, None if quats is None else quats[i], s, solver)
            if not r.converged:
                raise ArmctlError(f"target {i} ({np.array2string(target, precision=4)} m) not reached: "
                                  f"{r.status}, {r.position_error * 1e3:.2f} mm short")
            out[i] = r.q
            if warm:
                s = r.q
        return out


class TreeIkResult:
    """A tree's IK answer: joint values, the overall status and each target's outcome."""

    __slots__ = ("q", "status", "effectors", "iterations")

    def __init__(self, q: Array, status: str, effectors: dict[str, dict[str, Any]], iterations: int):
        self.q = q
        #: ``converged`` (every target reached, checked by FK), ``best_effort``, ``iteration_limit``.
        self.status = status
        #: Per end effector with a target: ``reached``, ``position_error`` (m),
        #: ``orientation_error`` (rad, None for a position target) and ``priority``.
        self.effectors = effectors
        #: Iterations over every restart.
        self.iterations = iterations

    @property
    def converged(self) -> bool:
        return self.status == "converged"

    def __repr__(self) -> str:
        reached = {name: e["reached"] for name, e in self.effectors.items()}
        return f"TreeIkResult(q={np.array2string(self.q, precision=4)}, status={self.status!r}, reached={reached})"


def _tree_targets(targets: dict[str, Any]) -> list[tuple[str, list[float], list[float] | None]]:
    """``{link: position}`` or ``{link: (position, quaternion_wxyz)}`` as the native module's list."""
    if not isinstance(targets, dict) or not targets:
        raise ArmctlError("targets: expected a dict {end effector: position or (position, quaternion_wxyz)}")
    out = []
    for name, value in targets.items():
        if isinstance(value, tuple) and len(value) == 2:
            position, quat = value
            out.append((str(name), _vector(position, f"targets[{name!r}] position", 3),
                        None if quat is None else _vector(quat, f"targets[{name!r}] quaternion_wxyz", 4)))
        else:
            out.append((str(name), _vector(value, f"targets[{name!r}]", 3), None))
    return out


class TreeModel(Model):
    """A tree's kinematics (a URDF with several leaves, read by ``Model(path)``): several end
    effectors, named by their links (:attr:`effectors`), on joints some of them share. ``fk`` and
    ``jacobian`` answer for every end effector, as dicts keyed by link; ``ik`` solves one target
    per end effector at once."""

    @property
    def effectors(self) -> list[str]:
        """The end effectors' links."""
        return self._m.effector_names

    @property
    def has_gripper(self) -> bool:
        return False

    @property
    def closed_form(self) -> str | None:
        return None

    def fk(self, q: npt.ArrayLike) -> dict[str, Array]:
        """Each end effector's pose at ``q``: ``{link: 4 x 4}``; ``(n, dof)`` gives ``{link: (n, 4, 4)}``."""
        batch = _rows(q, "q", self.dof)
        if batch is not None:
            poses = np.array([self._m.fk(row.tolist()) for row in batch]).reshape(len(batch), len(self.effectors), 4, 4)
            return {name: poses[:, e] for e, name in enumerate(self.effectors)}
        poses = self._m.fk(_vector(q, "q", self.dof))
        return {name: np.array(p) for name, p in zip(self.effectors, poses)}

    def jacobian(self, q: npt.ArrayLike) -> dict[str, Array]:
        """Each end effector's 6 x dof geometric Jacobian at ``q``, over every joint of the tree
        (zero in the columns of the joints that do not move it): ``{link: 6 x dof}``."""
        return {name: np.array(j) for name, j in zip(self.effectors, self._m.jacobian(_vector(q, "q", self.dof)))}

    def solve(self, targets: dict[str, Any], seed: npt.ArrayLike | None = None,
              priority: str | Sequence[str] | None = None, position_tolerance: float | None = None,
              orientation_tolerance: float | None = None) -> TreeIkResult:
        """Solves every target at once and says how it went (never raises for an unreachable
        target). ``targets``: ``{link: position}`` or ``{link: (position, quaternion_wxyz)}``;
        ``priority``: the links whose targets are met first, the others then only in the null
        space those leave (None: every target weighs alike)."""
        first = None if priority is None else [priority] if isinstance(priority, str) else [str(p) for p in priority]
        q, status, effectors, iterations = self._m.ik(
            _tree_targets(targets), None if seed is None else _vector(seed, "seed", self.dof), first,
            position_tolerance, orientation_tolerance)
        outcomes = {name: {"reached": reached, "position_error": pe, "orientation_error": oe, "priority": rank}
                    for name, reached, pe, oe, rank in effectors}
        return TreeIkResult(np.array(q), status, outcomes, iterations)

    def ik(self, targets: dict[str, Any], seed: npt.ArrayLike | None = None,
           priority: str | Sequence[str] | None = None) -> Array:
        """Joint values reaching every target at once (see :meth:`solve`). Raises
        :class:`ArmctlError` naming the targets not reached."""
        r = self.solve(targets, seed, priority)
        if not r.converged:
            missed = ", ".join(f"{name} {e['position_error'] * 1e3:.2f} mm short"
                               for name, e in r.effectors.items() if not e["reached"])
            raise ArmctlError(f"targets not reached: {r.status}, {missed}")
        return r.q


class Trajectory:
    """Samples of a curve through timed keyframes (:func:`sample`): times ``t`` ``(n,)`` and
    positions ``q``, velocities ``v``, accelerations ``a``, each ``(n, joints)``."""

    __slots__ = ("t", "q", "v", "a")

    def __init__(self, t: Array, q: Array, v: Array, a: Array):
        self.t, self.q, self.v, self.a = t, q, v, a


def sample(times: npt.ArrayLike, positions: npt.ArrayLike, rate: float, method: str = "catmull-rom",
           velocities: npt.ArrayLike | None = None, ends: str = "zero") -> Trajectory:
    """Samples the curve through keyframes at ``rate`` samples a second, as ``armctl trajectory
    sample`` does: ``method`` one of linear, catmull-rom, monotone, natural, hermite (with
    ``velocities``), kb."""
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 2:
        raise ArmctlError(f"positions: expected shape (keyframes, joints), got {p.shape}")
    v = None if velocities is None else np.asarray(velocities, dtype=np.float64).tolist()
    t, q, vv, a = _armctl.sample(_vector(times, "times"), p.tolist(), float(rate), method, v, ends)
    return Trajectory(np.array(t), np.array(q), np.array(vv), np.array(a))


class Stream:
    """A stream of readings to the arm's player (:meth:`Arm.stream`): each :meth:`send` is a
    keyframe due one lead after it is sent, clamped into the joints' ranges and to one step from
    the keyframe before; the player interpolates between them at the control rate within the
    velocity and acceleration limits. A stream whose readings stop coming (without :meth:`close`)
    ends on the last one: the player brakes within the limits and goes back to it (the status's
    ``largest_pass``, rad, says how far the brake carried it)."""

    def __init__(self, arm: "Arm"):
        self._arm = arm
        #: The figures of the stream once closed (keyframes, latency, underruns, clamps, tracking).
        self.figures: dict[str, Any] | None = None

    def send(self, q: npt.ArrayLike, gripper: float | None = None) -> tuple[float, Array, float | None]:
        """Joint values (rad or m) and the gripper's opening (percent); returns ``(time, q,
        gripper)`` as sent, after clamping."""
        t, sent, g = self._arm._a.stream_joints(_vector(q, "q", finite=False),
                                                None if gripper is None else float(gripper))
        return t, np.array(sent), g

    def send_pose(self, position: npt.ArrayLike, quaternion_wxyz: npt.ArrayLike | None = None,
                  gripper: float | None = None) -> tuple[float, float | None]:
        """A tool pose, solved by the firmware's IK as the player reaches it; returns ``(time,
        gripper)`` as sent. On an arm of fewer than six joints (SO-101, Koch) the orientation is
        held up to a turn about the base's z axis: the tool keeps its tilt and its yaw follows the
        pan, so a step sideways with the orientation held is taken, not refused."""
        return self._arm._a.stream_pose(
            _vector(position, "position", 3, finite=False),
            None if quaternion_wxyz is None else _vector(quaternion_wxyz, "quaternion_wxyz", 4, finite=False),
            None if gripper is None else float(gripper))

    @property
    def open(self) -> bool:
        """Whether the stream still takes readings: not closed, and not ended by a failed send
        (the link failed: the arm was stopped). A keyframe the firmware refused (a pose it cannot
        reach) raises and changes nothing; the stream stays open."""
        return self.figures is None and self._arm._a.streaming_now

    def close(self) -> dict[str, Any]:
        """Ends the stream where it was (at rest) and returns its figures. A stream a failed send
        already ended (the arm was stopped, and the send raised why) has no figures: ``{}``."""
        if self.figures is None:
            self.figures = self._arm._a.stream_end() if self._arm._a.streaming_now else {}
        return self.figures

    def __enter__(self) -> "Stream":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        elif self._arm._a.streaming_now:
            # An error in the caller's loop: the arm stops (decelerating within its limits).
            self._arm._a.stop()


class Arm:
    """An arm driven through the firmware core, opened as the drive commands open it:

    - ``sim="so101"`` (or ``"open-manipulator-x"``): the core on this PC in real time, against
      simulated servos with the safety monitor (:meth:`monitor`);
    - ``port="/dev/ttyACM0"``: a board running the firmware, or ``armctl serve``'s link;
    - ``bus="/dev/ttyUSB0", protocol="sts"|"dxl2"``: the core on this PC (its own thread) against
      the servos on a USB adapter, with ``arm`` and a LeRobot ``calibration`` file.

    ``servos="physical"`` gives the simulated arm servos that sag, lag and heat (``payload_kg`` at
    the tool); the firmware compensates their sag under gravity unless
    ``gravity_compensation=False``. ``gravity_compensation=True`` asks for it on a real arm (it has
    not run on one yet); ideal servos refuse it (docs/servo-model.md).

    Each method is its command's request and returns the command's JSON answer as a dict.

    The surroundings: a preset stands on a table at its base plane (``table=False`` leaves it
    out); ``obstacles`` adds boxes, spheres, capsules and planes in the base frame, each a dict
    (``{"shape": "box", "centre": [x, y, z], "size": [sx, sy, sz], "name": "crate"}``, as the
    view's API takes them) or a tuple (``("box", centre, size)``, ``("sphere", centre, radius)``,
    ``("capsule", a, b, radius)``, ``("table", height)``, ``("plane", normal, offset)``). A bad
    one (a NaN, a size not above zero) raises ``ValueError`` before anything opens. Every later
    command is checked against them (:attr:`obstacles`, :meth:`add_obstacle`,
    :meth:`remove_obstacle`, :meth:`clear_obstacles`); the firmware gets them with the arm, which
    it takes only with the torque off. ``hidden_obstacles`` (simulated arm only), in the same
    forms, are in the simulated world but not told to the firmware (something nobody declared): the
    simulated links stop at them, and a move one blocks raises :class:`ArmctlError` naming the
    joint that stopped short.

    An ``Arm`` is driven from the thread that opened it: its connection (the simulated board's
    virtual clock among it) is not made to cross threads, and a call from another thread raises
    :class:`ArmctlError` saying so, sending nothing. Open the arm in the thread that drives it (a
    GUI's worker, a control loop); other threads run while it waits, as the GIL is released."""

    def __init__(self, *, sim: str | bool | None = None, port: str | None = None, bus: str | None = None,
                 protocol: str | None = None, arm: str | None = None, calibration: str | None = None,
                 baud: int | None = None, obstacles: Iterable[Any] | None = None, table: bool = True,
                 servos: str | None = None, payload_kg: float | None = None,
                 gravity_compensation: bool | None = None, hidden_obstacles: Iterable[Any] | None = None):
        if isinstance(sim, str):
            if arm is not None and arm != sim:
                raise ArmctlError(f"sim={sim!r} and arm={arm!r}: name the simulated arm once")
            arm, sim = sim, True
        self._native = _armctl.Arm(sim=bool(sim), port=port, bus=bus, protocol=protocol, arm=arm,
                                   calibration=None if calibration is None else str(calibration), baud=baud,
                                   obstacles=None if obstacles is None else list(obstacles), table=bool(table),
                                   servos=servos, payload_kg=None if payload_kg is None else float(payload_kg),
                                   gravity_compensation=None if gravity_compensation is None
                                   else bool(gravity_compensation),
                                   hidden_obstacles=None if hidden_obstacles is None else list(hidden_obstacles))
        self._owner = threading.current_thread()

    @property
    def _a(self) -> Any:
        """The native arm, for the thread that opened it only (see the class's documentation)."""
        here = threading.current_thread()
        if here is not self._owner:
            raise ArmctlError(f"this Arm was opened in thread {self._owner.name!r} and is driven from there only "
                              f"(called from {here.name!r}; nothing was sent): open it in the thread that drives it")
        return self._native

    @property
    def name(self) -> str:
        return self._a.name

    @property
    def joint_names(self) -> list[str]:
        return self._a.joint_names

    @property
    def dof(self) -> int:
        return len(self._a.joint_names)

    @property
    def limits(self) -> Array:
        """``(dof, 2)``: the range each joint is commanded within, rad or m."""
        return np.array(self._a.limits, dtype=np.float64).reshape(-1, 2)

    @property
    def has_gripper(self) -> bool:
        return self._a.has_gripper

    @property
    def servo_ids(self) -> list[int]:
        """Bus ids of the joints' servos, base first, then the gripper's."""
        return self._a.servo_ids

    @property
    def sim_port(self) -> str | None:
        """The simulated servos' pseudo-terminal (``sim``), or None."""
        return self._a.sim_port

    @property
    def obstacles(self) -> list[dict[str, Any]]:
        """The obstacles every command is checked against (the table's too), base frame."""
        return self._a.obstacles

    @property
    def collision(self) -> dict[str, Any]:
        """The collision geometry: ``margin``, ``bodies`` (each on joint ``link``'s frame, None for
        the base), ``obstacles``, ``allowed`` pairs, and its ``source``."""
        return self._a.collision

    def add_obstacle(self, obstacle: dict[str, Any] | tuple) -> str:
        """Adds an obstacle (a dict or a tuple, see the class) for the commands that follow;
        returns its name. Raises ``ValueError`` for a bad one, and nothing changes."""
        return self._a.add_obstacle(obstacle)

    def remove_obstacle(self, name: str) -> None:
        """Removes the obstacle named ``name`` (``"table"``: the table)."""
        self._a.remove_obstacle(name)

    def clear_obstacles(self) -> None:
        """Removes every obstacle but the table."""
        self._a.clear_obstacles()

    def status(self) -> dict[str, Any]:
        """State, ``measured`` and ``setpoints`` joints, ``tool`` position, gripper, queue, errors."""
        return self._a.status()

    def joints(self) -> Array:
        """The measured joint values, rad or m."""
        return np.array(self.status()["measured"], dtype=np.float64)

    def move_to(self, position: npt.ArrayLike, quaternion_wxyz: npt.ArrayLike | None = None, *,
                speed: float | None = None, duration: float | None = None, path: str = "auto",
                timeout: float = 60.0) -> dict[str, Any]:
        """The tool to ``position`` (m), oriented by ``quaternion_wxyz`` if given; ``path`` auto
        (a straight line where it is clear, else by joints), line or joint. Waits until at rest."""
        return self._a.move_to(_vector(position, "position", finite=False),
                               None if quaternion_wxyz is None
                               else _vector(quaternion_wxyz, "quaternion_wxyz", finite=False),
                               speed, duration, path, timeout)

    def move_joints(self, q: npt.ArrayLike, *, speed: float | None = None, duration: float | None = None,
                    timeout: float = 60.0) -> dict[str, Any]:
        """Every joint to ``q`` (rad or m), arriving together. Waits until at rest."""
        return self._a.move_joints(_vector(q, "q", finite=False), speed, duration, timeout)

    def play(self, keyframes: str | None = None, *, times: npt.ArrayLike | None = None,
             positions: npt.ArrayLike | None = None, gripper: npt.ArrayLike | None = None,
             timeout: float = 30.0) -> dict[str, Any]:
        """Plays timed keyframes as ``armctl play`` does (streamed with flow control, waited for):
        a keyframe file (joint or Cartesian, by its header), or ``times`` (s), ``positions``
        ``(n, dof)`` and the gripper's opening per keyframe (percent)."""
        if keyframes is not None:
            if times is not None or positions is not None or gripper is not None:
                raise ArmctlError("play takes a keyframe file or times and positions, not both")
            return self._a.play(str(keyframes), None, None, None, "keyframes", timeout)
        if times is None or positions is None:
            raise ArmctlError("play needs a keyframe file, or times and positions")
        t = _numbers(times, "times", finite=False)
        q = _numbers(positions, "positions", finite=False)
        if t.ndim != 1 or q.ndim != 2 or q.shape[0] != t.shape[0]:
            raise ArmctlError(f"times {t.shape} and positions {q.shape}: expected (n,) and (n, joints)")
        g = None if gripper is None else _numbers(gripper, "gripper", finite=False).reshape(-1).tolist()
        return self._a.play(None, t.tolist(), q.tolist(), g, "keyframes", timeout)

    def stream(self, rate: float, lead_ms: float | None = None,
               max_step: float | Sequence[float] | None = None) -> Stream:
        """Opens a stream of ``rate`` readings a second (see :class:`Stream`); switches torque on.
        Each keyframe is due ``lead_ms`` after it is sent (default: one period plus 8 ms); no joint
        moves more than ``max_step`` rad (one value, or one per joint) from one keyframe to the
        next (default: its speed limit over one period)."""
        steps = None if max_step is None else _vector(np.atleast_1d(max_step), "max_step", finite=False)
        self._a.stream_begin(float(rate), lead_ms, steps)
        return Stream(self)

    def stop(self) -> dict[str, Any]:
        """Decelerates within the limits and holds (ends an open stream)."""
        return self._a.stop()

    def torque(self, on: bool) -> dict[str, Any]:
        return self._a.torque(bool(on))

    def gripper(self, action: str | float, effort: float | None = None, timeout: float = 10.0) -> dict[str, Any]:
        """``"open"``, ``"close"``, or an opening in percent (0 closed to 100 open)."""
        if isinstance(action, str):
            return self._a.gripper(action, None, effort, timeout)
        return self._a.gripper("set", float(action), effort, timeout)

    def monitor(self) -> dict[str, Any] | None:
        """For ``sim``: the safety monitor's goals checked and violations; None otherwise."""
        return self._a.monitor()

    def close(self, torque_off: bool = False) -> None:
        """Ends an open stream at rest, then the connection; ``torque_off`` lets the servos go limp."""
        self._a.close(torque_off)

    def __enter__(self) -> "Arm":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()
