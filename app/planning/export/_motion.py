"""What an export needs from a plan, as plain data that rebuilds every method exactly.

A :class:`PlanMotion` holds, per planning method, the knots of its trajectory: for a piecewise
quintic (``quintic``, ``paper``) the polynomial's own knots, which define it exactly at every
time; for a method known only at samples, its samples (position, velocity and acceleration at
each), which a quintic Hermite spline joins — exact at the samples and C2 between
them. With the robot (rebuilt from ``robot_spec``), inverse dynamics gives the torque at
any time. ``PlanMotion.to_dict()`` is the ``"motion"`` block of every plan's and simulation's
JSON; :meth:`PlanMotion.from_dict` reads it back, bit for bit (JSON floats round-trip exactly).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app.errors import BioPlanError
from app.jsonsafe import json_safe

if TYPE_CHECKING:
    from app.planning.planner import EvaluatedTrajectory, PlanResult
    from app.planning.robots import Robot

__all__ = [
    "MAX_RATE_HZ",
    "MOTION_FORMAT",
    "ExportError",
    "MethodMotion",
    "PlanMotion",
    "Samples",
    "check_rate",
    "plan_methods",
    "plan_motion",
    "sample_count",
]

FloatArray = NDArray[np.float64]

#: Version tag of the ``motion`` block.
MOTION_FORMAT = "bioplan.motion/1"
#: Highest export rate [Hz]; EtherCAT drives top out near 10-20 kHz.
MAX_RATE_HZ = 20_000.0
#: Most samples one export may hold (a 10-minute motion at 1 kHz is 600k).
MAX_SAMPLES = 2_000_000
#: Times at which each method's torque is stored to check a rebuilt robot [fraction of T].
_CHECK_FRACTIONS = (0.0, 0.25, 0.5, 0.75, 1.0)
#: Relative torque mismatch that means the robot is not the one that was planned with.
_CHECK_RTOL = 1e-6


class ExportError(BioPlanError):
    """A plan cannot be exported as asked (one line: what, which field, what was expected)."""


def plan_methods(result: PlanResult) -> dict[str, EvaluatedTrajectory]:
    """Every method of a plan, by its name in ``app.names.METHODS``.

    The one place that knows how a ``PlanResult`` holds its methods (``result.methods``: name
    -> ``MethodResult``, whose ``evaluated`` is the trajectory with its torques and metrics).
    """
    return {name: m.evaluated for name, m in result.methods.items()}


@dataclass(frozen=True)
class Samples:
    """A method resampled at a uniform rate.

    Attributes:
        t: (T,) times [s], k / rate; the last one is at or after the plan's duration.
        q, qd, qdd: (T, n) positions [rad], velocities [rad/s], accelerations [rad/s^2].
        tau: (T, n) joint torques from inverse dynamics [Nm] (rigid body, payload, armature).
        rate: the sample rate [Hz].
    """

    t: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    tau: FloatArray
    rate: float


@dataclass(frozen=True)
class MethodMotion:
    """One method's trajectory as knots of a piecewise quintic Hermite spline.

    Attributes:
        name: method name (``quintic``, ``paper``, ...).
        kind: ``"piecewise_quintic"`` (the polynomial itself: exact at every time) or
            ``"samples"`` (exact at the samples, quintic Hermite between them).
        t: (K,) knot times [s], 0 first, the duration last.
        q, qd, qdd: (K, n) knot positions [rad], velocities [rad/s], accelerations [rad/s^2].
        metrics: the planner's metrics of the method (JSON-ready; NaN/None = not modelled).
        check_t: (C,) times [s] at which ``check_tau`` was computed.
        check_tau: (C, n) torques there [Nm], to check that a rebuilt robot is the same.
    """

    name: str
    kind: str
    t: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    metrics: Mapping[str, Any] = field(default_factory=dict)
    check_t: FloatArray = field(default_factory=lambda: np.zeros(0))
    check_tau: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def evaluate(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(T,) times [s] -> q, qd, qdd each (T, n); after the last knot the goal is held."""
        from app.planning.profiles import piecewise_quintic_batch

        t = np.asarray(t, dtype=np.float64)
        inside = t <= self.t[-1]
        n = self.q.shape[1]
        q = np.empty((t.size, n))
        qd = np.zeros((t.size, n))
        qdd = np.zeros((t.size, n))
        if inside.any():
            qi, qdi, qddi = piecewise_quintic_batch(
                self.t[None], self.q[None], self.qd[None], self.qdd[None], t[inside]
            )
            q[inside], qd[inside], qdd[inside] = qi[0], qdi[0], qddi[0]
        q[~inside] = self.q[-1]
        # At a knot's own time, its stored values themselves (the spline equals them up to
        # rounding; a controller file should carry the planned sample bit for bit).
        index = np.minimum(np.searchsorted(self.t, t), self.t.size - 1)
        hit = self.t[index] == t
        q[hit], qd[hit], qdd[hit] = self.q[index[hit]], self.qd[index[hit]], self.qdd[index[hit]]
        return q, qd, qdd

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "t": self.t.tolist(),
            "q": self.q.tolist(),
            "qd": self.qd.tolist(),
            "qdd": self.qdd.tolist(),
            "metrics": json_safe(dict(self.metrics)),
            "check": {"t": self.check_t.tolist(), "tau": self.check_tau.tolist()},
        }

    @classmethod
    def from_dict(cls, name: str, data: Mapping[str, Any], n: int) -> MethodMotion:
        where = f"motion.methods.{name}"
        if not isinstance(data, Mapping):
            raise ExportError(f"{where} is {type(data).__name__}: expected an object")
        kind = data.get("kind")
        if kind not in ("piecewise_quintic", "samples"):
            raise ExportError(f"{where}.kind is {kind!r}: expected piecewise_quintic or samples")
        t = _array(f"{where}.t", data.get("t"), (-1,))
        q, qd, qdd = (_array(f"{where}.{k}", data.get(k), (t.size, n)) for k in ("q", "qd", "qdd"))
        if t.size < 2 or t[0] != 0.0 or not np.all(np.diff(t) > 0):
            raise ExportError(f"{where}.t: expected at least two increasing times from 0 s")
        check = data.get("check") or {}
        check_t = _array(f"{where}.check.t", check.get("t", []), (-1,))
        check_tau = _array(f"{where}.check.tau", check.get("tau", []), (check_t.size, n))
        metrics = data.get("metrics") or {}
        return cls(
            name,
            str(kind),
            t,
            q,
            qd,
            qdd,
            metrics=metrics,
            check_t=check_t,
            check_tau=check_tau,
        )


