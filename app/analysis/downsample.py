"""Min/max-preserving downsampling of signals for plotting.

A plot of N samples on a screen of P pixels only needs, per pixel column, the smallest and the
largest sample: the envelope (and every spike) looks the same as with all N samples. The signal is
cut into ``points // 2`` buckets of consecutive samples; each bucket contributes its minimum and
its maximum, in time order. Missing samples (NaN) are skipped; a bucket with no valid sample
contributes nothing.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from app.errors import BioPlanError

FloatArray = NDArray[np.float64]


def minmax_downsample(t: FloatArray, y: FloatArray, points: int) -> tuple[FloatArray, FloatArray]:
    """Keep at most ``points`` samples of ``y(t)``, preserving each bucket's min and max.

    Args:
        t: (N,) sample times [s], increasing.
        y: (N,) samples (NaN = missing).
        points: largest number of samples to return (>= 2).

    Returns:
        (t_out, y_out), each (M,) with M <= points, in time order. When N <= points the valid
        samples are returned unchanged.
    """
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if t.shape != y.shape or t.ndim != 1:
        raise BioPlanError(f"t and y must be 1-D of equal length, got {t.shape} and {y.shape}")
    if points < 2:
        raise BioPlanError(f"points must be >= 2, got {points}")
    n = y.shape[0]
    if n <= points:
        ok = ~np.isnan(y)
        return t[ok], y[ok]
    buckets = points // 2
    size = -(-n // buckets)  # ceil: every bucket but the last is full
    pad = buckets * size - n
    grid = np.concatenate([y, np.full(pad, np.nan)]).reshape(buckets, size)
    valid = ~np.isnan(grid)
    # argmin/argmax ignore NaN when it is replaced by a value that can never win.
    lo = np.argmin(np.where(valid, grid, np.inf), axis=1)
    hi = np.argmax(np.where(valid, grid, -np.inf), axis=1)
    has = valid.any(axis=1)
    offset = np.arange(buckets) * size
    idx = np.concatenate([(offset + lo)[has], (offset + hi)[has]])
    idx = np.unique(idx)  # sorted: time order; a flat bucket gives one sample, not two
    return t[idx], y[idx]
