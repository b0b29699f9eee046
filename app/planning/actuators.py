"""Actuators that can say no: a torque–speed envelope and an RMS (thermal) torque limit per joint.

**Envelope** (joint side): the full ``peak_torque`` is available up to ``corner_speed``; above it
the supply voltage caps it along a straight line that reaches zero at ``max_speed``:

    |τ| <= τ_peak · min(1, (ω_max − |q̇|) / (ω_max − ω_corner)),

i.e. |τ| <= τ_peak and |τ| (ω_max − ω_c) + τ_peak |q̇| <= τ_peak ω_max; the second is four linear
inequalities in (τ, q̇), so the optimal control keeps it exactly at its evaluation points. A
sidecar may give ``bus_voltage`` instead of the corner: with the joint's motor (gear ratio N,
torque constant k_t, resistance R; back-EMF constant = k_t in SI units), the peak current
i_p = τ_peak / (N k_t) leaves V − R i_p for the back-EMF, so ω_c = (V − R i_p) / (k_t N), and
``max_speed`` defaults to the no-load speed V / (k_t N).

**RMS limit**: a motion of T seconds is repeated every ``duty_cycle`` seconds with the arm
holding the goal pose in between, so over one cycle C

    τ_rms = sqrt((∫ τ² dt + τ_hold² (C − T)) / C) <= rms_torque,

with τ_hold the static torque at the goal (C < T: the cycle is the motion alone).

``rated_speed`` is the continuous rating, reported with the margins (a joint above it for long
heats up faster than the RMS model of a constant winding resistance says).

Built-in values and their sources are in :data:`BUILT_IN` (docs/robots.md, "Actuator limits");
a user robot's come from its sidecar's ``actuators`` block.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from app.errors import BioPlanError
from app.planning.robots import ACTUATOR_FIELDS, read_sidecar

if TYPE_CHECKING:
    from app.planning.evaluation import EvaluatedTrajectory
    from app.planning.robots import Robot

__all__ = [
    "ACTUATOR_FIELDS",
    "BUILT_IN",
    "ActuatorEnvelope",
    "ActuatorLimits",
    "actuator_limits",
    "actuator_report",
    "actuator_violation",
    "envelope_from_fields",
    "plan_actuators",
]

#: The constraints hold with this margin at the evaluation points, so that they hold between
#: them too: a fraction of the peak torque below the envelope (measured: a 2-DOF elbow at
#: 11.7 rad/s, where the envelope falls 6.7 Nm per rad/s, rose 0.5 Nm = 0.6 % of its peak above
#: it between the points of 40 intervals kept with 0.2 %) [-].
ENVELOPE_MARGIN = 1e-2
#: The peak torque and the RMS limit hold with this relative margin (as
#: ``optimal.TORQUE_MARGIN``; the RMS is an integral: only quadrature error) [-].
LIMIT_MARGIN = 2e-3
#: A margin below this (relative, round-off) is a violation [-].
_TOL = 1e-6


@dataclass(frozen=True)
class ActuatorEnvelope:
    """One joint's actuator limits (joint side).

    Attributes:
        peak_torque: torque available up to the corner speed [Nm].
        rated_speed: continuous (rated) speed [rad/s].
        max_speed: speed at which no torque is left [rad/s].
        corner_speed: speed up to which the peak torque is available [rad/s].
        rms_torque: RMS (thermal) torque limit over the duty cycle [Nm].
        duty_cycle: the cycle the RMS is taken over [s].
        source: where the numbers come from.
    """

    peak_torque: float
    rated_speed: float
    max_speed: float
    corner_speed: float
    rms_torque: float
    duty_cycle: float
    source: str = ""

    def available(self, speed: Any) -> Any:
        """Torque [Nm] available at joint speed(s) [rad/s]."""
        w = np.abs(np.asarray(speed, dtype=np.float64))
        slope = (self.max_speed - w) / (self.max_speed - self.corner_speed)
        return self.peak_torque * np.clip(slope, 0.0, 1.0)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def envelope_from_fields(
    where: str, values: Mapping[str, float], motor: Any = None, source: str = ""
) -> ActuatorEnvelope:
    """An envelope from sidecar fields (:data:`ACTUATOR_FIELDS`), the corner from
    ``bus_voltage`` and the joint's motor when ``corner_speed`` is not given.

    Raises:
        BioPlanError: a missing or inconsistent field, named with ``where``.
    """
    for name, (_, required) in ACTUATOR_FIELDS.items():
        if required and name not in values:
            raise BioPlanError(f"{where} lacks {name}: expected it")
    corner, top = values.get("corner_speed"), values.get("max_speed")
    if corner is None:
        volts = values.get("bus_voltage")
        if volts is None:
            raise BioPlanError(f"{where} lacks corner_speed: expected it, or bus_voltage")
        if motor is None or not getattr(motor, "modelled", False):
            raise BioPlanError(
                f"{where}.bus_voltage needs the joint's motor (gear_ratio, torque_constant, "
                "winding_resistance) in the sidecar's motors block: expected it, or corner_speed"
            )
        k = float(motor.torque_constant) * float(motor.gear_ratio)
        current = float(values["peak_torque"]) / k
        corner = (float(volts) - float(motor.winding_resistance) * current) / k
        top = float(volts) / k if top is None else top
        if corner <= 0:
            raise BioPlanError(
                f"{where}.bus_voltage {volts:g} V: expected more than the peak current's "
                f"resistive drop ({float(motor.winding_resistance) * current:.3g} V)"
            )
    if top is None:
        raise BioPlanError(f"{where} lacks max_speed: expected it, or bus_voltage")
    if not float(top) > float(corner):
        raise BioPlanError(
            f"{where}: max_speed {float(top):g} rad/s: expected more than the corner speed "
            f"{float(corner):g} rad/s"
        )
    return ActuatorEnvelope(
        peak_torque=float(values["peak_torque"]),
        rated_speed=float(values["rated_speed"]),
        max_speed=float(top),
        corner_speed=float(corner),
        rms_torque=float(values["rms_torque"]),
        duty_cycle=float(values["duty_cycle"]),
        source=source,
    )


@dataclass(frozen=True)
class ActuatorLimits:
    """Per joint envelopes (None: no data for that joint, not constrained nor checked)."""

    joint_names: tuple[str, ...]
    envelopes: tuple[ActuatorEnvelope | None, ...]

    def key(self) -> tuple[Any, ...]:
        """The solver structure: the envelopes' numbers are constants of the NLP's graph."""
        return tuple(self.envelopes)

    def to_dict(self) -> dict[str, Any]:
        return {
            n: None if e is None else e.to_dict()
            for n, e in zip(self.joint_names, self.envelopes, strict=True)
        }

    def constrain(
        self, robot: Robot, goal: Any, grid: Any, cons: Any, tau: Any, free: tuple[int, ...]
    ) -> None:
        """Add the envelopes and RMS limits to an optimal-control problem (``optimal.py``):
        ``grid`` has the point speeds (n, P) and Simpson weights (1, P), ``tau`` is (n, P);
        ``free`` are the joints that move (a held joint's speed is 0: only its peak torque can
        bind). Rows that cannot bind are left out: the peak where the torque limit is lower, the
        speed line where the speed limit stays below the corner."""
        import casadi as ca

        hold = _hold_torques(robot, np.asarray(goal, float))
        duration = grid.T
        keep = 1.0 - LIMIT_MARGIN
        tau_max, qd_max = np.asarray(robot.tau_max), np.asarray(robot.qd_max)
        for j, env in enumerate(self.envelopes):
            if env is None:
                continue
            t, w = tau[j, :], grid.point_qd[j, :]
            if env.peak_torque < tau_max[j]:
                cons.add(t / env.peak_torque, -keep, keep)
            span = env.max_speed - env.corner_speed
            scale = env.peak_torque * env.max_speed
            if j in free and qd_max[j] > env.corner_speed:
                # |τ| <= available(|q̇|) − margin · τ_peak, as four lines in (τ, q̇).
                below = 1.0 - ENVELOPE_MARGIN * span / env.max_speed
                for st in (1.0, -1.0):
                    for sw in (1.0, -1.0):
                        line = st * t * span + sw * env.peak_torque * w
                        cons.add(line / scale, -np.inf, below)
            # ∫τ² + τ_hold² (C − T) <= rms² C, scaled by rms² C; the cycle is at least the motion.
            cycle = ca.fmax(env.duty_cycle, duration)
            heat = ca.dot(grid.weights, t**2) + hold[j] ** 2 * (cycle - duration)
            cons.add(heat / (env.rms_torque**2 * cycle), -np.inf, keep**2)


def _hold_torques(robot: Robot, goal: Any) -> Any:
    q = np.asarray(goal, float)[None, :]
    rest = np.zeros_like(q)
    return np.abs(robot.dynamics().inverse_dynamics(q, rest, rest)[0])


def _row(peak: float, rated: float, top: float, corner: float, rms: float, source: str) -> Any:
    return ActuatorEnvelope(peak, rated, top, corner, rms, 10.0, source)


_SERVO = (
    "assumed: 200 V-class AC servo motors on strain-wave gears: peak torque = the joint's "
    "effort limit, full torque up to {corner} rpm at the motor (rated 3000 rpm) / gear ratio, "
    "none left at the maximum motor speed ({top} rpm) / gear ratio; RMS limit about 40 % of the "
    "peak (strain-"
    "wave gear rated vs repeated-peak torque), over a 10 s cycle (360 lifts per hour)"
)
_MUSCLE = (
    "assumed: Hill's force-velocity relation approximated by a straight line from 20 % of the "
    "maximal shortening speed (= the joint's speed limit) to it; peak = the effort limit "
    "(peak isometric torque); RMS limit about 40 % of it (sustainable share of a maximal "
    "voluntary contraction) over a 10 s cycle"
)
_RPM = 2 * math.pi / 60

#: Built-in robots' actuator limits by robot name, joint order (docs/robots.md).
BUILT_IN: dict[str, tuple[ActuatorEnvelope, ...]] = {
    "curtain_wall_6dof": (
        _row(200, 3000 * _RPM / 160, 5000 * _RPM / 160, 3000 * _RPM / 160, 80,
             _SERVO.format(corner=3000, top=5000)),
        _row(350, 3000 * _RPM / 160, 5000 * _RPM / 160, 3000 * _RPM / 160, 140,
             _SERVO.format(corner=3000, top=5000)),
        _row(200, 3000 * _RPM / 100, 6000 * _RPM / 100, 4000 * _RPM / 100, 80,
             _SERVO.format(corner=4000, top=6000)),
        *(
            _row(peak, 3000 * _RPM / 100, 6000 * _RPM / 100, 4000 * _RPM / 100, 0.4 * peak,
                 _SERVO.format(corner=4000, top=6000))
            for peak in (40.0, 40.0, 25.0)
        ),
    ),
    "human_arm_2dof": (
        _row(100, 2.0, 10.0, 2.0, 40, _MUSCLE),
        _row(80, 3.0, 15.0, 3.0, 32, _MUSCLE),
    ),
}  # fmt: skip


def actuator_limits(robot: Robot) -> ActuatorLimits | None:
    """The robot's actuator limits: its sidecar's ``actuators`` block (user robots), else the
    built-in table; None when there are none (cached on the robot)."""
    key = ("actuator_limits",)
    if key not in robot._cache:
        robot._cache[key] = _actuator_limits(robot)
    cached: ActuatorLimits | None = robot._cache[key]
    return cached


def actuator_violation(robot: Robot, ev: EvaluatedTrajectory) -> str | None:
    """The first actuator limit an evaluated trajectory breaks, or None (none, or no limits)."""
    limits = actuator_limits(robot)
    if limits is None:
        return None
    _, violations = actuator_report(robot, ev, limits)
    return violations[0] if violations else None


def _actuator_limits(robot: Robot) -> ActuatorLimits | None:
    names = tuple(robot.joint_names)
    sidecar = (robot.spec or {}).get("sidecar")
    if sidecar:
        car = read_sidecar(Path(str(sidecar)))
        blocks = getattr(car, "actuators", {}) or {}
        if blocks:
            unknown = sorted(set(blocks) - set(names))
            if unknown:
                raise BioPlanError(
                    f"{car.path.name}: actuators.{unknown[0]} is not a free joint of "
                    f"{robot.name}: expected one of {', '.join(names)}"
                )
            motors = dict(zip(names, robot.motors, strict=True))
            envs = tuple(
                None
                if n not in blocks
                else envelope_from_fields(
                    f"{car.path.name}: actuators.{n}",
                    blocks[n],
                    motors[n],
                    f"sidecar {car.path.name}",
                )
                for n in names
            )
            return ActuatorLimits(names, envs)
    table = BUILT_IN.get(robot.name)
    if table is None or len(table) != len(names) or sidecar:
        return None
    return ActuatorLimits(names, table)


def actuator_report(
    robot: Robot, ev: EvaluatedTrajectory, limits: ActuatorLimits
) -> tuple[dict[str, Any], list[str]]:
    """Each joint's margins to its actuator limits and the violations, named.

    Margins are fractions (1 = unused, 0 = on the limit, < 0 = over it): ``peak_torque``
    1 − max|τ| / τ_peak; ``envelope`` 1 − max over time of |τ| / the torque available at that
    speed; ``speed`` 1 − max|q̇| / ω_max; ``rms`` 1 − τ_rms / the RMS limit over the duty cycle
    (the goal pose held for the rest of it). ``above_rated_s`` is how long the joint runs above
    its rated speed [s].
    """
    tr = ev.trajectory
    hold = _hold_torques(robot, tr.q[-1])
    joints: dict[str, Any] = {}
    violations: list[str] = []
    for j, (name, env) in enumerate(zip(limits.joint_names, limits.envelopes, strict=True)):
        if env is None:
            continue
        tau, w = np.abs(ev.tau[:, j]), np.abs(tr.qd[:, j])
        avail = env.available(w)
        with np.errstate(divide="ignore", invalid="ignore"):
            use = np.where(avail > 0, tau / avail, np.where(tau > 0, np.inf, 0.0))
        k = int(np.argmax(use))
        cycle = max(env.duty_cycle, tr.duration)
        heat = float(np.trapezoid(tau**2, tr.t)) + hold[j] ** 2 * (cycle - tr.duration)
        rms = math.sqrt(heat / cycle)
        dt = np.diff(tr.t)
        above = float(np.sum(dt * ((w[1:] > env.rated_speed) | (w[:-1] > env.rated_speed))))
        margins = {
            "peak_torque": 1.0 - float(tau.max()) / env.peak_torque,
            "envelope": 1.0 - float(use[k]),
            "speed": 1.0 - float(w.max()) / env.max_speed,
            "rms": 1.0 - rms / env.rms_torque,
        }
        joints[name] = {
            "margins": margins,
            "rms_torque": rms,
            "above_rated_s": above,
            "binding_time": float(tr.t[k]),
        }
        if margins["envelope"] < -_TOL:
            violations.append(
                f"joint {name} needs {tau[k]:.1f} Nm at {w[k]:.2f} rad/s (t={tr.t[k]:.3f} s) but "
                f"its actuator gives {avail[k]:.1f} Nm there (torque-speed envelope)"
            )
        if margins["rms"] < -_TOL:
            violations.append(
                f"joint {name} RMS torque {rms:.1f} Nm over a {cycle:g} s cycle exceeds its "
                f"{env.rms_torque:g} Nm thermal limit"
            )
    return {"joints": joints, "violations": violations}, violations


def plan_actuators(robot: Robot, methods: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """Every method's margins to the robot's actuator limits (``PlanResult.actuators``) and the
    violations as warnings naming the method and joint; ``({}, [])`` without limits."""
    limits = actuator_limits(robot)
    if limits is None:
        return {}, []
    report: dict[str, Any] = {"limits": limits.to_dict(), "methods": {}}
    warnings: list[str] = []
    for name, method in methods.items():
        margins, violations = actuator_report(robot, method.evaluated, limits)
        report["methods"][name] = margins
        warnings += [f"{name}: {v}" for v in violations]
    return report, warnings
