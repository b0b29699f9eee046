"""One time base for EMG and pose.

Clock convention: ``offset`` [s] is what must be added to a pose time to get the EMG time of the
same instant (t_emg = t_pose + offset). It comes from the user, from a sync event seen on both
clocks (:func:`event_offset`), or from cross-correlating the EMG envelope with the joint
acceleration (:func:`estimate_offset`). The cross-correlation estimate includes the
electromechanical delay (EMG leads the movement by some tens of ms), so a known sync event is
better when there is one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.recordings.types import RecordingError


def resample(t_source: ArrayLike, x_source: ArrayLike, t_target: ArrayLike) -> NDArray[np.float64]:
    """Linear resampling that keeps gaps: NaN where a neighbour is NaN or outside the source.

    Args:
        t_source: (N,) increasing source times [s].
        x_source: (N,) or (N, C) samples, NaN in gaps.
        t_target: (M,) target times [s] on the same clock.

    Returns:
        (M,) or (M, C) samples at the target times.
    """
    ts = np.asarray(t_source, dtype=np.float64)
    xs = np.asarray(x_source, dtype=np.float64)
    tt = np.asarray(t_target, dtype=np.float64)
    if xs.shape[0] != ts.shape[0]:
        raise RecordingError(
            f"{xs.shape[0]} samples but {ts.shape[0]} times", expected="one time per sample"
        )
    if ts.size < 2 or np.any(np.diff(ts) <= 0):
        raise RecordingError("source times do not increase", expected="increasing times")
    cols = xs.reshape(len(ts), -1)
    i = np.clip(np.searchsorted(ts, tt, side="right") - 1, 0, len(ts) - 2)
    w = (tt - ts[i]) / (ts[i + 1] - ts[i])
    out = cols[i] * (1 - w)[:, None] + cols[i + 1] * w[:, None]
    # An exact hit on a sample must not be spoiled by a NaN neighbour with zero weight.
    exact = w == 0
    out[exact] = cols[i[exact]]
    exact_hi = w == 1
    out[exact_hi] = cols[i[exact_hi] + 1]
    out[(tt < ts[0]) | (tt > ts[-1])] = np.nan
    return out.reshape((len(tt), *xs.shape[1:]))


def event_offset(t_event_emg: float, t_event_pose: float) -> float:
    """Offset [s] from one event seen on both clocks (e.g. a tap, a trigger, a marker)."""
    return float(t_event_emg) - float(t_event_pose)


def estimate_offset(
    emg_signal: ArrayLike,
    emg_rate: float,
    pose_signal: ArrayLike,
    pose_t: ArrayLike,
    *,
    emg_start: float = 0.0,
    max_lag: float = 0.5,
) -> float:
    """Offset between the clocks that best lines up EMG activity with the movement.

    The pose signal (normally |elbow acceleration|, NaN in gaps) is compared with the EMG
    envelope read at ``pose_t + offset`` for every candidate offset within ``max_lag`` on the
    pose sampling grid; the Pearson correlation's maximum is refined by a parabola through its
    neighbours.

    Args:
        emg_signal: (N,) EMG envelope, or (N, C) envelopes: each is tried and the one with the
            highest correlation peak decides.
        emg_rate: EMG sampling rate [Hz].
        pose_signal: (M,) kinematic signal on the pose clock, NaN in gaps.
        pose_t: (M,) pose sample times [s].
        emg_start: EMG time of the first EMG sample [s].
        max_lag: largest offset tried in either direction [s]. Keep it below half the
            repetition period: repeated lifts look alike, so a longer search can lock onto the
            neighbouring lift.

    Returns:
        offset [s] such that t_emg = t_pose + offset.
    """
    env = np.asarray(emg_signal, dtype=np.float64)
    cols = env.reshape(len(env), -1)
    te = emg_start + np.arange(len(cols)) / float(emg_rate)
    kin = np.asarray(pose_signal, dtype=np.float64)
    tp = np.asarray(pose_t, dtype=np.float64)
    if kin.shape != tp.shape:
        raise RecordingError("pose signal and times differ in length", expected="(M,) each")
    good = np.isfinite(kin)
    if good.sum() < 10:
        raise RecordingError(
            "too few valid pose samples to estimate the clock offset",
            expected="at least 10 samples, or give the offset",
        )
    step = float(np.median(np.diff(tp)))
    lags = np.arange(-max_lag, max_lag + step / 2, step)
    curves = np.full((cols.shape[1], len(lags)), -np.inf)
    for c in range(cols.shape[1]):
        for j, lag in enumerate(lags):
            e = np.interp(tp + lag, te, cols[:, c], left=np.nan, right=np.nan)
            m = good & np.isfinite(e)
            if m.sum() < 10:
                continue
            a = kin[m] - kin[m].mean()
            b = e[m] - e[m].mean()
            denom = np.sqrt(np.dot(a, a) * np.dot(b, b))
            if denom > 0:
                curves[c, j] = np.dot(a, b) / denom
    if not np.isfinite(curves).any():
        raise RecordingError(
            "EMG and pose do not overlap at any offset within the search range",
            expected=f"recordings overlapping within {max_lag} s, or give the offset",
        )
    # The channel that follows the movement most closely decides (muscles that hold a posture
    # rather than drive the elbow can even anti-correlate with it). Only true peaks count: a
    # maximum on the edge of the search range is where the overlap shrinks, not a match.
    peaks = np.zeros(curves.shape, dtype=bool)
    if len(lags) > 2:
        inner = curves[:, 1:-1]
        peaks[:, 1:-1] = (inner >= curves[:, :-2]) & (inner >= curves[:, 2:]) & np.isfinite(inner)
    if not peaks.any():
        peaks = np.isfinite(curves)
    heights = np.where(peaks, curves, -np.inf)
    row, k = (int(v) for v in np.unravel_index(int(np.argmax(heights)), heights.shape))
    best = float(lags[k])
    if 0 < k < len(lags) - 1 and np.isfinite(curves[row, k - 1 : k + 2]).all():
        y0, y1, y2 = curves[row, k - 1 : k + 2]
        bend = y0 - 2 * y1 + y2
        if bend < 0:
            best += 0.5 * (y0 - y2) / bend * step
    return best
