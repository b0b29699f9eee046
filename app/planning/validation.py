"""Validation: the torques a robot model predicts for a logged motion against the measured ones.

The log is matched to the robot's joints and filtered with the zero-phase filter of
:func:`app.planning.identification.filter_motion` (no delay); the model's torque is Pinocchio's
RNEA on the filtered positions, speeds and accelerations (payload and armature included) plus
the motors' friction b q̇ + c tanh(q̇/ε) (its Coulomb step passed through the same filter as the
measurement) and the sidecar's torque offsets. Two cutoff periods are trimmed at each end (the
filter's edge transients).

With a plan (``bioplan plan --json --out``), the log is aligned in time to each planned method by
cross-correlating joint speeds, the method it tracks best is taken as the one executed, and the
tracking error and the measured against the predicted saving are reported.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app.planning.energy import FRICTION_VELOCITY_SCALE, energy_metrics
from app.planning.identification import (
    DEFAULT_CUTOFF_HZ,
    FilteredMotion,
    IdentificationError,
    filter_motion,
    torque_fit,
)

if TYPE_CHECKING:
    from app.planning.robots import Robot
    from app.recordings.robot_logs import RobotLog

__all__ = ["ValidateOptions", "Validation", "align_to_plan", "validate"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ValidateOptions:
    """Options of ``bioplan validate``.

    Attributes:
        cutoff_hz: zero-phase low-pass cutoff [Hz] of positions, speeds and torques.
    """

    cutoff_hz: float = DEFAULT_CUTOFF_HZ

    def __post_init__(self) -> None:
        if not (math.isfinite(self.cutoff_hz) and self.cutoff_hz > 0.0):
            raise IdentificationError(f"cutoff_hz is {self.cutoff_hz}: expected a value > 0 Hz")


@dataclass
class Validation:
    """Measured against predicted torque (see the module docstring).

    Attributes:
        result: the JSON-ready result (``joints``, ``abs_work``, ``filter``, ...).
        t: (T,) times [s]; measured, predicted: (T, n) torques [Nm]; qd: (T, n) [rad/s].
    """

    result: dict[str, Any]
    t: FloatArray
    measured: FloatArray
    predicted: FloatArray
    qd: FloatArray
    joint_names: tuple[str, ...]


def _offsets(robot: Robot) -> FloatArray:
    """The sidecar's torque offsets per joint [Nm] (zeros without one)."""
    path = robot.spec.get("sidecar") if robot.spec else None
    out = np.zeros(robot.n_joints)
    if not path:
        return out
    from app.planning.robots import read_sidecar

    friction = getattr(read_sidecar(path), "friction", {})
    for j, name in enumerate(robot.joint_names):
        if name in friction:
            out[j] = friction[name].offset
    return out


def model_torque(robot: Robot, motion: FilteredMotion) -> FloatArray:
    """(T, n) joint torque the robot model predicts for a filtered motion [Nm]."""
    rigid = robot.dynamics().inverse_dynamics(motion.q, motion.qd, motion.qdd)
    viscous = np.array([m.viscous_friction for m in robot.motors])
    coulomb = np.array([m.coulomb_friction for m in robot.motors])
    sign = np.tanh(motion.qd / FRICTION_VELOCITY_SCALE) if motion.sign is None else motion.sign
    friction = viscous * motion.qd + coulomb * sign
    result: FloatArray = rigid + friction + _offsets(robot)
    return result


def _trim(motion: FilteredMotion) -> slice:
    rate = (motion.t.size - 1) / (motion.t[-1] - motion.t[0])
    edge = min(int(2.0 * rate / motion.cutoff_hz), motion.t.size // 10)
    return slice(edge, motion.t.size - edge)


def _abs_work(t: FloatArray, tau: FloatArray, qd: FloatArray) -> float:
    power = np.sum(np.abs(tau * qd), axis=1)
    return float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(t)))


def _electrical(
    robot: Robot, t: FloatArray, qd: FloatArray, current: FloatArray, predicted_rigid: FloatArray
) -> dict[str, float] | None:
    """Bus energy from the logged currents and from the model [J]; None when not modelled."""
    if not robot.motors_modelled:
        return None
    gear = np.array([m.gear_ratio for m in robot.motors])
    kt = np.array([m.torque_constant for m in robot.motors])
    resistance = np.array([m.winding_resistance for m in robot.motors])
    eta = min(m.regen_efficiency for m in robot.motors)
    bus = np.sum(gear * kt * current * qd + resistance * current**2, axis=1)
    drawn = np.maximum(bus, 0.0) - eta * np.maximum(-bus, 0.0)
    measured = float(np.sum(0.5 * (drawn[1:] + drawn[:-1]) * np.diff(t)))
    predicted = energy_metrics(t, qd, predicted_rigid, motors=robot.motors).electrical_energy
    return {"measured": measured, "predicted": float(predicted)}


