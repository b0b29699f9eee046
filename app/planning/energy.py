"""Energy metrics of a joint trajectory, their physical floors, and the motor model.

All metrics take the joint velocities q̇ and the joint-side torques τ on a time grid (τ from the
rigid-body dynamics, armature included, as the dynamics module returns it) and integrate with the
trapezoidal rule (DESIGN.md, "Energy metrics"):

- ``tau_sq`` = ∫ Σ_j τ_j² dt [N²m²s]
- ``abs_work`` = ∫ Σ_j |τ_j q̇_j| dt [J] (no regeneration)
- ``pos_work`` = ∫ Σ_j max(τ_j q̇_j, 0) dt [J]
- ``electrical_energy`` [J], see :func:`electrical_power`
- ``peak_power`` = max_t Σ_j |τ_j q̇_j| [W]
- ``peak_torque`` = max_t |τ_j| per joint [Nm]

Floors (:class:`Floors`): no rest-to-rest motion does less absolute work than |ΔPE| (lifting
takes ΔPE, lowering must absorb −ΔPE), less positive work than max(ΔPE, 0), or has a lower peak
of Σ|τq̇| than |ΔPE| / T; with motor friction, the friction work no motion avoids adds to the
electrical floor.

Electrical model (per joint j, joint side): friction τ_f = b q̇ + c tanh(q̇ / ε) with
ε = :data:`FRICTION_VELOCITY_SCALE` (a smooth Coulomb term, so PSO sees a smooth cost), motor
torque τ_m = (τ + τ_f) / N, current i = τ_m / k_t, electrical power
P_j = (τ + τ_f) q̇ + R i² (mechanical power at the motor shaft, N q̇ · τ_m, plus copper loss).
The joints share one DC bus, P_bus = Σ_j P_j; the energy drawn is
∫ max(P_bus, 0) dt − η ∫ max(−P_bus, 0) dt with η the smallest regeneration efficiency of the
joints (the bus can only recover what its worst converter passes back). The rotor inertia is
not added here: it belongs in τ as armature.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app import names
from app.errors import BioPlanError

FloatArray = NDArray[np.float64]

#: The metrics PSO can minimise (see :func:`objective_values`); defined in ``app.names``.
OBJECTIVES: tuple[str, ...] = names.OBJECTIVES

#: ε in the smooth Coulomb friction c tanh(q̇ / ε) [rad/s]: above 3ε (0.03 rad/s, 1.7 deg/s)
#: it is within 0.5 % of c sign(q̇).
FRICTION_VELOCITY_SCALE = 0.01


@dataclass(frozen=True)
class MotorModel:
    """A joint's motor and gearbox, seen from the joint side.

    Attributes:
        gear_ratio: motor turns per joint turn (N, dimensionless, >= 1).
        torque_constant: motor torque constant k_t [Nm/A].
        winding_resistance: motor winding resistance R [ohm].
        rotor_inertia: rotor (+ gearbox input) inertia at the motor shaft [kg m^2]; the joint
            sees N^2 times this as armature.
        viscous_friction: viscous friction at the joint [Nm s/rad].
        coulomb_friction: Coulomb friction at the joint [Nm].
        regen_efficiency: fraction of negative (generated) electrical power recovered, in [0, 1].
        modelled: False for :data:`NOT_MODELLED`, the placeholder of a robot whose motors are
            unknown (a user URDF without a sidecar): its joint torques are produced without
            loss or armature, and every electrical quantity is reported as not modelled.
    """

    gear_ratio: float
    torque_constant: float
    winding_resistance: float
    rotor_inertia: float
    viscous_friction: float
    coulomb_friction: float
    regen_efficiency: float = 0.0
    modelled: bool = True

    @property
    def armature(self) -> float:
        """Reflected rotor inertia at the joint, N^2 J_m [kg m^2]."""
        return self.gear_ratio**2 * self.rotor_inertia


#: A lossless direct drive: the joint torque is produced without copper loss, friction,
#: reflected inertia or recovery. Used for the human arm (muscles are not motors) and the
#: two-link reference arm.
IDEAL_ACTUATOR = MotorModel(
    gear_ratio=1.0,
    torque_constant=1.0,
    winding_resistance=0.0,
    rotor_inertia=0.0,
    viscous_friction=0.0,
    coulomb_friction=0.0,
    regen_efficiency=0.0,
)

#: The motor of a joint whose drive is unknown: dynamically the same as
#: :data:`IDEAL_ACTUATOR` (no armature, no friction), but its electrical quantities are
#: reported as not modelled (NaN in arrays and metrics, ``None`` in JSON).
NOT_MODELLED = replace(IDEAL_ACTUATOR, modelled=False)


def motors_modelled(motors: Sequence[MotorModel] | None) -> bool:
    """True unless some motor is :data:`NOT_MODELLED` (``None`` means ideal actuators)."""
    return motors is None or all(m.modelled for m in motors)


@dataclass(frozen=True)
class EnergyMetrics:
    """The energy metrics of one trajectory (DESIGN.md).

    Attributes:
        tau_sq: ∫ Σ τ² dt [N²m²s].
        abs_work: ∫ Σ |τ q̇| dt [J].
        pos_work: ∫ Σ max(τ q̇, 0) dt [J].
        electrical_energy: energy drawn from the DC bus [J] (motor model; ideal actuators when
            no motors are given); NaN when the robot's motors are not modelled (``to_dict``
            keeps the NaN, ``json_safe`` writes it as ``null``; tables say "not modelled").
        peak_power: max over time of Σ |τ q̇| [W].
        peak_torque: (n,) max over time of |τ_j| per joint [Nm].
    """

    tau_sq: float
    abs_work: float
    pos_work: float
    electrical_energy: float
    peak_power: float
    peak_torque: tuple[float, ...]

    def to_dict(self) -> dict[str, float | list[float]]:
        """Plain JSON-ready values; ``peak_torque`` becomes a list."""
        out: dict[str, float | list[float]] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = [float(v) for v in value] if isinstance(value, tuple) else float(value)
        return out


#: Metrics with no physical floor: ``Floors.to_dict`` names them with the value None.
NO_FLOOR: tuple[str, ...] = ("tau_sq", "peak_torque", "torque_change")

#: Each metric's floor said plainly, for results, the CLI and the page ("no floor" where none
#: exists; the peak-power floor is loose, so the optimal-control bound is its reference).
FLOOR_NOTES: dict[str, str] = {
    "abs_work": "|ΔPE|: tight (a lift takes it, a lowering must absorb it)",
    "pos_work": "max(ΔPE, 0): tight",
    "electrical_energy": "ΔPE + the friction work no motion avoids (η times it when negative)",
    "peak_power": (
        "|ΔPE|/T: loose (no rest-to-rest motion holds its mean power from start to end); "
        "the bound is the reference"
    ),
    "tau_sq": "no floor",
    "peak_torque": "no floor",
    "torque_change": "no floor",
}


@dataclass(frozen=True)
class Floors:
    """Physical lower bounds of the metrics of a rest-to-rest motion.

    The work floors are tight; the peak-power floor |ΔPE|/T is loose (the optimal-control bound
    is the reference there); ``tau_sq``, ``peak_torque`` and ``torque_change`` have no floor
    (:data:`NO_FLOOR`, None in :meth:`to_dict`).

    Attributes:
        delta_potential: ΔPE = PE(goal) − PE(start) [J], signed (negative when lowering).
        min_peak_power: |ΔPE| / T [W]: the mean of Σ|τq̇| is at least |∫Στq̇ dt| / T.
        abs_work: |ΔPE| [J]: lifting takes at least ΔPE, lowering absorbs at least −ΔPE.
        pos_work: max(ΔPE, 0) [J].
        peak_power: |ΔPE| / T [W] (the same as ``min_peak_power``, under the metric's name).
        friction_energy: friction work no motion of the task avoids [J] (0 without friction):
            Σ_j b_j Δq_j² / T (viscous, least at constant speed) + c_j |Δq_j| (Coulomb), less
            the smooth Coulomb law's largest shortfall 0.2785 c_j ε T.
        electrical_energy: F = ΔPE + friction_energy when F >= 0, else η F [J]: the bus energy
            is at least ∫P_bus dt >= F, and at least η ∫P_bus dt (η = regeneration efficiency).
    """

    delta_potential: float
    min_peak_power: float
    abs_work: float = 0.0
    pos_work: float = 0.0
    peak_power: float = 0.0
    friction_energy: float = 0.0
    electrical_energy: float = 0.0

    def to_dict(self) -> dict[str, float | None]:
        """Every floor [SI]; the metrics of :data:`NO_FLOOR` with None ("no floor")."""
        out: dict[str, float | None] = {f.name: float(getattr(self, f.name)) for f in fields(self)}
        out.update(dict.fromkeys(NO_FLOOR))
        return out


#: max over x of |x| (1 − tanh(|x| / ε)) / ε: how far the smooth Coulomb law's work can fall
#: short of c |q̇| per unit time and per unit ε (at |x| ≈ 0.64 ε).
_SMOOTH_COULOMB_SHORTFALL = 0.2785


def friction_energy_floor(
    motors: Sequence[MotorModel] | None, delta_q: ArrayLike, duration: float
) -> float:
    """Friction work [J] that no rest-to-rest motion of stroke ``delta_q`` in ``duration`` avoids.

    Args:
        motors: (n,) motor models (None: ideal actuators, no friction).
        delta_q: (n,) joint strokes q_goal − q_start [rad].
        duration: T [s].
    """
    if motors is None:
        return 0.0
    dq = np.abs(np.asarray(delta_q, dtype=np.float64))
    total = 0.0
    for m, d in zip(motors, dq, strict=True):
        coulomb = m.coulomb_friction * (
            d - _SMOOTH_COULOMB_SHORTFALL * FRICTION_VELOCITY_SCALE * duration
        )
        total += m.viscous_friction * d * d / duration + max(coulomb, 0.0)
    return float(total)


def floors(
    delta_potential: float,
    duration: float,
    *,
    friction_energy: float = 0.0,
    regen_efficiency: float = 0.0,
) -> Floors:
    """The floors of a rest-to-rest motion that changes the potential energy by ΔPE in T.

    Args:
        delta_potential: ΔPE [J] (negative for a lowering motion).
        duration: T [s], > 0.
        friction_energy: unavoidable friction work [J] (:func:`friction_energy_floor`).
        regen_efficiency: the bus's regeneration efficiency η in [0, 1].

    Returns:
        The floors (see :class:`Floors`).
    """
    dpe = float(delta_potential)
    t = float(duration)
    if not math.isfinite(dpe):
        raise BioPlanError(f"delta_potential must be a finite energy [J], got {delta_potential!r}")
    if not (math.isfinite(t) and t > 0.0):
        raise BioPlanError(f"duration must be a finite number of seconds > 0, got {duration!r}")
    if not (math.isfinite(friction_energy) and friction_energy >= 0.0):
        raise BioPlanError(f"friction_energy must be >= 0 J, got {friction_energy!r}")
    if not 0.0 <= regen_efficiency <= 1.0:
        raise BioPlanError(f"regen_efficiency must lie in [0, 1], got {regen_efficiency!r}")
    bus = dpe + float(friction_energy)
    return Floors(
        delta_potential=dpe,
        min_peak_power=abs(dpe) / t,
        abs_work=abs(dpe),
        pos_work=max(dpe, 0.0),
        peak_power=abs(dpe) / t,
        friction_energy=float(friction_energy),
        electrical_energy=bus if bus >= 0.0 else regen_efficiency * bus + 0.0,
    )


def task_floors(
    dynamics_pe: tuple[float, float],
    delta_q: ArrayLike,
    duration: float,
    motors: Sequence[MotorModel] | None,
) -> Floors:
    """The floors of a task from the potential energies at start and goal [J], the strokes
    (n,) [rad], the duration [s] and the motors."""
    eta = min((float(m.regen_efficiency) for m in motors), default=0.0) if motors else 0.0
    return floors(
        dynamics_pe[1] - dynamics_pe[0],
        duration,
        friction_energy=friction_energy_floor(motors, delta_q, duration),
        regen_efficiency=eta,
    )


# ----------------------------------------------------------------------------------------------
# Input checks
# ----------------------------------------------------------------------------------------------


def _check_time(t: ArrayLike) -> FloatArray:
    tt = np.asarray(t, dtype=np.float64)
    if tt.ndim != 1 or tt.size < 2:
        raise BioPlanError(f"t must be a 1-D array of at least 2 times [s], got shape {tt.shape}")
    if not (np.all(np.isfinite(tt)) and np.all(np.diff(tt) > 0.0)):
        raise BioPlanError("t must be finite and strictly increasing [s]")
    return tt


def _check_pair(qd: ArrayLike, tau: ArrayLike, n_t: int | None = None) -> tuple[FloatArray, ...]:
    v = np.asarray(qd, dtype=np.float64)
    f = np.asarray(tau, dtype=np.float64)
    if v.ndim < 2 or v.shape != f.shape:
        raise BioPlanError(
            f"qd and tau must have the same shape (..., T, n), got {v.shape} and {f.shape}"
        )
    if n_t is not None and v.shape[-2] != n_t:
        raise BioPlanError(
            f"qd and tau have {v.shape[-2]} samples along axis -2 but t has {n_t} "
            "(expected shape (..., T, n))"
        )
    return v, f


def _motor_arrays(motors: Sequence[MotorModel], n: int) -> tuple[FloatArray, ...]:
    if len(motors) != n:
        raise BioPlanError(f"expected one MotorModel per joint ({n}), got {len(motors)}")
    gear = np.array([m.gear_ratio for m in motors], dtype=np.float64)
    kt = np.array([m.torque_constant for m in motors], dtype=np.float64)
    res = np.array([m.winding_resistance for m in motors], dtype=np.float64)
    visc = np.array([m.viscous_friction for m in motors], dtype=np.float64)
    coul = np.array([m.coulomb_friction for m in motors], dtype=np.float64)
    eta = np.array([m.regen_efficiency for m in motors], dtype=np.float64)
    if not (np.all(gear > 0) and np.all(kt > 0)):
        raise BioPlanError("every motor needs gear_ratio > 0 and torque_constant > 0 [Nm/A]")
    if np.any(res < 0) or np.any(visc < 0) or np.any(coul < 0):
        raise BioPlanError("winding resistance and friction coefficients must be >= 0")
    if np.any((eta < 0) | (eta > 1)):
        raise BioPlanError(f"regen_efficiency must lie in [0, 1], got {eta.tolist()}")
    return gear, kt, res, visc, coul, eta


def _joint_sum(x: FloatArray) -> FloatArray:
    """Sum over the joint axis (..., T, n) -> (..., T). A product with ones: numpy's reduction
    over a short last axis is several times slower, and this is the PSO's inner loop."""
    result: FloatArray = x @ np.ones(x.shape[-1])
    return result


def _integrate(tt: FloatArray, y: FloatArray) -> FloatArray:
    """Trapezoidal integral over the last axis, (..., T) -> (...,), as one dot product with the
    trapezoid weights (equal to ``np.trapezoid`` up to round-off, and faster on batches)."""
    dt = np.diff(tt)
    weights = np.zeros(tt.size)
    weights[:-1] += 0.5 * dt
    weights[1:] += 0.5 * dt
    result: FloatArray = y @ weights
    return result


# ----------------------------------------------------------------------------------------------
# Curves over time
# ----------------------------------------------------------------------------------------------


def joint_power(qd: ArrayLike, tau: ArrayLike) -> FloatArray:
    """Mechanical power per joint, τ_j q̇_j.

    Args:
        qd: (..., T, n) joint velocities [rad/s].
        tau: (..., T, n) joint torques [Nm].

    Returns:
        (..., T, n) power [W]; positive when the actuator does work on the arm.
    """
    v, f = _check_pair(qd, tau)
    result: FloatArray = v * f
    return result


def power_curve(qd: ArrayLike, tau: ArrayLike) -> FloatArray:
    """Total absolute mechanical power Σ_j |τ_j q̇_j| (the curve under ``abs_work``).

    Args:
        qd: (..., T, n) joint velocities [rad/s].
        tau: (..., T, n) joint torques [Nm].

    Returns:
        (..., T) power [W].
    """
    v, f = _check_pair(qd, tau)
    return _joint_sum(np.abs(v * f))


def _electrical_power(
    v: FloatArray, f: FloatArray, motors: Sequence[MotorModel] | None
) -> tuple[FloatArray, float]:
    """Bus power (..., T) and the regeneration efficiency used for it."""
    if motors is None:
        return _joint_sum(v * f), 0.0
    if not motors_modelled(motors):
        return np.full(v.shape[:-1], np.nan), 0.0
    gear, kt, res, visc, coul, eta = _motor_arrays(motors, v.shape[-1])
    total = f + visc * v + coul * np.tanh(v / FRICTION_VELOCITY_SCALE)
    current = total / (gear * kt)
    return _joint_sum(total * v + res * current * current), float(eta.min())


def electrical_power(
    qd: ArrayLike, tau: ArrayLike, motors: Sequence[MotorModel] | None = None
) -> FloatArray:
    """Electrical power on the shared DC bus, P_bus = Σ_j [(τ_j + τ_f,j) q̇_j + R_j i_j²].

    See the module docstring for the model. ``motors=None`` means ideal actuators (N = 1,
    R = 0, no friction), so P_bus = Σ_j τ_j q̇_j.

    Args:
        qd: (..., T, n) joint velocities [rad/s].
        tau: (..., T, n) joint-side torques [Nm] (rigid body incl. armature).
        motors: (n,) one motor model per joint, or None.

    Returns:
        (..., T) bus power [W]; negative while the joints generate.
    """
    v, f = _check_pair(qd, tau)
    power, _ = _electrical_power(v, f, motors)
    result: FloatArray = power
    return result


def cumulative_energy(t: ArrayLike, power: ArrayLike) -> FloatArray:
    """Running integral of a power curve (trapezoidal rule), starting at 0.

    Args:
        t: (T,) sample times [s].
        power: (..., T) power [W].

    Returns:
        (..., T) energy [J]; the last sample equals ``np.trapezoid(power, t)``.
    """
    tt = _check_time(t)
    p = np.asarray(power, dtype=np.float64)
    if p.ndim < 1 or p.shape[-1] != tt.size:
        raise BioPlanError(f"power must have shape (..., {tt.size}) to match t, got {p.shape}")
    steps = 0.5 * (p[..., 1:] + p[..., :-1]) * np.diff(tt)
    out = np.zeros(p.shape, dtype=np.float64)
    np.cumsum(steps, axis=-1, out=out[..., 1:])
    return out


# ----------------------------------------------------------------------------------------------
# Scalar metrics
# ----------------------------------------------------------------------------------------------


def _bus_energy(tt: FloatArray, p_bus: FloatArray, eta: float) -> FloatArray:
    drawn = np.maximum(p_bus, 0.0)
    if eta > 0.0:
        drawn = drawn - eta * np.maximum(-p_bus, 0.0)
    return _integrate(tt, drawn)


def objective_values(
    objective: str,
    t: ArrayLike,
    qd: ArrayLike,
    tau: ArrayLike,
    *,
    motors: Sequence[MotorModel] | None = None,
    tau_max: ArrayLike | None = None,
) -> FloatArray:
    """One scalar metric for a batch of trajectories (the PSO cost).

    ``"peak_torque"`` as an objective is one number per trajectory: the largest torque relative
    to its joint's limit, max_{t, j} |τ_j| / tau_max_j (dimensionless), or max_{t, j} |τ_j| [Nm]
    when ``tau_max`` is None. The other objectives are the metrics of :class:`EnergyMetrics`.

    Args:
        objective: one of :data:`OBJECTIVES`.
        t: (T,) sample times [s].
        qd: (..., T, n) joint velocities [rad/s].
        tau: (..., T, n) joint torques [Nm].
        motors: (n,) motor models for ``"electrical_energy"``; None means ideal actuators.
        tau_max: (n,) torque limits [Nm] > 0 for ``"peak_torque"``.

    Returns:
        (...,) the metric per trajectory.

    Raises:
        ValueError: unknown objective (the message lists the valid ones) or bad shapes.
    """
    if objective not in OBJECTIVES:
        raise BioPlanError(
            f"unknown objective {objective!r}; expected one of: {', '.join(OBJECTIVES)}"
        )
    tt = _check_time(t)
    v, f = _check_pair(qd, tau, tt.size)
    result: FloatArray
    if objective == "tau_sq":
        result = _integrate(tt, _joint_sum(f * f))
    elif objective == "abs_work":
        result = _integrate(tt, _joint_sum(np.abs(v * f)))
    elif objective == "pos_work":
        result = _integrate(tt, _joint_sum(np.maximum(v * f, 0.0)))
    elif objective == "electrical_energy":
        if not motors_modelled(motors):
            raise BioPlanError(
                "objective electrical_energy needs a motor model, and this robot's motors are not "
                "modelled: expected a sidecar with motors (docs/robots.md) or another objective"
            )
        p_bus, eta = _electrical_power(v, f, motors)
        result = _bus_energy(tt, p_bus, eta)
    elif objective == "peak_power":
        result = _joint_sum(np.abs(v * f)).max(axis=-1)
    else:  # peak_torque
        mag = np.abs(f)
        if tau_max is not None:
            lim = np.asarray(tau_max, dtype=np.float64)
            if lim.shape != (f.shape[-1],) or not np.all(lim > 0.0):
                raise BioPlanError(
                    f"tau_max must be ({f.shape[-1]},) positive torque limits [Nm], got {lim}"
                )
            mag = mag / lim
        result = mag.max(axis=(-2, -1))
    return result


def energy_metrics(
    t: ArrayLike,
    qd: ArrayLike,
    tau: ArrayLike,
    *,
    motors: Sequence[MotorModel] | None = None,
) -> EnergyMetrics:
    """All metrics of one trajectory.

    Args:
        t: (T,) sample times [s].
        qd: (T, n) joint velocities [rad/s].
        tau: (T, n) joint torques [Nm] (rigid body incl. armature).
        motors: (n,) one motor model per joint; None means ideal actuators, for which
            ``electrical_energy`` = ∫ max(Σ_j τ_j q̇_j, 0) dt.

    Returns:
        The metrics.
    """
    tt = _check_time(t)
    v, f = _check_pair(qd, tau, tt.size)
    if v.ndim != 2:
        raise BioPlanError(f"qd and tau must have shape (T, n) for one trajectory, got {v.shape}")
    p = v * f
    p_bus, eta = _electrical_power(v, f, motors)
    abs_power = _joint_sum(np.abs(p))
    return EnergyMetrics(
        tau_sq=float(_integrate(tt, _joint_sum(f * f))),
        abs_work=float(_integrate(tt, abs_power)),
        pos_work=float(_integrate(tt, _joint_sum(np.maximum(p, 0.0)))),
        electrical_energy=float(_bus_energy(tt, p_bus, eta)),
        peak_power=float(abs_power.max()),
        peak_torque=tuple(float(x) for x in np.abs(f).max(axis=0)),
    )


def improvement_pct(
    standard: EnergyMetrics, optimized: EnergyMetrics
) -> dict[str, float | list[float]]:
    """Relative saving per metric, 100 (standard − optimized) / |standard| [%].

    Positive means the optimised one is lower (saves). Dividing by |standard| keeps that sign
    meaning when a standard value is negative (net regeneration). When the standard value is 0
    the result is 0.0 if the optimised one is 0 too and NaN otherwise (no relative change is
    defined); no exception and no numpy warning either way.

    Args:
        standard: metrics of the reference (e.g. the quintic) trajectory.
        optimized: metrics of the optimised trajectory.

    Returns:
        Metric name -> percent; ``peak_torque`` is a per-joint list.
    """

    def pct(s: float, o: float) -> float:
        if s == 0.0:
            return 0.0 if o == 0.0 else math.nan
        return 100.0 * (s - o) / abs(s)

    out: dict[str, float | list[float]] = {}
    for f in fields(EnergyMetrics):
        s_val = getattr(standard, f.name)
        o_val = getattr(optimized, f.name)
        if isinstance(s_val, tuple):
            if len(s_val) != len(o_val):
                raise BioPlanError(
                    f"{f.name} has {len(s_val)} joints in standard but {len(o_val)} in optimized"
                )
            out[f.name] = [pct(a, b) for a, b in zip(s_val, o_val, strict=True)]
        else:
            out[f.name] = pct(s_val, o_val)
    return out
