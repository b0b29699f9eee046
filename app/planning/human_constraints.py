"""The template's human-likeness in robot terms, for the optimal-control methods.

* ``peak``: the elbow is fastest where it passes ``template.peak_joint_angle(q0, q1)``.
* ``phases``: each A/B/C phase's share of the duration lies within the template's spread.
  The shares come, in this order of preference, from

  1. the template's ``phase_time_shares`` and ``phase_time_share_sd`` (per-phase mean and
     standard deviation over recorded lifts), when the template has them: mean ± 2 SD, and at
     least ± :data:`MIN_SHARE_SPREAD`;
  2. the template's mean velocity profile (``normalized_time``, ``velocity_mean``,
     ``velocity_sd``): the profile is integrated to the fraction of the stroke covered over
     time, the phase bounds (human flexion on the curl span) are placed on it, and the profiles
     mean ± SD give the spread;
  3. otherwise (the paper's defaults, which hold no lift): the shares of a triangular velocity
     profile peaking at the template's angle (constant acceleration up to the peak, constant
     deceleration after it), ± :data:`DEFAULT_SHARE_SPREAD` (an assumption, said in the result).

* ``shape``: the person's own elbow-speed shape: the elbow speed divided by its peak stays inside
  the band of the recorded lifts, mean ± SD, over normalised time (:func:`speed_band`); only for
  a template built from lifts with kinematics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from app.errors import BioPlanError
from app.names import HUMAN_CURL_SPAN_DEG
from app.planning.human_template import HumanTemplate, joint_on_stroke

__all__ = [
    "DEFAULT_SHARE_SPREAD",
    "MIN_SHARE_SPREAD",
    "SHAPE_TOP_DROP",
    "PhaseShares",
    "SpeedBand",
    "elbow_speed_on_stroke",
    "human_likeness_distance",
    "phase_shares",
    "speed_band",
    "template_speed_on_stroke",
]

FloatArray = NDArray[np.float64]

#: Spread of the phase shares when the template holds no lift [-] (assumed).
DEFAULT_SHARE_SPREAD = 0.05
#: Smallest spread allowed around a recorded share [-].
MIN_SHARE_SPREAD = 0.02
#: ``shape``: the elbow speed comes within this fraction of its peak only where the recorded
#: mean profile does (the issue's 1 % criterion of a clear peak) [-].
SHAPE_TOP_DROP = 0.01


@dataclass(frozen=True)
class PhaseShares:
    """Bounds on the A/B/C phases' shares of the motion's duration.

    Attributes:
        nominal: (3,) the template's shares [-] (summing to 1).
        bounds: (3, 2) lower and upper share per phase [-].
        source: where they come from (one line).
    """

    nominal: tuple[float, float, float]
    bounds: tuple[tuple[float, float], ...]
    source: str

    def to_dict(self) -> dict[str, object]:
        return {
            "nominal": list(self.nominal),
            "bounds": [list(b) for b in self.bounds],
            "source": self.source,
        }


def _bounded(nominal: FloatArray, spread: FloatArray, source: str) -> PhaseShares:
    lo = np.clip(nominal - spread, 0.02, 0.96)
    hi = np.clip(nominal + spread, 0.04, 0.98)
    return PhaseShares(
        nominal=(float(nominal[0]), float(nominal[1]), float(nominal[2])),
        bounds=tuple((float(a), float(b)) for a, b in zip(lo, hi, strict=True)),
        source=source,
    )


def _stroke_fractions(template: HumanTemplate) -> tuple[float, float, float]:
    """Phase bounds and peak angle as fractions of the human curl span."""
    lo, hi = HUMAN_CURL_SPAN_DEG
    a, b = template.phase_bounds_deg
    peak = template.peak_velocity_angle_deg
    return (a - lo) / (hi - lo), (b - lo) / (hi - lo), (peak - lo) / (hi - lo)


def _shares_from_profile(template: HumanTemplate, velocity: FloatArray) -> FloatArray:
    """Phase shares of a normalised velocity profile (fraction of the stroke over time)."""
    t = np.asarray(template.normalized_time, dtype=np.float64)
    v = np.maximum(velocity, 0.0)
    covered = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    if covered[-1] <= 0.0:
        raise BioPlanError("the template's velocity profile never moves: expected a lift")
    fraction = np.maximum.accumulate(covered / covered[-1])
    f_ab, f_bc, _ = _stroke_fractions(template)
    t_ab, t_bc = (float(np.interp(f, fraction, t)) for f in (f_ab, f_bc))
    span = float(t[-1] - t[0])
    return np.array([t_ab - t[0], t_bc - t_ab, t[-1] - t_bc]) / span


def _triangular_shares(template: HumanTemplate) -> FloatArray:
    """Shares of the triangular velocity profile peaking at the template's angle."""
    f_ab, f_bc, f_peak = _stroke_fractions(template)

    def time_at(f: float) -> float:
        # Accelerating: f = f_p (t / t_p)^2 with t_p = f_p; decelerating mirrors it.
        if f <= f_peak:
            return f_peak * math.sqrt(f / f_peak)
        return 1.0 - (1.0 - f_peak) * math.sqrt((1.0 - f) / (1.0 - f_peak))

    t_ab, t_bc = time_at(f_ab), time_at(f_bc)
    return np.array([t_ab, t_bc - t_ab, 1.0 - t_bc])


