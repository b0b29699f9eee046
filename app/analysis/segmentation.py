"""Repetitions (lifts) and their A/B/C phases.

A lift runs from rest (start) up to the highest elbow flexion (top) and back down to rest (end):
start -> top is the concentric (lifting) part, top -> end the eccentric (lowering) part. Lifts are
found from the elbow angle, or from EMG bursts when no angle was recorded. Phases follow
DESIGN.md: A [0, 40) deg, B [40, 90) deg, C [90, 150] deg of elbow flexion by default.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, TypedDict

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.analysis._checks import as_signal, check_rate, scipy_signal, true_runs
from app.recordings.types import RecordingError

DEFAULT_PHASE_BOUNDS = (float(np.deg2rad(40.0)), float(np.deg2rad(90.0)))
PhaseName = Literal["A", "B", "C"]
Part = Literal["concentric", "eccentric"]


@dataclass(frozen=True)
class Lift:
    """One repetition.

    Attributes:
        start: movement start: the last moment at rest before the elbow rises [s].
        top: first arrival at the highest elbow flexion (end of the concentric part) [s]; for
            EMG-only lifts the time of the burst's peak, an estimate.
        end: back at rest [s].
        source: ``"angle"`` or ``"emg"`` (what the lift was detected from).
        start_angle, top_angle, end_angle: elbow flexion there [rad] (NaN for EMG-only lifts).
        lower_start: when the lowering begins [s]; ``top -> lower_start`` is the hold at the
            top (its own part, in no phase). None = no hold (lowering begins at ``top``).
    """

    start: float
    top: float
    end: float
    source: Literal["angle", "emg"]
    start_angle: float = float("nan")
    top_angle: float = float("nan")
    end_angle: float = float("nan")
    lower_start: float | None = None

    @property
    def concentric(self) -> tuple[float, float]:
        return (self.start, self.top)

    @property
    def hold(self) -> tuple[float, float]:
        """(top, lowering start) [s]: the hold at the top (zero length without one)."""
        return (self.top, self.top if self.lower_start is None else self.lower_start)

    @property
    def eccentric(self) -> tuple[float, float]:
        return (self.hold[1], self.end)

    @property
    def duration(self) -> float:
        return self.end - self.start


class PhaseMeta(TypedDict):
    """JSON form of a :class:`Phase` (the overlays' meta, each lift's phase statistics):
    times [s] on its file's clock."""

    name: str
    part: str
    start_s: float
    end_s: float


@dataclass(frozen=True)
class Phase:
    """One phase of one part of a lift.

    Attributes:
        name: ``"A"`` (high-load capacity), ``"B"`` (weakest), ``"C"`` (deceleration).
        part: ``"concentric"`` or ``"eccentric"``.
        start, end: times [s].
    """

    name: PhaseName
    part: Part
    start: float
    end: float

    @property
    def duration(self) -> float:
        return self.end - self.start

    def to_dict(self) -> PhaseMeta:
        return {"name": self.name, "part": self.part, "start_s": self.start, "end_s": self.end}


def _rate_of(t: NDArray[np.float64]) -> float:
    steps = np.diff(t)
    if len(steps) == 0 or not np.all(steps > 0):
        raise RecordingError("sample times do not increase", expected="strictly increasing times")
    return float(1.0 / np.median(steps))


