"""Build the planner's HumanTemplate from recorded lifts.

Everything is measured over the concentric (lifting) part of each lift, start -> top, because
that is the move the robot copies: the elbow angle at the velocity peak (absolute, and as a
fraction of the lift's own range), the velocity and acceleration profiles on a normalised time
grid (each lift scaled to its own peak), the muscle activation order and when each muscle's
envelope peaks.

Honesty rules: a velocity peak on a lift's first or last sample is no peak (the lift was cut,
or the angle is noise) and the lift gives no kinematics; EMG peak times are measured against the
lift's top only when the elbow angle defined that top (an EMG-only lift's top is the EMG's own
burst peak, so timing EMG against it would measure the EMG against itself).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from app.analysis.segmentation import Lift
from app.planning.human_template import PAPER_DEFAULT_SOURCE, HumanTemplate
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
        peak_velocity_range_fraction: its angle as a fraction of the lift's range,
            (angle - start angle) / (top angle - start angle).
        velocity: (K,) elbow velocity / peak velocity on the normalised grid (empty without).
        acceleration: (K,) elbow acceleration / peak |acceleration| on the grid.
        activation_order: muscles by onset.
        emg_peak_time_fraction: muscle -> envelope peak time as a fraction of start -> top
            (empty for EMG-only lifts).
        rejected: why the lift gives no kinematics ("" when it does, or has no angle).
    """

    lift: Lift
    peak_velocity: float = float("nan")
    peak_velocity_angle: float = float("nan")
    peak_velocity_time_fraction: float = float("nan")
    peak_velocity_range_fraction: float = float("nan")
    velocity: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    acceleration: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    activation_order: tuple[str, ...] = ()
    emg_peak_time_fraction: dict[str, float] = field(default_factory=dict)
    rejected: str = ""

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
        if span > 0 and np.isfinite(tp) and lift.source == "angle"
    }
    base = LiftProfile(
        lift=lift, activation_order=tuple(activation_order), emg_peak_time_fraction=fractions
    )
    if t is None or elbow is None or elbow_velocity is None or elbow_acceleration is None:
        return base
    inside = (t >= lift.start - 1e-9) & (t <= lift.top + 1e-9)
    if inside.sum() < 3 or span <= 0:
        return replace(base, rejected="fewer than 3 samples from start to top")
    ts, ang, vel, acc = t[inside], elbow[inside], elbow_velocity[inside], elbow_acceleration[inside]
    if not (np.isfinite(vel).all() and np.isfinite(acc).all() and np.isfinite(ang).all()):
        return replace(base, rejected="the rise touches a gap in the elbow angle")
    k = int(np.argmax(vel))
    peak = float(vel[k])
    if not peak > 0:
        return replace(base, rejected="the elbow does not rise")
    if k in (0, len(vel) - 1):
        where = "first" if k == 0 else "last"
        return replace(base, rejected=f"the velocity peaks on the lift's {where} sample")
    rise = float(ang[-1] - ang[0])
    fraction = float((ang[k] - ang[0]) / rise) if rise > 0 else float("nan")
    if not 0.0 < fraction < 1.0:
        return replace(base, rejected="the velocity peak lies outside the lift's range")
    grid = np.linspace(0.0, 1.0, grid_points)
    tau = (ts - lift.start) / span
    acc_scale = float(np.max(np.abs(acc)))
    return LiftProfile(
        lift=lift,
        peak_velocity=peak,
        peak_velocity_angle=float(ang[k]),
        peak_velocity_time_fraction=float(tau[k]),
        peak_velocity_range_fraction=fraction,
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
    files: Sequence[str] = (),
    assumptions: Sequence[str] = (),
    left_out: Mapping[str, int] | None = None,
) -> HumanTemplate:
    """The HumanTemplate from lift profiles.

    Kinematic fields (peak-velocity angle mean +- SD, absolute and as a fraction of each lift's
    range, time fraction, profiles) come from the lifts with complete angle data; with none,
    they keep the paper's defaults (62 deg), ``n_lifts`` is 0 and ``source`` says so and why,
    while the activation order still comes from the EMG. EMG peak times come from the lifts
    whose top the elbow angle defined. The EMG fields cover the four sites (deltoid, triceps,
    biceps, forearm) when any channel is mapped to one, else every muscle.

    Args:
        profiles: per-lift features (:func:`lift_profile`).
        phase_bounds_deg: (A/B, B/C) elbow thresholds [deg] to record in the template.
        files: the recordings the lifts came from.
        assumptions: what the analysis assumed, recorded in the template.
        left_out: reason -> number of lifts the analysis left out before (e.g. ``{"low pose
            quality": 2}``); ``source`` says so, also when the paper's default is all that is
            left.

    Returns:
        A HumanTemplate (JSON round-trip through ``to_json``/``from_json``).
    """
    kin = [p for p in profiles if p.has_kinematics]
    order, emg_peaks = _emg_fields(profiles)
    base = HumanTemplate(
        phase_bounds_deg=(float(phase_bounds_deg[0]), float(phase_bounds_deg[1])),
        activation_order=order,
        emg_peak_time_fraction=emg_peaks,
        files=tuple(files),
        emg_lifts=sum(bool(p.activation_order or p.emg_peak_time_fraction) for p in profiles),
        assumptions=tuple(assumptions),
        n_lifts=0,
        source=_default_source(profiles, left_out or {}),
    )
    if not kin:
        return base
    angles = np.rad2deg([p.peak_velocity_angle for p in kin])
    fractions = np.array([p.peak_velocity_range_fraction for p in kin])
    ranges = np.rad2deg([[p.lift.start_angle, p.lift.top_angle] for p in kin])
    vel = np.stack([p.velocity for p in kin])
    acc = np.stack([p.acceleration for p in kin])
    grid = np.linspace(0.0, 1.0, vel.shape[1])
    without = len(profiles) - len(kin)
    return replace(
        base,
        peak_velocity_angle_deg=float(np.mean(angles)),
        peak_velocity_angle_sd_deg=_sd(angles),
        peak_velocity_time_fraction=float(np.mean([p.peak_velocity_time_fraction for p in kin])),
        peak_velocity_range_fraction=float(np.mean(fractions)),
        peak_velocity_range_fraction_sd=_sd(fractions),
        lift_range_deg=(float(ranges[:, 0].mean()), float(ranges[:, 1].mean())),
        normalized_time=tuple(float(v) for v in grid),
        velocity_mean=tuple(float(v) for v in vel.mean(axis=0)),
        velocity_sd=_profile_sd(vel),
        acceleration_mean=tuple(float(v) for v in acc.mean(axis=0)),
        acceleration_sd=_profile_sd(acc),
        n_lifts=len(kin),
        source=f"{len(kin)} lift(s) with kinematics"
        + (f" ({without} without)" if without else "")
        + _left_out_text(left_out or {}),
    )