def phase_shares(template: HumanTemplate) -> PhaseShares:
    """The A/B/C share bounds of ``template`` (see the module docstring for the order).

    Fields read from the template: ``phase_time_shares`` and ``phase_time_share_sd`` (if the
    template type has them), ``normalized_time``, ``velocity_mean``, ``velocity_sd``,
    ``phase_bounds_deg``, ``peak_velocity_angle_deg``.
    """
    shares = getattr(template, "phase_time_shares", None)
    if shares:
        mean = np.asarray(shares, dtype=np.float64)
        sd = np.asarray(getattr(template, "phase_time_share_sd", None) or np.zeros(3), float)
        spread = np.maximum(2.0 * sd, MIN_SHARE_SPREAD)
        return _bounded(mean / mean.sum(), spread, f"template phase shares ({template.source})")
    if template.normalized_time and template.velocity_mean:
        mean_v = np.asarray(template.velocity_mean, dtype=np.float64)
        sd_v = np.asarray(template.velocity_sd or np.zeros_like(mean_v), dtype=np.float64)
        nominal = _shares_from_profile(template, mean_v)
        lower = _shares_from_profile(template, mean_v - sd_v)
        upper = _shares_from_profile(template, mean_v + sd_v)
        spread = np.maximum(
            np.abs(np.stack([lower, upper]) - nominal).max(axis=0), MIN_SHARE_SPREAD
        )
        return _bounded(
            nominal, spread, f"template velocity profile, mean ± SD ({template.source})"
        )
    nominal = _triangular_shares(template)
    return _bounded(
        nominal,
        np.full(3, DEFAULT_SHARE_SPREAD),
        f"triangular velocity profile peaking at {template.peak_velocity_angle_deg:g} deg "
        f"(no recorded lift), ± {DEFAULT_SHARE_SPREAD:g} assumed",
    )


def phase_bound_angles(template: HumanTemplate, q0: float, q1: float) -> tuple[float, float]:
    """The A/B and B/C phase bounds on the robot elbow stroke q0 -> q1 [rad]."""
    a, b = template.phase_bounds_deg
    angles = (joint_on_stroke(a, q0, q1), joint_on_stroke(b, q0, q1))
    lo, hi = sorted((q0, q1))
    for deg, angle in zip((a, b), angles, strict=True):
        if not lo < angle < hi:
            raise BioPlanError(
                f"phase bound {deg:g} deg lies outside the elbow's stroke "
                f"[{math.degrees(lo):.1f}, {math.degrees(hi):.1f}] deg: expected the stroke to "
                "pass every phase bound for --human-constraint phases"
            )
    return angles


# ----------------------------------------------------------------------------------------------
# The recorded shape
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SpeedBand:
    """The band of the recorded lifts' elbow speed, for ``--human-constraint shape``.

    Attributes:
        time: (K,) normalised time of the lift, 0 at its start, 1 at its top [-].
        lower, upper: (K,) edges of the band: elbow speed divided by the peak of the mean
            profile [-] (mean - SD and mean + SD, the lower edge lowered as said in
            :func:`speed_band`).
        peak_time: normalised time at which the mean profile peaks [-].
        source: where the band comes from (one line).
    """

    time: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    peak_time: float
    source: str

    def to_dict(self) -> dict[str, object]:
        return {
            "time": list(self.time),
            "lower": list(self.lower),
            "upper": list(self.upper),
            "peak_time": self.peak_time,
            "source": self.source,
        }


