"""Robot: what the planner and the simulator know about an arm (a data type: its dynamics and
MuJoCo model are built by ``app.planning.dynamics.robot_dynamics`` and
``_mujoco.robot_mujoco_model``; ``Payload`` and ``RobotError`` live in ``app.planning.payload``)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.planning.dynamics import Dynamics, robot_dynamics
from app.planning.energy import IDEAL_ACTUATOR, MotorModel, motors_modelled
from app.planning.payload import Payload, RobotError
from app.planning.robots._mujoco import robot_mujoco_model

if TYPE_CHECKING:
    import mujoco

__all__ = ["IDEAL_ACTUATOR", "Payload", "Robot", "RobotError"]

#: Default acceleration limit of user robots: full speed reached in this time [s].
DEFAULT_RAMP_TIME = 0.25
#: Default jerk limit of user robots: full acceleration reached in this time [s].
DEFAULT_JERK_TIME = 0.05


@dataclass(frozen=True, eq=False)
class Robot:
    """A robot arm: its model files, limits, motors, payload and default curl task.

    Attributes:
        name: robot name (a built-in name, or the URDF's robot name).
        joint_names: (n,) joint names, root to tip (URDF joint == MJCF joint).
        urdf_path: the URDF file (a real file: viewers and users read it).
        mjcf_path: the matching MJCF file, or None.
        q_min, q_max: (n,) position limits [rad] (+-inf for continuous joints).
        qd_max: (n,) speed limits [rad/s].
        tau_max: (n,) torque limits [Nm].
        motors: one MotorModel per joint.
        payload: the payload carried by ``payload_body``.
        payload_body: URDF link == MJCF body that carries the payload.
        default_start, default_goal: (n,) the default curl task [rad].
        shoulder_joint, elbow_joint: indices that human shoulder / elbow flexion map to.
        parameters: the parameter table, rows with keys name, value, unit, source.
        locks: joints of the file held at fixed values [rad, or m for prismatic joints]; they
            are not in ``joint_names`` (the planner sees Pinocchio's reduced model) but the
            viewer and the exporters need them.
        all_joint_names: every movable joint of the file in Pinocchio's order, the locked ones
            included (empty: the same as ``joint_names``).
        package_dirs: folders that ``package://NAME/...`` mesh paths resolve against (the
            folder that holds a package ``NAME``); the URDF's own folder is always searched.
        spec: how to rebuild this robot, as JSON-ready ``load_robot`` arguments (stored with
            every plan, so that a saved result can be exported again).
        qdd_max: (n,) acceleration limits [rad/s^2] of the joint controller (the jerk-limited
            industrial baseline); None = the table's ``<joint>.acceleration`` rows, else
            ``qd_max / DEFAULT_RAMP_TIME`` (full speed in 0.25 s).
        jerk_max: (n,) jerk limits [rad/s^3]; None = the table's ``<joint>.jerk`` rows, else
            ``qdd_max / DEFAULT_JERK_TIME`` (full acceleration in 0.05 s).
        stated_limits: ``acceleration`` and ``jerk`` -> the joints whose limit of that kind
            the robot states (a sidecar's ``acceleration_limits``/``jerk_limits``; every joint
            when ``qdd_max``/``jerk_max`` are given explicitly). Assumed limits (the built-in
            robots' table rows, the defaults) serve the jerk-limited baseline but are not
            stated: exports gate only stated ones (``app.planning.export``).
    """

    name: str
    joint_names: tuple[str, ...]
    urdf_path: Path
    mjcf_path: Path | None
    q_min: NDArray[np.float64]
    q_max: NDArray[np.float64]
    qd_max: NDArray[np.float64]
    tau_max: NDArray[np.float64]
    motors: tuple[MotorModel, ...]
    payload: Payload
    payload_body: str
    default_start: NDArray[np.float64]
    default_goal: NDArray[np.float64]
    shoulder_joint: int
    elbow_joint: int
    parameters: tuple[dict[str, object], ...] = ()
    locks: Mapping[str, float] = field(default_factory=dict)
    all_joint_names: tuple[str, ...] = ()
    package_dirs: tuple[Path, ...] = ()
    spec: Mapping[str, Any] = field(default_factory=dict)
    qdd_max: NDArray[np.float64] | None = None
    jerk_max: NDArray[np.float64] | None = None
    stated_limits: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    _cache: dict[Any, Any] = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        if n == 0:
            raise RobotError(f"robot '{self.name}' has no joints: expected at least one")
        if len(self.motors) != n:
            raise RobotError(
                f"robot '{self.name}' has {len(self.motors)} motors: expected one per joint ({n})"
            )
        for attr in ("q_min", "q_max", "qd_max", "tau_max", "default_start", "default_goal"):
            array = np.array(getattr(self, attr), dtype=np.float64)
            if array.shape != (n,):
                raise RobotError(
                    f"robot '{self.name}' {attr} has shape {array.shape}: expected ({n},)"
                )
            array.setflags(write=False)
            object.__setattr__(self, attr, array)
        for attr in ("shoulder_joint", "elbow_joint"):
            index = getattr(self, attr)
            if not 0 <= index < n:
                raise RobotError(f"robot '{self.name}' {attr}={index}: expected 0 <= index < {n}")
        self._controller_limits(n)
        object.__setattr__(self, "urdf_path", Path(self.urdf_path))
        object.__setattr__(self, "locks", {str(k): float(v) for k, v in self.locks.items()})
        overlap = sorted(set(self.locks) & set(self.joint_names))
        if overlap:
            raise RobotError(f"robot '{self.name}' joints {overlap} are both free and locked")
        if not self.all_joint_names:
            object.__setattr__(self, "all_joint_names", tuple(self.joint_names))
        missing = sorted((set(self.joint_names) | set(self.locks)) - set(self.all_joint_names))
        if missing or len(self.all_joint_names) != n + len(self.locks):
            raise RobotError(
                f"robot '{self.name}' all_joint_names {list(self.all_joint_names)}: expected the "
                "free and the locked joints, each once"
            )
        object.__setattr__(self, "package_dirs", tuple(Path(p) for p in self.package_dirs))
        if self.mjcf_path is not None:
            object.__setattr__(self, "mjcf_path", Path(self.mjcf_path))

    def _table_limits(self, suffix: str) -> NDArray[np.float64] | None:
        """Per-joint values of the parameter rows ``<joint>.<suffix>``, if all are present."""
        rows = {row.get("name"): row.get("value") for row in self.parameters}
        values = [rows.get(f"{joint}.{suffix}") for joint in self.joint_names]
        if any(v is None for v in values):
            return None
        return np.array([float(v) for v in values], dtype=np.float64)  # type: ignore[arg-type]

    def _controller_limits(self, n: int) -> None:
        """Acceleration and jerk limits: given, from the parameter table, or the defaults."""
        stated = {str(k): tuple(str(j) for j in v) for k, v in self.stated_limits.items()}
        for kind, given in (("acceleration", self.qdd_max), ("jerk", self.jerk_max)):
            if kind not in stated:  # explicit limits are stated ones (kept through replace())
                stated[kind] = tuple(self.joint_names) if given is not None else ()
        unknown = sorted({j for v in stated.values() for j in v} - set(self.joint_names))
        if set(stated) != {"acceleration", "jerk"} or unknown:
            raise RobotError(
                f"robot '{self.name}' stated_limits {stated}: expected acceleration and jerk "
                "mapped to its joints"
            )
        object.__setattr__(self, "stated_limits", stated)
        qdd = self.qdd_max if self.qdd_max is not None else self._table_limits("acceleration")
        if qdd is None:
            qdd = np.asarray(self.qd_max) / DEFAULT_RAMP_TIME
        jerk = self.jerk_max if self.jerk_max is not None else self._table_limits("jerk")
        if jerk is None:
            jerk = np.asarray(qdd) / DEFAULT_JERK_TIME
        for attr, value in (("qdd_max", qdd), ("jerk_max", jerk)):
            array = np.array(value, dtype=np.float64)
            # inf is allowed (a model without speed limits); the jerk-limited baseline, the only
            # user of these limits, refuses it with a clear message.
            if array.shape != (n,) or np.any(np.isnan(array)) or np.any(array <= 0.0):
                raise RobotError(
                    f"robot '{self.name}' {attr} is {array.tolist()}: expected {n} values > 0"
                )
            array.setflags(write=False)
            object.__setattr__(self, attr, array)

    def __getstate__(self) -> dict[str, Any]:
        # Cached dynamics hold C++ scratch data: rebuild them after unpickling instead.
        state = self.__dict__.copy()
        state["_cache"] = {}
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def shoulder_joint_name(self) -> str:
        """The joint human shoulder flexion maps to."""
        return self.joint_names[self.shoulder_joint]

    @property
    def elbow_joint_name(self) -> str:
        """The joint human elbow flexion maps to."""
        return self.joint_names[self.elbow_joint]

    @property
    def motors_modelled(self) -> bool:
        """False when the motors are unknown (electrical metrics are then "not modelled")."""
        return motors_modelled(self.motors)

    def full_configuration(self, q: ArrayLike) -> NDArray[np.float64]:
        """Free-joint values with the locked joints inserted, in ``all_joint_names`` order.

        Args:
            q: (..., n) values of ``joint_names`` [rad or m].

        Returns:
            (..., N) values of ``all_joint_names`` (N = n + number of locks).
        """
        values = np.asarray(q, dtype=np.float64)
        if values.ndim == 0 or values.shape[-1] != self.n_joints:
            raise RobotError(
                f"robot '{self.name}' configuration has shape {values.shape}: "
                f"expected (..., {self.n_joints})"
            )
        out = np.empty((*values.shape[:-1], len(self.all_joint_names)))
        column = {name: i for i, name in enumerate(self.joint_names)}
        for k, name in enumerate(self.all_joint_names):
            out[..., k] = values[..., column[name]] if name in column else self.locks[name]
        return out

    @property
    def armature(self) -> NDArray[np.float64]:
        """(n,) reflected rotor inertia N^2 J_m per joint [kg m^2]."""
        return np.array([motor.armature for motor in self.motors], dtype=np.float64)

    def parameter(self, name: str) -> object:
        """The value of the parameter-table row called ``name``."""
        for row in self.parameters:
            if row.get("name") == name:
                return row.get("value")
        raise RobotError(f"robot '{self.name}' has no parameter '{name}'")

    def dynamics(self, *, armature: bool = True, threads: int = 1) -> Dynamics:
        """Rigid-body dynamics with the payload (and the motors' armature), cached per instance:
        ``app.planning.dynamics.robot_dynamics(self, ...)``, kept as a method for its callers."""
        return robot_dynamics(self, armature=armature, threads=threads)

    def with_payload(self, mass: float) -> Robot:
        """The same robot carrying a payload of the same shape with ``mass`` [kg]."""
        spec = {**self.spec, "payload": float(mass)} if self.spec else {}
        return dataclasses.replace(self, payload=self.payload.with_mass(mass), spec=spec)

    def mujoco_model(self, *, armature: bool = True, friction: bool = False) -> mujoco.MjModel:
        """The MJCF compiled with the payload and armature applied exactly as in ``dynamics()``:
        ``app.planning.robots._mujoco.robot_mujoco_model(self, ...)``, kept as a method for
        its callers."""
        return robot_mujoco_model(self, armature=armature, friction=friction)