def detect_lifts(
    elbow: ArrayLike,
    t: ArrayLike,
    *,
    segments: ArrayLike | None = None,
    min_prominence: float = 0.3,
    min_range: float = float(np.deg2rad(20.0)),
    min_spacing: float = 1.0,
    rest_speed_fraction: float = 0.05,
    top_fraction: float = 0.02,
) -> list[Lift]:
    """Lifts from the elbow flexion angle.

    Each lift is a peak of the angle whose prominence is at least ``min_prominence`` of the
    angle's whole range (and at least ``min_range``), peaks at least ``min_spacing`` apart.
    Its boundaries follow the elbow's speed, so they mark when the forearm moves:

    - start: the last sample before the rise's fastest point whose rising speed is at most
      ``rest_speed_fraction`` of that peak speed (the elbow starts to move);
    - top: the first arrival at the top: the first sample after the fastest point whose speed
      has fallen to that fraction in the upper tenth of the rise (when the speed never settles,
      the first sample within ``top_fraction`` of the rise of the highest angle);
    - lowering start and end: the same rules mirrored on the way down. Time at the top between
      top and lowering start is the hold, in no phase.

    Lifts never span a gap.

    Args:
        elbow: (T,) elbow flexion [rad], NaN in gaps.
        t: (T,) sample times [s].
        segments: (S, 2) [start, stop) index ranges free of gaps (default: the finite runs).
        min_prominence: smallest peak prominence as a fraction of the angle's range.
        min_range: smallest peak prominence [rad].
        min_spacing: shortest time between two tops [s].
        rest_speed_fraction: speed, as a fraction of the rise's (fall's) peak speed, below
            which the elbow counts as not moving.
        top_fraction: share of the rise (fall) within which the angle counts as at the top.

    Returns:
        Lifts in time order.
    """
    y = as_signal(elbow, min_samples=3, allow_nan=True, require_variance=False, what="elbow")
    times = np.asarray(t, dtype=np.float64)
    if y.ndim != 1 or times.shape != y.shape:
        raise RecordingError(
            f"elbow angle {y.shape} and times {times.shape} do not match", expected="(T,) each"
        )
    rate = _rate_of(times)
    if segments is None:
        segs = true_runs(np.isfinite(y))
    else:
        segs = np.asarray(segments, dtype=np.intp).reshape(-1, 2)
    span = float(np.nanmax(y) - np.nanmin(y))
    prominence = max(min_prominence * span, min_range)
    distance = max(1, round(min_spacing * rate))
    lifts: list[Lift] = []
    for i0, i1 in segs:
        if i1 - i0 >= 3:
            lifts += _segment_lifts(
                y[i0:i1], times[i0:i1], prominence, distance, rest_speed_fraction, top_fraction
            )
    return lifts


def _segment_lifts(
    seg: NDArray[np.float64],
    ts: NDArray[np.float64],
    prominence: float,
    distance: int,
    rest_fraction: float,
    top_fraction: float,
) -> list[Lift]:
    """The lifts of one gap-free stretch: (S,) angles [rad] at (S,) times [s]."""
    peaks, _ = scipy_signal().find_peaks(seg, prominence=prominence, distance=distance)
    speed = np.gradient(seg, ts)
    lifts: list[Lift] = []
    for k, p in enumerate(peaks):
        left = int(peaks[k - 1]) if k > 0 else 0
        right = int(peaks[k + 1]) if k + 1 < len(peaks) else len(seg) - 1
        lo = left + int(np.argmin(seg[left : p + 1]))
        hi = p + int(np.argmin(seg[p : right + 1]))
        s, top = _rise_bounds(
            seg[lo : p + 1], speed[lo : p + 1], 0, int(p) - lo, rest_fraction, top_fraction
        )
        s, top = s + lo, top + lo
        # The fall is the rise seen backwards in time: mirror the lift's samples.
        fall, fall_speed = seg[p : hi + 1][::-1], -speed[p : hi + 1][::-1]
        e_m, low_m = _rise_bounds(fall, fall_speed, 0, hi - int(p), rest_fraction, top_fraction)
        e, lower = hi - e_m, hi - low_m
        lifts.append(
            Lift(
                start=float(ts[s]),
                top=float(ts[top]),
                end=float(ts[e]),
                source="angle",
                start_angle=float(seg[s]),
                top_angle=float(seg[top]),
                end_angle=float(seg[e]),
                lower_start=float(ts[lower]) if lower > top else None,
            )
        )
    return lifts