def speed_band(template: HumanTemplate) -> SpeedBand:
    """The elbow-speed band of the lifts behind ``template`` (``shape``'s constraint).

    The band lies on **normalised time**, not on normalised flexion: the template's profiles
    are recorded that way (each lift's start -> top scaled to [0, 1], each lift's speed
    divided by its own peak), so mean ± SD at a given time is a statistic over the lifts that
    the recordings measure directly; re-expressed on flexion, the SD would mix the lifts'
    different progress at one instant. And the robot's motion has a fixed duration, so its
    normalised time is known before the solve: the band's edges are numbers at every solver
    node, and the constraint is linear (speed >= edge x peak speed), where on flexion each
    edge would depend on the unknown elbow angle.

    The profile is divided by the mean's peak, so the band holds 1 where the mean peaks. The
    top is the person's too: outside the times where the mean profile is within
    :data:`SHAPE_TOP_DROP` of its peak, the upper edge is at most ``1 - SHAPE_TOP_DROP``: mean
    plus SD exceeds 1 there (every lift is divided by its own peak) and let the human arm's
    peak-power optimum hold its top speed from 34 % to 55 % of the duration.

    The recorded lifts begin and end at a small speed (the segmentation's start rule, a few %
    of the peak), which a robot moving from rest to rest cannot match: the lower edge is
    lowered by the straight line through its two end values (so it is 0 at both ends) and
    clipped at 0.

    Raises:
        BioPlanError: the template holds no recorded profile (the paper's default), rests on
            fewer than 2 lifts (no spread), or its profile fields are inconsistent.
    """
    if template.is_paper_default or not template.velocity_mean:
        raise BioPlanError(
            "the human constraint shape needs the elbow-speed profile (mean ± SD) of recorded "
            f"lifts, and this template has none ({template.source}): expected a template "
            "built by `bioplan analyze` from recordings with elbow kinematics, or the "
            "constraint peak"
        )
    if template.n_lifts < 2:
        raise BioPlanError(
            f"the human constraint shape needs the spread of at least 2 lifts, and the "
            f"template rests on {template.n_lifts} ({template.source}): expected more recorded "
            "lifts, or the constraint peak"
        )
    t = np.asarray(template.normalized_time, dtype=np.float64)
    mean = np.asarray(template.velocity_mean, dtype=np.float64)
    sd = np.asarray(template.velocity_sd, dtype=np.float64)
    if not (t.size == mean.size == sd.size >= 3) or np.any(np.diff(t) <= 0) or np.any(sd < 0):
        raise BioPlanError(
            "HumanTemplate fields 'normalized_time', 'velocity_mean', 'velocity_sd': expected "
            "three arrays of one length (>= 3), the time increasing and the SD >= 0, got "
            f"lengths {t.size}, {mean.size}, {sd.size}"
        )
    top = float(mean.max())
    if top <= 0:
        raise BioPlanError("HumanTemplate field 'velocity_mean': expected a positive peak")
    tau = (t - t[0]) / (t[-1] - t[0])
    raw = (mean - sd) / top
    line = raw[0] + (raw[-1] - raw[0]) * tau
    lower = np.maximum(raw - line, 0.0)
    lower[[0, -1]] = 0.0  # exactly, not to rounding
    upper = (mean + sd) / top
    upper = np.where(
        mean / top < 1.0 - SHAPE_TOP_DROP, np.minimum(upper, 1.0 - SHAPE_TOP_DROP), upper
    )
    upper = np.maximum(upper, lower)
    return SpeedBand(
        time=tuple(float(v) for v in tau),
        lower=tuple(float(v) for v in lower),
        upper=tuple(float(v) for v in upper),
        peak_time=float(tau[int(np.argmax(mean))]),
        source=(
            f"elbow speed / peak within mean ± SD of {template.n_lifts} recorded lifts on "
            f"normalised time ({template.source})"
        ),
    )


# ----------------------------------------------------------------------------------------------
# Human-likeness score
# ----------------------------------------------------------------------------------------------

#: Points of the stroke-fraction grid on which speed profiles are compared.
LIKENESS_POINTS = 101


