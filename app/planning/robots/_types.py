"""Robot, Payload and RobotError: what the planner and the simulator know about an arm."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.errors import BioPlanError
from app.planning.energy import MotorModel, motors_modelled

if TYPE_CHECKING:
    import mujoco

    from app.planning.dynamics import Dynamics

__all__ = ["IDEAL_ACTUATOR", "Payload", "Robot", "RobotError"]

# "Ideal actuator": the joint torque is produced without loss, reflected inertia or recovery.
# Used for the human arm (muscles are not motors) and as the default for user URDFs.
IDEAL_ACTUATOR = MotorModel(
    gear_ratio=1.0,
    torque_constant=1.0,
    winding_resistance=0.0,
    rotor_inertia=0.0,
    viscous_friction=0.0,
    coulomb_friction=0.0,
    regen_efficiency=0.0,
)


#: Default acceleration limit of user robots: full speed reached in this time [s].
DEFAULT_RAMP_TIME = 0.25
#: Default jerk limit of user robots: full acceleration reached in this time [s].
DEFAULT_JERK_TIME = 0.05


class RobotError(BioPlanError):
    """A robot cannot be loaded or used; one-line message: what, which file, what was expected."""


def _frozen(values: ArrayLike, shape: tuple[int, ...], what: str) -> NDArray[np.float64]:
    array = np.array(values, dtype=np.float64)
    if array.shape != shape:
        raise RobotError(f"{what} has shape {array.shape}: expected {shape}")
    if not np.all(np.isfinite(array)):
        raise RobotError(f"{what} contains NaN or inf: expected finite values")
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class Payload:
    """A rigid payload fixed to the payload body (a dumbbell in the hand, a panel at the flange).

    Attributes:
        mass: payload mass [kg] (>= 0).
        com: (3,) centre of mass in the payload body's frame [m].
        inertia: (3, 3) inertia about the centre of mass, payload body's axes [kg m^2]
            (zeros for a point mass).
        size: (3,) box extents for display [m] (zeros for a point mass).
    """

    mass: float
    com: NDArray[np.float64]
    inertia: NDArray[np.float64]
    size: NDArray[np.float64]

    def __post_init__(self) -> None:
        mass = float(self.mass)
        if not np.isfinite(mass) or mass < 0.0:
            raise RobotError(f"payload mass is {self.mass}: expected a finite mass >= 0 kg")
        object.__setattr__(self, "mass", mass)
        object.__setattr__(self, "com", _frozen(self.com, (3,), "payload com"))
        inertia = _frozen(self.inertia, (3, 3), "payload inertia")
        if not np.allclose(
            inertia, inertia.T, rtol=0.0, atol=1e-12 * (1.0 + np.abs(inertia).max())
        ):
            raise RobotError("payload inertia is not symmetric: expected a symmetric 3x3 tensor")
        if np.linalg.eigvalsh(inertia).min() < -1e-12 * (1.0 + np.abs(inertia).max()):
            raise RobotError("payload inertia is not positive semi-definite: expected I >= 0")
        object.__setattr__(self, "inertia", inertia)
        size = _frozen(self.size, (3,), "payload size")
        if np.any(size < 0.0):
            raise RobotError(f"payload size is {size.tolist()}: expected extents >= 0 m")
        object.__setattr__(self, "size", size)

    @classmethod
    def point(cls, mass: float, com: ArrayLike = (0.0, 0.0, 0.0)) -> Payload:
        """A point mass at ``com`` (body frame) [kg, m]."""
        return cls(
            mass=mass, com=np.asarray(com, float), inertia=np.zeros((3, 3)), size=np.zeros(3)
        )

    @classmethod
    def box(cls, mass: float, size: ArrayLike, com: ArrayLike = (0.0, 0.0, 0.0)) -> Payload:
        """A uniform box of extents ``size`` (x, y, z) [m] along the body's axes, centred at com."""
        a, b, c = np.asarray(size, dtype=np.float64)
        inertia = float(mass) / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
        return cls(mass=mass, com=np.asarray(com, float), inertia=inertia, size=np.array([a, b, c]))

    def with_mass(self, mass: float) -> Payload:
        """The same payload shape with another mass; the inertia scales with the mass."""
        if not np.isfinite(mass) or mass < 0.0:
            raise RobotError(f"payload mass is {mass}: expected a finite mass >= 0 kg")
        if np.all(self.size > 0.0):
            return Payload.box(mass, self.size, self.com)
        inertia = self.inertia * (float(mass) / self.mass) if self.mass > 0.0 else np.zeros((3, 3))
        return Payload(mass=mass, com=self.com, inertia=inertia, size=self.size)


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
        """Rigid-body dynamics with the payload (and the motors' armature), cached per instance.

        Args:
            armature: add each motor's reflected rotor inertia N^2 J_m to the joint's diagonal.
            threads: threads for batched inverse dynamics (1 = one core).

        Returns:
            A ``PinocchioDynamics`` built from ``urdf_path``.
        """
        key = ("dynamics", bool(armature), int(threads))
        if key not in self._cache:
            from app.planning.dynamics import PinocchioDynamics

            self._cache[key] = PinocchioDynamics(
                self.urdf_path,
                payload=self.payload,
                payload_body=self.payload_body,
                armature=self.armature if armature else None,
                num_threads=threads,
                locks=self.locks,
            )
        result: Dynamics = self._cache[key]
        return result

    def with_payload(self, mass: float) -> Robot:
        """The same robot carrying a payload of the same shape with ``mass`` [kg]."""
        spec = {**self.spec, "payload": float(mass)} if self.spec else {}
        return dataclasses.replace(self, payload=self.payload.with_mass(mass), spec=spec)

    def mujoco_model(self, *, armature: bool = True, friction: bool = False) -> mujoco.MjModel:
        """The MJCF compiled with the payload and armature applied exactly as in ``dynamics()``.

        Args:
            armature: set each joint's ``armature`` to the motor's N^2 J_m [kg m^2].
            friction: also set joint ``damping`` to the motor's viscous friction [Nm s/rad] and
                ``frictionloss`` to its Coulomb friction [Nm] (off by default so that the model
                matches ``dynamics()``, which is frictionless; friction is accounted for in the
                energy model).

        Returns:
            A fresh ``mujoco.MjModel`` (callers may modify it).

        Raises:
            RobotError: the robot has no MJCF, or the MJCF lacks the payload body or a joint.
        """
        if self.mjcf_path is None:
            raise RobotError(
                f"robot '{self.name}' ({self.urdf_path.name}) has no MJCF: "
                "expected load_robot(..., mjcf=path) for a MuJoCo model"
            )
        from app.planning.robots._mujoco import build_mujoco_model

        return build_mujoco_model(
            self.mjcf_path,
            joint_names=self.joint_names,
            payload=self.payload,
            payload_body=self.payload_body,
            armature=self.armature if armature else None,
            motors=self.motors if friction else None,
            locks=self.locks,
            source=self._model_source(),
        )

    def _model_source(self) -> str | None:
        """The user's URDF when the MuJoCo model is its cached copy (no MJCF of their own)."""
        source = self.spec.get("source") if self.spec else None
        if not isinstance(source, str) or self.spec.get("mjcf") or not source.endswith(".urdf"):
            return None
        return f"{Path(source).name} (MuJoCo's copy {Path(str(self.mjcf_path)).name})"