def _rise_bounds(
    y: NDArray[np.float64],
    speed: NDArray[np.float64],
    lo: int,
    p: int,
    rest_fraction: float,
    top_fraction: float,
) -> tuple[int, int]:
    """(start, first arrival at the top) indices of the rise ``y[lo] -> y[p]`` (p = highest).

    Args:
        y: (T,) angle [rad].
        speed: (T,) its time derivative [rad/s].
        lo, p: indices of the resting minimum before the rise and of the highest angle.
        rest_fraction: share of the peak rising speed below which the elbow is at rest.
        top_fraction: share of the rise within which the angle counts as at the top.
    """
    if p <= lo:
        return lo, p
    k = lo + int(np.argmax(speed[lo : p + 1]))
    v_peak = float(speed[k])
    rise = float(y[p] - y[lo])
    if not v_peak > 0 or not rise > 0:
        return lo, p
    slow = speed <= rest_fraction * v_peak
    before = np.flatnonzero(slow[lo : k + 1])
    start = lo + int(before[-1]) if before.size else lo
    # Speed first: it marks the arrival exactly; the angle band is the fallback for noisy
    # angles whose speed never settles (it puts the top up to top_fraction of the rise early).
    stopped = np.flatnonzero(slow[k : p + 1] & (y[k : p + 1] >= y[p] - 0.1 * rise))
    near = np.flatnonzero(y[k : p + 1] >= y[p] - top_fraction * rise)
    top = k + int(stopped[0]) if stopped.size else k + int(near[0]) if near.size else p
    return start, top


def detect_emg_lifts(
    envelope: ArrayLike,
    rate: float,
    *,
    start: float = 0.0,
    smoothing: float = 1.0,
    min_prominence: float = 0.2,
    min_spacing: float = 1.0,
    rest_level: float = 0.1,
    names: list[str] | None = None,
) -> list[Lift]:
    """Lifts from EMG bursts when no joint angle is available.

    Each channel's envelope is scaled to [0, 1] between its 5th and 99th percentiles, the
    channels are averaged and smoothed (zero-phase, ``smoothing`` Hz). A lift is a burst peak
    with prominence >= ``min_prominence``, peaks >= ``min_spacing`` apart; it starts (ends) where
    the combined activity last rises from (first falls back to) ``rest_level`` before (after) the
    peak, and never beyond the neighbouring peaks. The top is placed at the burst's peak: an
    estimate, as EMG cannot tell exactly when the forearm stops rising.

    Args:
        envelope: (N,) or (N, C) EMG envelopes.
        rate: sampling rate [Hz].
        start: time of the first sample [s].
        smoothing: low-pass cut-off applied to the combined activity [Hz].
        min_prominence: smallest burst prominence (fraction of the scaled range).
        min_spacing: shortest time between bursts [s].
        rest_level: activity level (fraction of the scaled range) that counts as rest.
        names: channel names for error messages.

    Returns:
        Lifts (``source="emg"``) in time order.
    """
    rate = check_rate(rate)
    env = as_signal(envelope, names=names, min_samples=3, what="envelope")
    cols = env.reshape(env.shape[0], -1)
    lo = np.percentile(cols, 5, axis=0)
    hi = np.percentile(cols, 99, axis=0)
    activity = ((cols - lo) / (hi - lo)).mean(axis=1)
    signal = scipy_signal()
    if smoothing < 0.95 * rate / 2:
        sos = signal.butter(2, smoothing, fs=rate, output="sos")
        pad = min(3 * (2 * len(sos) + 1), len(activity) - 1)
        activity = signal.sosfiltfilt(sos, activity, padlen=pad)
    peaks, _ = signal.find_peaks(
        activity, prominence=min_prominence, distance=max(1, round(min_spacing * rate))
    )
    lifts: list[Lift] = []
    n = len(activity)
    for k, p in enumerate(peaks):
        left = int(peaks[k - 1]) if k > 0 else 0
        right = int(peaks[k + 1]) if k + 1 < len(peaks) else n - 1
        before = np.flatnonzero(activity[left : p + 1] <= rest_level)
        after = np.flatnonzero(activity[p : right + 1] <= rest_level)
        s = left + int(before[-1]) if len(before) else left + int(np.argmin(activity[left : p + 1]))
        e = p + int(after[0]) if len(after) else p + int(np.argmin(activity[p : right + 1]))
        lifts.append(
            Lift(start=start + s / rate, top=start + p / rate, end=start + e / rate, source="emg")
        )
    return lifts