def _min_jerk_on_fraction(fraction: FloatArray, peak: float) -> FloatArray:
    """The minimum-jerk speed profile (normalised, peak 1) against the fraction of its stroke,
    its peak moved from mid-stroke to ``peak`` by a piecewise-linear warp of the fraction."""
    tau = np.linspace(0.0, 1.0, 2001)
    pos = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    speed = 16 * tau**2 * (1 - tau) ** 2  # 30 τ²(1−τ)² over its peak 30/16
    warped = np.where(
        fraction <= peak, 0.5 * fraction / peak, 0.5 + 0.5 * (fraction - peak) / (1 - peak)
    )
    return np.asarray(np.interp(warped, pos, speed), dtype=np.float64)


def template_speed_on_stroke(
    template: HumanTemplate, q0: float, q1: float, *, peak_angle: float | None = None
) -> tuple[FloatArray, str]:
    """The template's elbow speed (normalised, peak 1) on the stroke-fraction grid, and its source.

    From the template's recorded mean velocity profile (``normalized_time``, ``velocity_mean``),
    integrated to the fraction of the stroke covered; without one (the paper's defaults), the
    minimum-jerk bell with its peak where the template puts it on the stroke q0 -> q1 [rad]
    (or at ``peak_angle`` [rad], the plan's override of the template's angle).
    """
    grid = np.linspace(0.0, 1.0, LIKENESS_POINTS)
    if template.normalized_time and template.velocity_mean:
        t = np.asarray(template.normalized_time, dtype=np.float64)
        v = np.maximum(np.asarray(template.velocity_mean, dtype=np.float64), 0.0)
        covered = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
        if covered[-1] > 0 and v.max() > 0:
            fraction = covered / covered[-1]
            keep = np.concatenate([[True], np.diff(fraction) > 0])
            speed = np.interp(grid, fraction[keep], v[keep] / v.max())
            return speed, f"the template's mean velocity profile ({template.source})"
    at = template.peak_joint_angle(q0, q1) if peak_angle is None else peak_angle
    peak = (at - q0) / (q1 - q0)
    peak = float(np.clip(peak, 0.05, 0.95))
    return _min_jerk_on_fraction(grid, peak), (
        f"minimum-jerk bell peaking at the template's angle, {100 * peak:.0f} % of the stroke "
        "(the template holds no recorded profile)"
    )


def elbow_speed_on_stroke(q: FloatArray, qd: FloatArray, q0: float, q1: float) -> FloatArray:
    """An elbow motion's speed (normalised, peak 1) on the stroke-fraction grid.

    Args:
        q, qd: (T,) elbow angle [rad] and velocity [rad/s] over time.
        q0, q1: the stroke's start and end [rad].
    """
    fraction = np.maximum.accumulate(np.clip((q - q0) / (q1 - q0), 0.0, 1.0))
    speed = np.abs(qd)
    top = float(speed.max())
    if top <= 0:
        return np.zeros(LIKENESS_POINTS)
    keep = np.concatenate([[True], np.diff(fraction) > 0])
    grid = np.linspace(0.0, 1.0, LIKENESS_POINTS)
    return np.asarray(np.interp(grid, fraction[keep], speed[keep] / top), dtype=np.float64)


def human_likeness_distance(
    q: FloatArray, qd: FloatArray, q0: float, q1: float, reference: FloatArray
) -> float:
    """The human-likeness score: how far an elbow motion's speed profile is from the template's.

    Both profiles are the elbow speed divided by its peak, against the fraction of the elbow's
    stroke covered (0 at the start angle, 1 at the goal), on :data:`LIKENESS_POINTS` points;
    the score is the root-mean-square difference of the two, in [0, 1]: 0 = the template's
    shape, about 0.1 = a minimum-jerk bell against one peaking 20 % of the stroke earlier.
    Where the elbow moves back (reversal allowed), the first pass over each fraction counts.

    Args:
        q, qd: (T,) elbow angle [rad] and velocity [rad/s] over time.
        q0, q1: the stroke's start and end [rad].
        reference: (LIKENESS_POINTS,) the template's profile (:func:`template_speed_on_stroke`).
    """
    speed = elbow_speed_on_stroke(q, qd, q0, q1)
    return float(np.sqrt(np.mean((speed - reference) ** 2)))
