"""Build the planner's HumanTemplate from recorded lifts.

Everything is measured over the concentric (lifting) part of each lift, start -> top, because
that is the move the robot copies: the elbow angle at the velocity peak, the velocity and
acceleration profiles on a normalised time grid (each lift scaled to its own peak), the muscle
activation order and when each muscle's envelope peaks.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from app.analysis.segmentation import Lift
from app.planning.human_template import HumanTemplate
from app.recordings.types import SITES

GRID_POINTS = 101


@dataclass(frozen=True)
class LiftProfile:
    """Features of one lift's concentric part.

    Attributes:
        lift: the lift.
        peak_velocity: highest elbow velocity [rad/s] (NaN without angles).
        peak_velocity_angle: elbow flexion at that moment [rad].
        peak_velocity_time_fraction: its time as a fraction of start -> top.
        velocity: (K,) elbow velocity / peak velocity on the normalised grid (empty without).
        acceleration: (K,) elbow acceleration / peak |acceleration| on the grid.
        activation_order: muscles by onset.
        emg_peak_time_fraction: muscle -> envelope peak time as a fraction of start -> top.
    """

    lift: Lift
    peak_velocity: float = float("nan")
    peak_velocity_angle: float = float("nan")
    peak_velocity_time_fraction: float = float("nan")
    velocity: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    acceleration: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    activation_order: tuple[str, ...] = ()
    emg_peak_time_fraction: dict[str, float] = field(default_factory=dict)

    @property
    def has_kinematics(self) -> bool:
        return bool(np.isfinite(self.peak_velocity_angle)) and self.velocity.size > 0


def lift_profile(
    lift: Lift,
    *,
    t: NDArray[np.float64] | None = None,
    elbow: NDArray[np.float64] | None = None,
    elbow_velocity: NDArray[np.float64] | None = None,
    elbow_acceleration: NDArray[np.float64] | None = None,
    activation_order: Sequence[str] = (),
    emg_peak_times: Mapping[str, float] | None = None,
    grid_points: int = GRID_POINTS,
) -> LiftProfile:
    """Features of one lift; kinematic ones only when the angle series are given and complete.

    Args:
        lift: the lift (times on the same clock as ``t`` and ``emg_peak_times``).
        t: (T,) sample times [s].
        elbow, elbow_velocity, elbow_acceleration: (T,) elbow flexion [rad], [rad/s], [rad/s^2].
        activation_order: muscles in order of onset for this lift.
        emg_peak_times: muscle -> time of the envelope peak during the concentric part [s].
        grid_points: K, points of the normalised time grid over start -> top.

    Returns:
        The lift's profile; without angles, or when the concentric part touches a gap (NaN
        derivatives), only the EMG features are filled in.
    """
    span = lift.top - lift.start
    fractions = {
        m: float((tp - lift.start) / span)
        for m, tp in (emg_peak_times or {}).items()
        if span > 0 and np.isfinite(tp)
    }
    base = LiftProfile(
        lift=lift, activation_order=tuple(activation_order), emg_peak_time_fraction=fractions
    )
    if t is None or elbow is None or elbow_velocity is None or elbow_acceleration is None:
        return base
    inside = (t >= lift.start - 1e-9) & (t <= lift.top + 1e-9)
    if inside.sum() < 3 or span <= 0:
        return base
    ts, ang, vel, acc = t[inside], elbow[inside], elbow_velocity[inside], elbow_acceleration[inside]
    if not (np.isfinite(vel).all() and np.isfinite(acc).all() and np.isfinite(ang).all()):
        return base
    k = int(np.argmax(vel))
    peak = float(vel[k])
    if not peak > 0:
        return base
    grid = np.linspace(0.0, 1.0, grid_points)
    tau = (ts - lift.start) / span
    acc_scale = float(np.max(np.abs(acc)))
    return LiftProfile(
        lift=lift,
        peak_velocity=peak,
        peak_velocity_angle=float(ang[k]),
        peak_velocity_time_fraction=float(tau[k]),
        velocity=np.interp(grid, tau, vel) / peak,
        acceleration=np.interp(grid, tau, acc) / acc_scale
        if acc_scale > 0
        else np.zeros_like(grid),
        activation_order=tuple(activation_order),
        emg_peak_time_fraction=fractions,
    )


def consensus_order(orders: Sequence[Sequence[str]]) -> tuple[str, ...]:
    """One activation order from many: muscles by mean rank (absent = ranked last), ties by
    how often the muscle was seen, then by name."""
    muscles = sorted({m for order in orders for m in order})
    if not muscles:
        return ()
    ranks: dict[str, list[float]] = {m: [] for m in muscles}
    for order in orders:
        for m in muscles:
            ranks[m].append(float(order.index(m)) if m in order else float(len(muscles)))
    seen = {m: sum(m in order for order in orders) for m in muscles}
    return tuple(sorted(muscles, key=lambda m: (float(np.mean(ranks[m])), -seen[m], m)))


def build_template(
    profiles: Sequence[LiftProfile],
    *,
    phase_bounds_deg: tuple[float, float] = (40.0, 90.0),
    source: str = "",
) -> HumanTemplate:
    """The HumanTemplate from lift profiles.

    Kinematic fields (peak-velocity angle mean +- SD, time fraction, profiles) come from the
    lifts with complete angle data; with none, they keep the paper's defaults (62 deg) and
    ``n_lifts`` is 0, while the activation order and EMG peak times still come from the EMG.
    The activation order and EMG peak times cover the four sites (deltoid, triceps, biceps,
    forearm) when any channel is mapped to one, else every muscle.

    Args:
        profiles: per-lift features (:func:`lift_profile`).
        phase_bounds_deg: (A/B, B/C) elbow thresholds [deg] to record in the template.
        source: where the lifts came from (file names).

    Returns:
        A HumanTemplate (JSON round-trip through ``to_json``/``from_json``).
    """
    kin = [p for p in profiles if p.has_kinematics]
    # The template speaks of the method's four sites; other muscles count only when no channel
    # is mapped to a site.
    named = {m for p in profiles for m in (*p.activation_order, *p.emg_peak_time_fraction)}
    keep = set(SITES) if named & set(SITES) else named
    order = consensus_order(
        [[m for m in p.activation_order if m in keep] for p in profiles if p.activation_order]
    )
    muscles = sorted({m for p in profiles for m in p.emg_peak_time_fraction if m in keep})
    emg_peaks = {
        m: float(
            np.mean(
                [p.emg_peak_time_fraction[m] for p in profiles if m in p.emg_peak_time_fraction]
            )
        )
        for m in muscles
    }
    bounds = (float(phase_bounds_deg[0]), float(phase_bounds_deg[1]))
    if not kin:
        note = (
            f"{len(profiles)} lifts without complete elbow kinematics; kinematics: paper defaults"
        )
        return HumanTemplate(
            phase_bounds_deg=bounds,
            activation_order=order,
            emg_peak_time_fraction=emg_peaks,
            n_lifts=0,
            source=f"{source} ({note})" if source else note,
        )
    angles = np.rad2deg([p.peak_velocity_angle for p in kin])
    vel = np.stack([p.velocity for p in kin])
    acc = np.stack([p.acceleration for p in kin])
    grid = np.linspace(0.0, 1.0, vel.shape[1])
    return HumanTemplate(
        peak_velocity_angle_deg=float(np.mean(angles)),
        peak_velocity_angle_sd_deg=float(np.std(angles, ddof=1)) if len(kin) > 1 else 0.0,
        phase_bounds_deg=bounds,
        peak_velocity_time_fraction=float(np.mean([p.peak_velocity_time_fraction for p in kin])),
        normalized_time=tuple(float(v) for v in grid),
        velocity_mean=tuple(float(v) for v in vel.mean(axis=0)),
        velocity_sd=tuple(
            float(v) for v in (vel.std(axis=0, ddof=1) if len(kin) > 1 else 0 * grid)
        ),
        acceleration_mean=tuple(float(v) for v in acc.mean(axis=0)),
        acceleration_sd=tuple(
            float(v) for v in (acc.std(axis=0, ddof=1) if len(kin) > 1 else 0 * grid)
        ),
        activation_order=order,
        emg_peak_time_fraction=emg_peaks,
        n_lifts=len(kin),
        source=source or "recorded lifts",
    )
