"""Input checks shared by the analysis modules: bad input becomes a RecordingError that names the
channel and what was expected, before numpy or scipy can fail deep inside. Also the small array
helpers they share (runs of a mask, the lazily imported ``scipy.signal``)."""

from __future__ import annotations

from collections.abc import Sequence
from types import ModuleType

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.recordings.types import RecordingError


def channel_label(names: Sequence[str] | None, index: int) -> str:
    """The name of column ``index`` for error messages."""
    if names is not None and index < len(names):
        return str(names[index])
    return f"column {index}"


def as_signal(
    x: ArrayLike,
    *,
    names: Sequence[str] | None = None,
    min_samples: int = 2,
    allow_nan: bool = False,
    require_variance: bool = True,
    what: str = "signal",
) -> NDArray[np.float64]:
    """``x`` as a float64 array of shape (N,) or (N, C), checked sample by sample.

    Raises:
        RecordingError: wrong shape, too few samples, NaN/inf (unless allowed) or a flat channel.
    """
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise RecordingError(
            f"{what} is not numeric ({exc})", expected="an array of numbers"
        ) from None
    if arr.ndim not in (1, 2):
        raise RecordingError(
            f"{what} has shape {arr.shape}",
            expected="(N,) samples or (N, C) samples x channels",
        )
    n = arr.shape[0]
    if n < min_samples:
        label = names[0] if names and arr.ndim == 1 else None
        raise RecordingError(
            f"{what} has {n} sample(s)",
            channel=label,
            expected=f"at least {min_samples} samples",
        )
    cols = arr.reshape(n, -1)

    # Fast path for the usual case: a NaN or inf anywhere makes its column's sum non-finite.
    # Column by column: numpy reduces a narrow (N, C) block along axis 0 several times slower.
    def extremes() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        hi = np.array([cols[:, j].max() for j in range(cols.shape[1])])
        lo = np.array([cols[:, j].min() for j in range(cols.shape[1])])
        return hi, lo

    sums = np.array([cols[:, j].sum() for j in range(cols.shape[1])])
    if np.isfinite(sums).all():
        hi, lo = extremes()
    else:
        finite = np.isfinite(cols)
        if finite.all():  # only the sum overflowed
            hi, lo = extremes()
        else:
            if not allow_nan:
                col = int(np.argmin(finite.all(axis=0)))
                row = int(np.argmin(finite[:, col]))
                raise RecordingError(
                    f"{what} has a non-finite value (NaN or inf) at sample {row}",
                    channel=channel_label(names, col),
                    expected="finite samples only",
                )
            n_finite = finite.sum(axis=0)
            if (n_finite == 0).any():
                col = int(np.argmin(n_finite))
                raise RecordingError(
                    f"{what} has no finite samples",
                    channel=channel_label(names, col),
                    expected="finite samples",
                )
            hi = np.where(finite, cols, -np.inf).max(axis=0)
            lo = np.where(finite, cols, np.inf).min(axis=0)
    if require_variance:
        flat = np.flatnonzero(~(hi > lo))
        if flat.size:
            raise RecordingError(
                f"{what} is constant (zero variance)",
                channel=channel_label(names, int(flat[0])),
                expected="a signal that varies",
            )
    return arr


def check_rate(rate: float, *, what: str = "sampling rate") -> float:
    """A positive, finite sampling rate [Hz]."""
    try:
        value = float(rate)
    except (TypeError, ValueError):
        raise RecordingError(f"{what} {rate!r} is not a number", expected="a rate in Hz") from None
    if not np.isfinite(value) or value <= 0:
        raise RecordingError(f"{what} is {value}", expected="a positive rate in Hz")
    return value


def scipy_signal() -> ModuleType:
    """``scipy.signal``, imported on first use: importing it takes most of a second."""
    from scipy import signal

    module: ModuleType = signal
    return module


def true_runs(mask: ArrayLike) -> NDArray[np.intp]:
    """(M, 2) [start, stop) index pairs of the runs of True in a (T,) boolean mask."""
    padded = np.concatenate(([False], np.asarray(mask, dtype=bool), [False]))
    return np.flatnonzero(padded[1:] != padded[:-1]).reshape(-1, 2)