def _array(where: str, value: Any, shape: tuple[int, ...]) -> FloatArray:
    """``value`` as a finite float array of ``shape`` (-1: any length), else an ExportError."""
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ExportError(f"{where} is not numeric: expected numbers") from None
    if array.size == 0 and len(shape) == 2 and shape[0] in (0, -1):
        array = array.reshape(0, shape[1])
    fits = array.ndim == len(shape) and all(
        s < 0 or a == s for a, s in zip(array.shape, shape, strict=True)
    )
    if not fits:
        raise ExportError(f"{where} has shape {array.shape}: expected {shape}")
    if not np.all(np.isfinite(array)):
        raise ExportError(f"{where} contains NaN or inf: expected finite numbers")
    return array


@dataclass(frozen=True)
class PlanMotion:
    """Everything an exporter needs from one plan (or the plan of a simulation).

    Attributes:
        robot: robot name.
        robot_spec: ``Robot.spec``: how to rebuild the robot (its files, payload, locks, ...).
        joint_names: (n,) free joints, the columns of every array.
        locks: locked joints -> values [rad or m] (not exported as columns; a URScript needs
            them for the full arm).
        all_joint_names: every movable joint of the robot file, locked ones included.
        start, goal: (n,) task [rad].
        duration: motion time [s].
        methods: method name -> its motion.
        default_method: the method exported when none is named (the optimised one).
        floors: the task's physical floors (JSON-ready).
        conditions: objective, payload, template and so on (JSON-ready), for the JSON export.
        safety: the plan's collision and workspace check (its result's ``"safety"`` block, not
            part of the motion block); None = not checked. The export refuses a method with a
            contact unless told (``docs/export.md``).
    """

    robot: str
    robot_spec: Mapping[str, Any]
    joint_names: tuple[str, ...]
    locks: Mapping[str, float]
    all_joint_names: tuple[str, ...]
    start: FloatArray
    goal: FloatArray
    duration: float
    methods: Mapping[str, MethodMotion]
    default_method: str
    floors: Mapping[str, Any] = field(default_factory=dict)
    conditions: Mapping[str, Any] = field(default_factory=dict)
    safety: Mapping[str, Any] | None = None

    def method(self, name: str | None) -> MethodMotion:
        """The motion of method ``name`` (None: the default), or an ExportError listing them."""
        key = self.default_method if name is None else name
        if key not in self.methods:
            raise ExportError(
                f"method '{key}' is not in this result: expected one of {', '.join(self.methods)}"
            )
        return self.methods[key]

    def to_dict(self) -> dict[str, Any]:
        """The ``"motion"`` block of a plan's JSON (see the module docstring)."""
        return {
            "format": MOTION_FORMAT,
            "robot": self.robot,
            "robot_spec": dict(self.robot_spec),
            "joint_names": list(self.joint_names),
            "locks": dict(self.locks),
            "all_joint_names": list(self.all_joint_names),
            "start": self.start.tolist(),
            "goal": self.goal.tolist(),
            "duration": self.duration,
            "default_method": self.default_method,
            "methods": {name: m.to_dict() for name, m in self.methods.items()},
            "floors": json_safe(dict(self.floors)),
            "conditions": json_safe(dict(self.conditions)),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> PlanMotion:
        """Read a ``"motion"`` block back; ExportError naming the first bad field."""
        if not isinstance(data, Mapping) or data.get("format") != MOTION_FORMAT:
            raise ExportError(f"motion.format: expected '{MOTION_FORMAT}' (a bioplan result)")
        names = data.get("joint_names")
        if not isinstance(names, list) or not names or not all(isinstance(x, str) for x in names):
            raise ExportError("motion.joint_names: expected a list of joint names")
        n = len(names)
        methods_in = data.get("methods")
        if not isinstance(methods_in, Mapping) or not methods_in:
            raise ExportError("motion.methods: expected an object of method name -> knots")
        methods = {k: MethodMotion.from_dict(k, v, n) for k, v in methods_in.items()}
        duration = data.get("duration")
        if not isinstance(duration, int | float) or not duration > 0:
            raise ExportError(f"motion.duration is {duration!r}: expected a time > 0 s")
        default = data.get("default_method")
        if default not in methods:
            raise ExportError(
                f"motion.default_method is {default!r}: expected one of {list(methods)}"
            )
        spec = data.get("robot_spec")
        if not isinstance(spec, Mapping):
            raise ExportError("motion.robot_spec: expected an object")
        locks = data.get("locks") or {}
        return cls(
            robot=str(data.get("robot", "")),
            robot_spec=dict(spec),
            joint_names=tuple(names),
            locks={str(k): float(v) for k, v in locks.items()},
            all_joint_names=tuple(data.get("all_joint_names") or names),
            start=_array("motion.start", data.get("start"), (n,)),
            goal=_array("motion.goal", data.get("goal"), (n,)),
            duration=float(duration),
            methods=methods,
            default_method=str(default),
            floors=dict(data.get("floors") or {}),
            conditions=dict(data.get("conditions") or {}),
        )

    def sample(self, method: str | None, rate: float, robot: Robot) -> Samples:
        """Method ``method`` at ``rate`` Hz: t = k / rate up to (at least) the duration.

        Raises:
            ExportError: unknown method, a rate outside (0, MAX_RATE_HZ], too many samples, or
                a robot whose torques differ from the planned ones.
        """
        motion = self.method(method)
        rate = check_rate(rate)
        count = sample_count(self.duration, rate)
        if count > MAX_SAMPLES:
            raise ExportError(
                f"rate {rate:g} Hz gives {count} samples over {self.duration:g} s: expected at "
                f"most {MAX_SAMPLES} (a lower rate)"
            )
        t = np.arange(count, dtype=np.float64) / rate
        q, qd, qdd = motion.evaluate(t)
        dynamics = robot.dynamics()
        tau = np.asarray(dynamics.inverse_dynamics(q, qd, qdd), dtype=np.float64)
        return Samples(t=t, q=q, qd=qd, qdd=qdd, tau=tau, rate=rate)

    def check_robot(self, robot: Robot) -> None:
        """Refuse a robot that is not the one the plan was made with (torques differ)."""
        if tuple(robot.joint_names) != self.joint_names:
            raise ExportError(
                f"robot '{robot.name}' has joints {list(robot.joint_names)}: expected "
                f"{list(self.joint_names)} as planned"
            )
        for motion in self.methods.values():
            if motion.check_t.size == 0:
                continue
            q, qd, qdd = motion.evaluate(motion.check_t)
            tau = robot.dynamics().inverse_dynamics(q, qd, qdd)
            scale = float(np.abs(motion.check_tau).max()) + 1e-9
            error = np.abs(tau - motion.check_tau)
            if error.max() > _CHECK_RTOL * scale:
                k, j = np.unravel_index(int(np.argmax(error)), error.shape)
                raise ExportError(
                    f"robot '{robot.name}' differs from the planned one: joint "
                    f"'{self.joint_names[j]}' needs {tau[k, j]:.6g} Nm at "
                    f"t={motion.check_t[k]:g} s "
                    f"where the plan had {motion.check_tau[k, j]:.6g} Nm (the robot files or "
                    "payload changed): expected the same robot"
                )


def sample_count(duration: float, rate: float) -> int:
    """Samples of an export at ``rate`` [Hz]: t = k / rate from 0 to at least ``duration``."""
    return math.ceil(duration * rate - 1e-9) + 1


def check_rate(rate: float) -> float:
    """``rate`` when it is a number in (0, MAX_RATE_HZ] Hz, else an ExportError naming it."""
    if isinstance(rate, bool) or not isinstance(rate, int | float) or not math.isfinite(rate):
        raise ExportError(f"export rate is {rate!r}: expected a number of Hz")
    if not 0.0 < rate <= MAX_RATE_HZ:
        raise ExportError(f"export rate is {rate:g} Hz: expected a rate in (0, {MAX_RATE_HZ:g}] Hz")
    return float(rate)


def method_motion(name: str, ev: EvaluatedTrajectory, robot: Robot) -> MethodMotion:
    """One evaluated trajectory as method ``name`` of a motion block: its exact knots (an
    optimum's constant-jerk mesh, a quintic's polynomial) or else its samples, with the torques
    at a few times to check a rebuilt robot against."""
    traj = ev.trajectory
    if traj.knots is not None:
        kind, knots = "piecewise_quintic", traj.knots
    else:
        kind, knots = "samples", (traj.t, traj.q, traj.qd, traj.qdd)
    t, q, qd, qdd = (np.array(a, dtype=np.float64) for a in knots)
    motion = MethodMotion(name, kind, t, q, qd, qdd, metrics=ev.metrics.to_dict())
    check_t = np.array([f * motion.duration for f in _CHECK_FRACTIONS])
    cq, cqd, cqdd = motion.evaluate(check_t)
    check_tau = np.asarray(robot.dynamics().inverse_dynamics(cq, cqd, cqdd), dtype=np.float64)
    return MethodMotion(name, kind, t, q, qd, qdd, motion.metrics, check_t, check_tau)


#: Which planned method is "the optimised one" exported by default, in order of preference.
DEFAULT_METHOD_ORDER = ("paper", "human_optimal", "bound", "jerk_limited", "quintic")


def _default_method(preferred: str, methods: Mapping[str, Any]) -> str:
    """``preferred`` when planned, else the first planned in :data:`DEFAULT_METHOD_ORDER`."""
    if preferred in methods:
        return preferred
    return next((m for m in DEFAULT_METHOD_ORDER if m in methods), next(iter(methods)))


def plan_motion(result: PlanResult, robot: Robot, *, default_method: str = "paper") -> PlanMotion:
    """The exportable motion of a plan made with ``robot``.

    Args:
        result: the plan (for a simulation: its ``plan``).
        robot: the robot the plan was made with (its spec, joints and locks are recorded).
        default_method: the method exported when none is named.
    """
    methods = {name: method_motion(name, ev, robot) for name, ev in plan_methods(result).items()}
    safety = getattr(result, "safety", None)
    if safety is not None and not isinstance(safety, Mapping) and hasattr(safety, "to_dict"):
        safety = safety.to_dict()
    return PlanMotion(
        robot=robot.name,
        robot_spec=dict(robot.spec),
        joint_names=tuple(robot.joint_names),
        locks=dict(robot.locks),
        all_joint_names=tuple(robot.all_joint_names),
        start=np.array(result.task.start, dtype=np.float64),
        goal=np.array(result.task.goal, dtype=np.float64),
        duration=float(result.duration),
        methods=methods,
        default_method=_default_method(default_method, methods),
        floors=result.floors.to_dict(),
        conditions={
            "objective": result.objective,
            "payload": result.payload_mass,
            "template": result.template.source,
            "template_is_paper_default": result.template.is_paper_default,
        },
        safety=dict(safety) if isinstance(safety, Mapping) else None,
    )