def _crossing(t: NDArray[np.float64], y: NDArray[np.float64], i: int, level: float) -> float:
    """Time where y crosses ``level`` between samples i - 1 and i (linear interpolation)."""
    if i <= 0:
        return float(t[0])
    y0, y1 = y[i - 1], y[i]
    w = 0.0 if y1 == y0 else (level - y0) / (y1 - y0)
    return float(t[i - 1] + np.clip(w, 0.0, 1.0) * (t[i] - t[i - 1]))


def split_phases(
    elbow: ArrayLike,
    t: ArrayLike,
    lift: Lift,
    *,
    bounds: tuple[float, float] = DEFAULT_PHASE_BOUNDS,
) -> list[Phase]:
    """Split a lift into phases A/B/C by elbow flexion, on the way up and on the way down.

    On the way up (start -> top) a phase ends where the angle first reaches the next bound; on
    the way down (lowering start -> end) a phase ends where the angle last leaves it. A hold at
    the top (top -> lowering start) belongs to no phase. Phases the lift never enters are left
    out (a lift that starts at 50 deg has no concentric A).

    Args:
        elbow: (T,) elbow flexion [rad].
        t: (T,) sample times [s].
        lift: the lift to split.
        bounds: (A/B, B/C) elbow-flexion thresholds [rad].

    Returns:
        Concentric phases in order, then eccentric phases in order.
    """
    y = np.asarray(elbow, dtype=np.float64)
    times = np.asarray(t, dtype=np.float64)
    b1, b2 = bounds
    if not 0 < b1 < b2:
        raise RecordingError(f"phase bounds {bounds} rad", expected="0 < A/B bound < B/C bound")
    i_s, i_top, i_low, i_e = (
        int(np.searchsorted(times, x - 1e-9))
        for x in (lift.start, lift.top, lift.eccentric[0], lift.end)
    )
    i_e = min(i_e, len(times) - 1)
    names: tuple[PhaseName, PhaseName, PhaseName] = ("A", "B", "C")
    phases: list[Phase] = []
    # Concentric: times where the rising angle first reaches each bound.
    up_t, up_y = times[i_s : i_top + 1], y[i_s : i_top + 1]
    edges = [float(up_t[0])]
    for b in (b1, b2):
        above = np.flatnonzero(up_y >= b)
        edges.append(_crossing(up_t, up_y, int(above[0]), b) if len(above) else float(up_t[-1]))
    edges.append(float(up_t[-1]))
    for name, t0, t1 in zip(names, edges[:-1], edges[1:], strict=True):
        if t1 > t0:
            phases.append(Phase(name, "concentric", t0, t1))
    # Eccentric: times where the falling angle last leaves each bound, highest bound first.
    dn_t, dn_y = times[i_low : i_e + 1], y[i_low : i_e + 1]
    edges = [float(dn_t[0])]
    for b in (b2, b1):
        above = np.flatnonzero(dn_y >= b)
        if len(above) and above[-1] + 1 < len(dn_y):
            edges.append(_crossing(dn_t, dn_y, int(above[-1]) + 1, b))
        elif len(above):
            edges.append(float(dn_t[-1]))
        else:
            edges.append(float(dn_t[0]))
    edges.append(float(dn_t[-1]))
    for name, t0, t1 in zip(names[::-1], edges[:-1], edges[1:], strict=True):
        if t1 > t0:
            phases.append(Phase(name, "eccentric", t0, t1))
    return phases