def validate(
    robot: Robot,
    log: RobotLog,
    *,
    options: ValidateOptions | None = None,
    plan: str | Path | None = None,
) -> Validation:
    """Compare the model's torque with the log's (and the log with a plan, when given).

    Args:
        robot: the robot (with its sidecar: motors, identified links and friction).
        log: a robot log with joint torques (or currents and a sidecar's motors).
        options: see :class:`ValidateOptions`.
        plan: a ``bioplan plan --json --out`` result file.

    Returns:
        The comparison; ``result`` is JSON-ready.

    Raises:
        IdentificationError: a log without torques, a bad plan file.
        RecordingError: the log's joints do not match the robot's.
    """
    options = options or ValidateOptions()
    matched = log.matched(robot.joint_names, motors=robot.motors)
    if matched.effort is None:
        raise IdentificationError(
            f"{log.path.name}: no joint torque (effort, target_moment, or currents with a "
            "sidecar's motors): expected measured torques to validate against"
        )
    motion = filter_motion(matched, options.cutoff_hz)
    keep = _trim(motion)
    predicted_all = model_torque(robot, motion)
    assert motion.tau is not None
    t, qd = motion.t[keep], motion.qd[keep]
    measured, predicted = motion.tau[keep], predicted_all[keep]
    result: dict[str, Any] = {
        "robot": robot.name,
        "log": {
            "file": log.path.name,
            "format": log.format,
            "samples": log.n_samples,
            "rate_hz": log.rate,
            "duration_s": log.duration,
            "notes": list(matched.notes),
        },
        "filter": {
            "kind": "Butterworth order 4, zero-phase (sosfiltfilt)",
            "cutoff_hz": options.cutoff_hz,
            "delay_s": 0.0,
            "trimmed_s": float(motion.t[keep.start] - motion.t[0]),
        },
        "units": {"torque": "Nm", "work": "J", "power": "W"},
        "joints": torque_fit(measured, predicted, robot.joint_names),
        "abs_work": {
            "measured": _abs_work(t, measured, qd),
            "predicted": _abs_work(t, predicted, qd),
        },
    }
    if matched.current is not None:
        # The electrical model adds the motors' friction itself: give it the rigid-body torque.
        rigid = robot.dynamics().inverse_dynamics(motion.q[keep], motion.qd[keep], motion.qdd[keep])
        electrical = _electrical(robot, t, qd, _lowpassed_current(matched, motion)[keep], rigid)
        if electrical is not None:
            result["electrical_energy"] = electrical
    if plan is not None:
        result["plan"] = align_to_plan(plan, robot, motion, predicted_all)
    return Validation(
        result=result,
        t=t,
        measured=measured,
        predicted=predicted,
        qd=qd,
        joint_names=tuple(robot.joint_names),
    )


def _lowpassed_current(log: RobotLog, motion: FilteredMotion) -> FloatArray:
    from app.planning.identification import _lowpass

    assert log.current is not None
    return _lowpass(log.current, log.rate, motion.cutoff_hz)


# -- plans ---------------------------------------------------------------------------------


def _read_plan(path: Path, robot: Robot) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise IdentificationError(
            f"{path.name}: cannot be read as JSON ({exc}): expected a `bioplan plan --json "
            "--out` result"
        ) from None
    motion = data.get("motion") if isinstance(data, dict) else None
    if not isinstance(motion, dict) or not isinstance(motion.get("methods"), dict):
        raise IdentificationError(
            f"{path.name}: no 'motion' block: expected a `bioplan plan --json --out` result"
        )
    names = motion.get("joint_names")
    if names != list(robot.joint_names):
        raise IdentificationError(
            f"{path.name}: the plan's joints {names} are not the robot's "
            f"{list(robot.joint_names)}: expected a plan of this robot"
        )
    return motion


def _on_grid(t_plan: FloatArray, q_plan: FloatArray, grid: FloatArray) -> FloatArray:
    """Plan positions on ``grid`` (held at start before 0 and at the goal after the end)."""
    return np.stack([np.interp(grid, t_plan, q_plan[:, j]) for j in range(q_plan.shape[1])], 1)


