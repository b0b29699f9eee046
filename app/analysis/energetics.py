"""Energetics of recorded human lifts: joint torques, power, kinetic and potential energy.

The recorded shoulder and elbow angles drive the ``human_arm_2dof`` model (de Leva segments
scaled to the subject, the dumbbell in the hand), so each lift gets its joint torques, joint
power tau * omega, kinetic and potential energy over time, the metrics of DESIGN.md, and per
phase the exchange the method is built on: in phase C the arm's kinetic energy is handed over to
potential energy while gravity decelerates the load.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.analysis.segmentation import Phase
from app.recordings.types import RecordingError


class ArmDynamics(Protocol):
    """What is needed from a dynamics model (``app.planning.dynamics.Dynamics`` fits)."""

    def inverse_dynamics(
        self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike
    ) -> NDArray[np.float64]: ...

    def potential_energy(self, q: ArrayLike) -> NDArray[np.float64]: ...

    def kinetic_energy(self, q: ArrayLike, qd: ArrayLike) -> NDArray[np.float64]: ...


def human_arm_dynamics(
    *, body_mass: float = 75.0, body_height: float = 1.75, load_mass: float = 12.0
) -> ArmDynamics:
    """The ``human_arm_2dof`` model scaled to the subject, holding ``load_mass`` [kg]."""
    from app.planning.robots import load_robot

    robot = load_robot(
        "human_arm_2dof", payload=load_mass, body_mass=body_mass, body_height=body_height
    )
    dynamics: ArmDynamics = robot.dynamics()
    return dynamics


@dataclass(frozen=True)
class PhaseEnergetics:
    """Energy flow during one phase.

    Attributes:
        phase: the phase.
        delta_kinetic: change of kinetic energy [J].
        delta_potential: change of potential energy [J].
        work: (2,) joint work int tau * omega dt, shoulder and elbow [J].
        positive_work: (2,) int max(tau * omega, 0) dt [J].
        kinetic_to_potential: kinetic energy handed over to potential energy [J]: the kinetic
            energy lost while potential energy was gained, min(-dKE, dPE) when both hold, else 0.
        peak_power: max of sum |tau * omega| [W].
    """

    phase: Phase
    delta_kinetic: float
    delta_potential: float
    work: tuple[float, float]
    positive_work: tuple[float, float]
    kinetic_to_potential: float
    peak_power: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "phase": self.phase.name,
            "part": self.phase.part,
            "start": self.phase.start,
            "end": self.phase.end,
            "delta_kinetic_j": self.delta_kinetic,
            "delta_potential_j": self.delta_potential,
            "work_j": list(self.work),
            "positive_work_j": list(self.positive_work),
            "kinetic_to_potential_j": self.kinetic_to_potential,
            "peak_power_w": self.peak_power,
        }


@dataclass(frozen=True)
class Energetics:
    """Energetics of one lift (or any stretch of motion).

    Attributes:
        t: (T,) sample times [s].
        torque: (T, 2) joint torques, shoulder and elbow [Nm].
        power: (T, 2) joint power tau * omega [W].
        kinetic: (T,) kinetic energy [J].
        potential: (T,) potential energy [J] (zero with all masses at shoulder height).
        metrics: ``tau_sq`` [N^2 m^2 s], ``abs_work``, ``pos_work`` [J], ``peak_power`` [W],
            ``peak_torque`` (2,) [Nm], and the floors ``delta_potential`` [J] and
            ``min_peak_power`` [W] (DESIGN.md).
        phases: per-phase energy flow.
    """

    t: NDArray[np.float64]
    torque: NDArray[np.float64]
    power: NDArray[np.float64]
    kinetic: NDArray[np.float64]
    potential: NDArray[np.float64]
    metrics: dict[str, Any]
    phases: list[PhaseEnergetics] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """Metrics and per-phase flow (JSON-ready; no time series)."""
        return {
            "metrics": {
                k: (list(v) if isinstance(v, tuple) else v) for k, v in self.metrics.items()
            },
            "phases": [p.to_dict() for p in self.phases],
        }


def _trapz(y: NDArray[np.float64], t: NDArray[np.float64]) -> float:
    if len(t) < 2:
        return 0.0
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


def _window(t: NDArray[np.float64], t0: float, t1: float) -> NDArray[np.float64]:
    """Times of the samples inside [t0, t1] with both ends added exactly."""
    inside = t[(t > t0) & (t < t1)]
    return np.concatenate(([t0], inside, [t1]))


def _phase_flow(
    phase: Phase,
    ts: NDArray[np.float64],
    power: NDArray[np.float64],
    kinetic: NDArray[np.float64],
    potential: NDArray[np.float64],
) -> PhaseEnergetics | None:
    """Energy flow over one phase (None when the phase lies outside the samples)."""
    grid = _window(ts, max(phase.start, ts[0]), min(phase.end, ts[-1]))
    if grid[-1] <= grid[0]:
        return None
    p_grid = np.stack([np.interp(grid, ts, power[:, j]) for j in range(2)], axis=1)
    ke0, ke1 = np.interp([grid[0], grid[-1]], ts, kinetic)
    pe0, pe1 = np.interp([grid[0], grid[-1]], ts, potential)
    d_ke, d_pe = float(ke1 - ke0), float(pe1 - pe0)
    handed = min(-d_ke, d_pe) if (d_ke < 0 and d_pe > 0) else 0.0
    return PhaseEnergetics(
        phase=phase,
        delta_kinetic=d_ke,
        delta_potential=d_pe,
        work=(_trapz(p_grid[:, 0], grid), _trapz(p_grid[:, 1], grid)),
        positive_work=(
            _trapz(np.maximum(p_grid[:, 0], 0.0), grid),
            _trapz(np.maximum(p_grid[:, 1], 0.0), grid),
        ),
        kinetic_to_potential=handed,
        peak_power=float(np.abs(p_grid).sum(axis=1).max()),
    )


def lift_energetics(
    t: ArrayLike,
    q: ArrayLike,
    qd: ArrayLike,
    qdd: ArrayLike,
    dynamics: ArmDynamics,
    *,
    interval: tuple[float, float] | None = None,
    phases: Sequence[Phase] = (),
) -> Energetics:
    """Torques, power and energies along a recorded motion, with per-phase energy flow.

    Args:
        t: (T,) sample times [s].
        q: (T, 2) shoulder and elbow flexion [rad].
        qd: (T, 2) joint velocities [rad/s].
        qdd: (T, 2) joint accelerations [rad/s^2].
        dynamics: the arm model (e.g. :func:`human_arm_dynamics`).
        interval: (start, end) [s] to keep, e.g. a lift; None keeps everything.
        phases: phases to summarise (inside ``interval``).

    Returns:
        Energetics over the samples of ``interval`` where q, qd and qdd are all known.

    Raises:
        RecordingError: shapes disagree, or fewer than 3 usable samples.
    """
    times = np.asarray(t, dtype=np.float64)
    qa, va, aa = (np.asarray(x, dtype=np.float64) for x in (q, qd, qdd))
    for name, arr in (("q", qa), ("qd", va), ("qdd", aa)):
        if arr.shape != (len(times), 2):
            raise RecordingError(
                f"{name} has shape {arr.shape}", expected=f"({len(times)}, 2) shoulder, elbow"
            )
    keep = np.isfinite(qa).all(1) & np.isfinite(va).all(1) & np.isfinite(aa).all(1)
    if interval is not None:
        keep &= (times >= interval[0] - 1e-9) & (times <= interval[1] + 1e-9)
    if keep.sum() < 3:
        raise RecordingError(
            "fewer than 3 samples with known angles, velocities and accelerations",
            expected="a lift inside a gap-free stretch of the pose recording",
        )
    ts, qs, vs, acc = times[keep], qa[keep], va[keep], aa[keep]
    torque = np.asarray(dynamics.inverse_dynamics(qs, vs, acc), dtype=np.float64)
    power = torque * vs
    kinetic = np.asarray(dynamics.kinetic_energy(qs, vs), dtype=np.float64)
    potential = np.asarray(dynamics.potential_energy(qs), dtype=np.float64)
    total_abs = np.abs(power).sum(axis=1)
    duration = float(ts[-1] - ts[0])
    delta_pe = float(potential[-1] - potential[0])
    metrics: dict[str, Any] = {
        "tau_sq": _trapz((torque**2).sum(axis=1), ts),
        "abs_work": _trapz(total_abs, ts),
        "pos_work": _trapz(np.maximum(power, 0.0).sum(axis=1), ts),
        "peak_power": float(total_abs.max()),
        "peak_torque": tuple(float(v) for v in np.abs(torque).max(axis=0)),
        "delta_potential": delta_pe,
        "min_peak_power": delta_pe / duration if duration > 0 else 0.0,
        "duration": duration,
    }
    flows = [f for phase in phases if (f := _phase_flow(phase, ts, power, kinetic, potential))]
    return Energetics(
        t=ts,
        torque=torque,
        power=power,
        kinetic=kinetic,
        potential=potential,
        metrics=metrics,
        phases=flows,
    )