def _left_out_text(left_out: Mapping[str, int]) -> str:
    """``"; 2 lift(s) left out (low pose quality)"`` for the template's ``source``."""
    parts = [f"{n} lift(s) left out ({why})" for why, n in left_out.items() if n]
    return "".join(f"; {p}" for p in parts)


def _sd(x: NDArray[np.float64]) -> float:
    return float(np.std(x, ddof=1)) if len(x) > 1 else 0.0


def _profile_sd(x: NDArray[np.float64]) -> tuple[float, ...]:
    sd = x.std(axis=0, ddof=1) if len(x) > 1 else np.zeros(x.shape[1])
    return tuple(float(v) for v in sd)


def _default_source(profiles: Sequence[LiftProfile], left_out: Mapping[str, int]) -> str:
    """``source`` of a template that keeps the paper's kinematics, with the reason."""
    if not profiles and any(left_out.values()):
        why = ", ".join(f"{n} for {reason}" for reason, n in left_out.items() if n)
        return f"{PAPER_DEFAULT_SOURCE}: every lift found was left out ({why})"
    if not profiles:
        return f"{PAPER_DEFAULT_SOURCE}: no lifts found in these files"
    if all(p.lift.source == "emg" for p in profiles):
        return f"{PAPER_DEFAULT_SOURCE}: no kinematics in these files"
    reasons = sorted({p.rejected for p in profiles if p.rejected})
    why = "; ".join(reasons) if reasons else "no usable elbow kinematics"
    return f"{PAPER_DEFAULT_SOURCE}: no lift with usable kinematics ({why})" + _left_out_text(
        left_out
    )


def _emg_fields(profiles: Sequence[LiftProfile]) -> tuple[tuple[str, ...], dict[str, float]]:
    """(activation order, muscle -> mean EMG peak time fraction) over the lifts."""
    # The template speaks of the method's four sites; other muscles count only when no channel
    # is mapped to a site.
    named = {m for p in profiles for m in (*p.activation_order, *p.emg_peak_time_fraction)}
    keep = set(SITES) if named & set(SITES) else named
    order = consensus_order(
        [[m for m in p.activation_order if m in keep] for p in profiles if p.activation_order]
    )
    muscles = sorted({m for p in profiles for m in p.emg_peak_time_fraction if m in keep})
    peaks = {
        m: float(
            np.mean(
                [p.emg_peak_time_fraction[m] for p in profiles if m in p.emg_peak_time_fraction]
            )
        )
        for m in muscles
    }
    return order, peaks