def _shift(t: FloatArray, qd_log: FloatArray, t_plan: FloatArray, q_plan: FloatArray) -> float:
    """Time [s] at which the plan starts in the log: cross-correlation of joint speeds."""
    dt = float(t[1] - t[0])
    grid = np.arange(0.0, t_plan[-1] + dt, dt)
    qd_plan = np.gradient(_on_grid(t_plan, q_plan, grid), dt, axis=0)
    size = t.size + grid.size
    spectrum = np.zeros(size // 2 + 1, dtype=complex)
    for j in range(q_plan.shape[1]):
        spectrum += np.fft.rfft(qd_log[:, j], size) * np.conj(np.fft.rfft(qd_plan[:, j], size))
    corr = np.fft.irfft(spectrum, size)
    lags = np.arange(size)
    lags[lags > size // 2] -= size
    valid = (lags >= 0) & (lags <= t.size - 1)
    corr_valid = np.where(valid, corr, -np.inf)
    k = int(np.argmax(corr_valid))
    offset = 0.0
    if valid[k - 1] and valid[(k + 1) % size]:
        a, b, c = corr[k - 1], corr[k], corr[(k + 1) % size]
        denominator = a - 2.0 * b + c
        if denominator < 0.0:
            offset = 0.5 * (a - c) / denominator
    return float(t[0] + (lags[k] + offset) * dt)


def align_to_plan(
    path: str | Path, robot: Robot, motion: FilteredMotion, predicted: FloatArray
) -> dict[str, Any]:
    """The log aligned to the plan's methods; the tracked one's error and savings."""
    plan = _read_plan(Path(path), robot)
    assert motion.tau is not None
    best: dict[str, Any] | None = None
    for name, method in plan["methods"].items():
        t_plan = np.asarray(method["t"], dtype=np.float64)
        q_plan = np.asarray(method["q"], dtype=np.float64)
        shift = _shift(motion.t, motion.qd, t_plan, q_plan)
        inside = (motion.t >= shift) & (motion.t <= shift + t_plan[-1])
        if inside.sum() < 3:
            continue
        error = motion.q[inside] - _on_grid(t_plan, q_plan, motion.t[inside] - shift)
        rms = np.sqrt(np.mean(error**2, axis=0))
        candidate = {
            "method": name,
            "time_shift_s": shift,
            "tracking_error_rms_rad": dict(zip(robot.joint_names, rms.tolist(), strict=True)),
            "tracking_error_max_rad": dict(
                zip(robot.joint_names, np.abs(error).max(axis=0).tolist(), strict=True)
            ),
            "_score": float(np.mean(rms)),
            "_inside": inside,
        }
        if best is None or candidate["_score"] < best["_score"]:
            best = candidate
    if best is None:
        raise IdentificationError(
            f"{Path(path).name}: no planned motion overlaps the log: expected a log of the plan"
        )
    inside = best.pop("_inside")
    best.pop("_score")
    t, qd = motion.t[inside], motion.qd[inside]
    measured = _abs_work(t, motion.tau[inside], qd)
    modelled = _abs_work(t, predicted[inside], qd)
    metrics = {name: m.get("metrics", {}) for name, m in plan["methods"].items()}
    planned = metrics[best["method"]].get("abs_work")
    standard = metrics.get("quintic", {}).get("abs_work")
    best["abs_work"] = {"planned": planned, "measured": measured, "predicted": modelled}
    if standard:
        best["saving_pct"] = {
            "planned": None if planned is None else 100.0 * (standard - planned) / standard,
            "measured": 100.0 * (standard - measured) / standard,
            "reference": "the plan's predicted quintic abs_work (no log of the quintic given)",
        }
    return best


def plot_validation(validation: Validation, folder: str | Path) -> list[Path]:
    """Measured against predicted torque per joint, the residuals and the power, as plotly HTML.

    Returns:
        The files written (``torque.html``, ``power.html``).
    """
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    names = validation.joint_names
    figure = make_subplots(
        rows=len(names), cols=2, shared_xaxes=True,
        subplot_titles=[f"{n} {k}" for n in names for k in ("torque [Nm]", "residual [Nm]")],
    )  # fmt: skip
    t = validation.t
    for j, name in enumerate(names):
        row = j + 1
        figure.add_trace(
            go.Scatter(x=t, y=validation.measured[:, j], name=f"{name} measured"), row, 1
        )
        figure.add_trace(
            go.Scatter(x=t, y=validation.predicted[:, j], name=f"{name} predicted"), row, 1
        )
        figure.add_trace(
            go.Scatter(
                x=t,
                y=validation.measured[:, j] - validation.predicted[:, j],
                name=f"{name} residual",
            ),
            row, 2,
        )  # fmt: skip
    figure.update_layout(height=260 * len(names), title="measured vs predicted joint torque")
    torque = out / "torque.html"
    figure.write_html(torque, include_plotlyjs=True)
    power = go.Figure()
    for label, tau in (("measured", validation.measured), ("predicted", validation.predicted)):
        power.add_trace(go.Scatter(x=t, y=np.sum(np.abs(tau * validation.qd), axis=1), name=label))
    power.update_layout(title="Σ|τ q̇| [W]", xaxis_title="time [s]", yaxis_title="power [W]")
    power_file = out / "power.html"
    power.write_html(power_file, include_plotlyjs=True)
    return [torque, power_file]


def summary_lines(result: Mapping[str, Any], names: Sequence[str]) -> list[str]:
    """Human-readable lines of a validation result."""
    lines = [f"{'joint':<16}{'rms measured':>14}{'residual rms':>14}{'R²':>8}   [Nm]"]
    for name in names:
        row = result["joints"][name]
        lines.append(
            f"{name:<16}{row['rms_measured']:>14.4g}{row['residual_rms']:>14.4g}{row['r2']:>8.3f}"
        )
    work = result["abs_work"]
    lines.append(
        f"abs_work: measured {work['measured']:.4g} J, predicted {work['predicted']:.4g} J"
    )
    if "electrical_energy" in result:
        e = result["electrical_energy"]
        lines.append(
            f"electrical: measured {e['measured']:.4g} J, predicted {e['predicted']:.4g} J"
        )
    lines.append(
        f"filter: {result['filter']['kind']}, cutoff {result['filter']['cutoff_hz']:g} Hz, "
        "delay 0 s"
    )
    return lines
