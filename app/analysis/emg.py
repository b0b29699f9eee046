"""Surface-EMG processing: filtering, envelopes, normalisation, saturation, onsets and order.

Every function takes plain arrays: (N,) for one channel or (N, C) for C channels sampled at
``rate`` [Hz], in the recording's unit (V, mV, uV or ADC counts; envelopes keep that unit).
All channels are filtered in one call along the time axis. Filters are Butterworth in
second-order sections, applied forward and backward (zero phase) so onsets and peaks are not
delayed. ``scipy.signal`` is imported inside the functions because importing it costs most of a
second and the CLI should start fast.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.analysis._checks import as_signal, channel_label, check_rate, scipy_signal, true_runs
from app.recordings.types import RecordingError

EnvelopeMethod = Literal["lowpass", "rms"]
OnsetMethod = Literal["threshold", "tkeo"]

#: The band-pass upper edge is capped at this fraction of the Nyquist frequency.
NYQUIST_CAP = 0.95


def _columns(arr: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N,) or (N, C) -> a (C, N) view; rows are read one at a time."""
    return arr.reshape(arr.shape[0], -1).T


def _restore(rows: NDArray[np.float64], ndim: int) -> NDArray[np.float64]:
    return rows[0] if ndim == 1 else rows.T


def _padlen(sos: NDArray[np.float64]) -> int:
    # The same default edge padding as scipy.signal.sosfiltfilt.
    n_zeros = min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    return 3 * (2 * len(sos) + 1 - n_zeros)


def _check_length(sos: NDArray[np.float64], n: int, names: Sequence[str] | None) -> None:
    need = _padlen(sos) + 1
    if n < need:
        raise RecordingError(
            f"signal has {n} samples, too short to filter",
            channel=channel_label(names, 0) if names else None,
            expected=f"at least {need} samples",
        )


def _filtfilt(
    sos: NDArray[np.float64], rows: NDArray[np.float64], names: Sequence[str] | None
) -> NDArray[np.float64]:
    """Zero-phase filter each row of (C, N) ``rows``. One channel at a time: a 1-D channel
    stays in cache, which makes this faster than one call on the whole (C, N) block."""
    _check_length(sos, rows.shape[-1], names)
    sosfiltfilt = scipy_signal().sosfiltfilt
    out = np.empty(rows.shape)
    for j in range(rows.shape[0]):
        out[j] = sosfiltfilt(sos, rows[j])
    return out


def bandpass_sos(
    band: tuple[float, float], rate: float, *, order: int = 4
) -> tuple[NDArray[np.float64], tuple[float, float]]:
    """Butterworth band-pass (or high-pass/low-pass) sections with the upper edge capped.

    Args:
        band: (low, high) cut-offs [Hz]; ``low = 0`` gives a low-pass, ``high >= Nyquist`` is
            capped at ``NYQUIST_CAP`` times the Nyquist frequency.
        rate: sampling rate [Hz].
        order: Butterworth order per edge.

    Returns:
        (sections, (low, high)) with the cut-offs actually used [Hz].
    """
    rate = check_rate(rate)
    lo, hi = float(band[0]), float(band[1])
    nyq = rate / 2.0
    hi_eff = min(hi, NYQUIST_CAP * nyq)
    if lo < 0 or not lo < hi_eff:
        raise RecordingError(
            f"band-pass {lo:g}-{hi:g} Hz is empty at {rate:g} Hz sampling "
            f"(upper edge capped at {hi_eff:g} Hz)",
            expected="0 <= low cut-off < high cut-off < Nyquist",
        )
    signal = scipy_signal()
    if lo == 0:
        sos = signal.butter(order, hi_eff, btype="lowpass", fs=rate, output="sos")
    else:
        sos = signal.butter(order, (lo, hi_eff), btype="bandpass", fs=rate, output="sos")
    return np.asarray(sos, dtype=np.float64), (lo, hi_eff)


def _notch_sos(mains: float, rate: float, *, harmonics: int, quality: float) -> NDArray[np.float64]:
    signal = scipy_signal()
    sections = []
    nyq = rate / 2.0
    for k in range(1, harmonics + 1):
        f0 = k * mains
        if f0 >= NYQUIST_CAP * nyq:
            break
        b, a = signal.iirnotch(f0, quality, fs=rate)
        sections.append(signal.tf2sos(b, a))
    if not sections:
        return np.zeros((0, 6))
    return np.concatenate(sections).astype(np.float64)


def _band_sos(
    rate: float,
    band: tuple[float, float],
    notch: float | None,
    harmonics: int,
    notch_quality: float,
    order: int,
) -> NDArray[np.float64]:
    sos, _ = bandpass_sos(band, rate, order=order)
    if notch is not None:
        if not notch > 0:
            raise RecordingError(f"notch frequency is {notch}", expected="mains frequency in Hz")
        notches = _notch_sos(notch, rate, harmonics=harmonics, quality=notch_quality)
        sos = np.concatenate([sos, notches])
    return sos


def emg_process(
    x: ArrayLike,
    rate: float,
    *,
    band: tuple[float, float] | None = (20.0, 450.0),
    notch: float | None = None,
    harmonics: int = 3,
    notch_quality: float = 30.0,
    lowpass: float = 6.0,
    method: EnvelopeMethod = "lowpass",
    rms_window: float = 0.1,
    order: int = 4,
    names: Sequence[str] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Filtered EMG and its envelope in one pass (see :func:`emg_filter`, :func:`emg_envelope`).

    Returns:
        (filtered, envelope), each of the shape of ``x`` and in its unit.
    """
    rate = check_rate(rate)
    arr = as_signal(x, names=names, min_samples=2, what="EMG")
    if method not in ("lowpass", "rms"):
        raise RecordingError(f"unknown envelope method {method!r}", expected="'lowpass' or 'rms'")
    cols = _columns(arr)
    n = cols.shape[-1]
    band_sos = (
        _band_sos(rate, band, notch, harmonics, notch_quality, order) if band is not None else None
    )
    env_sos = bandpass_sos((0.0, lowpass), rate, order=order)[0] if method == "lowpass" else None
    for sos in (band_sos, env_sos):
        if sos is not None:
            _check_length(sos, n, names)
    signal = scipy_signal()
    filtered = np.empty(cols.shape)
    envelope = np.empty(cols.shape)
    for j in range(cols.shape[0]):
        # DC removal first: the band-pass would remove it too, but the filter's edge padding
        # (odd extension) is cleaner without an offset.
        col = cols[j] - cols[j].mean()
        f = signal.sosfiltfilt(band_sos, col) if band_sos is not None else col
        filtered[j] = f
        if env_sos is not None:
            envelope[j] = signal.sosfiltfilt(env_sos, np.abs(f))
    if env_sos is None:
        envelope = _columns(moving_rms(_restore(filtered, arr.ndim), rate, window=rms_window))
    return _restore(filtered, arr.ndim), _restore(envelope, arr.ndim)


def emg_filter(
    x: ArrayLike,
    rate: float,
    *,
    band: tuple[float, float] = (20.0, 450.0),
    notch: float | None = None,
    harmonics: int = 3,
    notch_quality: float = 30.0,
    order: int = 4,
    names: Sequence[str] | None = None,
) -> NDArray[np.float64]:
    """Remove the DC offset, band-pass and optionally notch raw EMG (zero phase).

    Args:
        x: (N,) or (N, C) raw EMG in any unit.
        rate: sampling rate [Hz].
        band: (low, high) band-pass cut-offs [Hz]; the upper edge is capped below Nyquist.
        notch: mains frequency [Hz] (50 or 60) to notch out with its harmonics, or None.
        harmonics: how many multiples of ``notch`` to remove (those below Nyquist).
        notch_quality: quality factor Q of each notch.
        order: Butterworth order per band edge.
        names: channel names, used in error messages.

    Returns:
        Filtered EMG, same shape and unit as ``x``.

    Raises:
        RecordingError: NaN/inf samples, too few samples, a flat channel, or an empty band.
    """
    rate = check_rate(rate)
    arr = as_signal(x, names=names, min_samples=2, what="EMG")
    cols = _columns(arr)
    sos = _band_sos(rate, band, notch, harmonics, notch_quality, order)
    centred = np.ascontiguousarray(cols) - cols.mean(axis=-1, keepdims=True)
    return _restore(_filtfilt(sos, centred, names), arr.ndim)


def moving_rms(x: ArrayLike, rate: float, *, window: float = 0.1) -> NDArray[np.float64]:
    """Centred moving root-mean-square, windows shrinking at the edges.

    Args:
        x: (N,) or (N, C) signal (normally band-passed EMG).
        rate: sampling rate [Hz].
        window: window length [s].

    Returns:
        Same shape as ``x``, in its unit.
    """
    rate = check_rate(rate)
    arr = as_signal(x, min_samples=1, require_variance=False, what="EMG")
    if not window > 0:
        raise RecordingError(f"RMS window is {window} s", expected="a positive window length")
    rows = _columns(arr)
    n = rows.shape[-1]
    half = max(round(window * rate / 2.0), 0)
    csum = np.zeros((rows.shape[0], n + 1))
    np.cumsum(rows * rows, axis=-1, out=csum[:, 1:])
    idx = np.arange(n)
    lo = np.clip(idx - half, 0, n)
    hi = np.clip(idx + half + 1, 0, n)
    mean_sq = (csum[:, hi] - csum[:, lo]) / (hi - lo)
    # Cumulative sums can cancel to tiny negative values on flat stretches.
    return _restore(np.sqrt(np.maximum(mean_sq, 0.0)), arr.ndim)


def emg_envelope(
    x: ArrayLike,
    rate: float,
    *,
    band: tuple[float, float] | None = (20.0, 450.0),
    notch: float | None = None,
    harmonics: int = 3,
    lowpass: float = 6.0,
    method: EnvelopeMethod = "lowpass",
    rms_window: float = 0.1,
    order: int = 4,
    names: Sequence[str] | None = None,
) -> NDArray[np.float64]:
    """Linear envelope of EMG: filter, then rectify + zero-phase low-pass, or moving RMS.

    Args:
        x: (N,) or (N, C) raw EMG, or already band-passed EMG when ``band`` is None.
        rate: sampling rate [Hz].
        band: band-pass cut-offs [Hz] (see :func:`emg_filter`), or None to skip it.
        notch: mains frequency [Hz] to notch (with harmonics), or None.
        harmonics: number of mains multiples notched.
        lowpass: envelope low-pass cut-off [Hz] (``method="lowpass"``).
        method: ``"lowpass"`` (full-wave rectification then low-pass) or ``"rms"``.
        rms_window: moving-RMS window [s] (``method="rms"``).
        order: Butterworth order of the band-pass edges and of the envelope low-pass.
        names: channel names, used in error messages.

    Returns:
        (N,) or (N, C) envelope in the unit of ``x``. The low-pass envelope is not clipped, so it
        can dip slightly below zero where the filter rings after a burst.
    """
    return emg_process(
        x,
        rate,
        band=band,
        notch=notch,
        harmonics=harmonics,
        lowpass=lowpass,
        method=method,
        rms_window=rms_window,
        order=order,
        names=names,
    )[1]


def normalize_amplitude(
    envelope: ArrayLike, *, mvc: float | ArrayLike | None = None
) -> NDArray[np.float64]:
    """Scale envelopes to a reference: the MVC value(s), or each channel's peak.

    Args:
        envelope: (N,) or (N, C) envelope.
        mvc: reference amplitude per channel (scalar or (C,)) in the envelope's unit, e.g. the
            envelope peak of a maximal voluntary contraction; None uses each channel's peak.

    Returns:
        Same shape, dimensionless (1 = reference).
    """
    arr = as_signal(envelope, min_samples=1, require_variance=False, what="envelope")
    if mvc is None:
        cols = arr.reshape(arr.shape[0], -1)
        peaks = [max(cols[:, j].max(), -cols[:, j].min()) for j in range(cols.shape[1])]
        ref = np.array(peaks).reshape(arr.shape[1:])
    else:
        ref = np.broadcast_to(np.asarray(mvc, dtype=np.float64), arr.shape[1:]).copy()
    bad = ~(np.asarray(ref) > 0) | ~np.isfinite(ref)
    if np.any(bad):
        raise RecordingError(
            f"normalisation reference is {ref}", expected="a positive MVC value or a non-zero peak"
        )
    out: NDArray[np.float64] = arr / ref
    return out


def saturation_flags(
    x: ArrayLike, *, limit: float | None = None, min_run: int = 3
) -> NDArray[np.bool_]:
    """Samples where the amplifier or converter is saturated (clipped).

    Args:
        x: (N,) or (N, C) raw EMG.
        limit: the input range |x| [unit of x] if known: samples at or beyond it are flagged.
            Without it, a clipped stretch is recognised as ``min_run`` or more consecutive samples
            stuck at the channel's own maximum or minimum.
        min_run: shortest plateau counted as clipping [samples].

    Returns:
        Boolean mask of the shape of ``x``.
    """
    arr = as_signal(x, min_samples=1, require_variance=False, what="EMG")
    cols = arr.reshape(arr.shape[0], -1)
    if limit is not None:
        return (np.abs(arr) >= limit).reshape(arr.shape)
    flags = np.zeros(cols.shape, dtype=bool, order="F")
    for j in range(cols.shape[1]):
        col = cols[:, j]
        at_rail = (col == col.max()) | (col == col.min())
        if np.count_nonzero(at_rail) < min_run:  # the usual case: no plateau possible
            continue
        for start, stop in true_runs(at_rail):
            if stop - start >= min_run:
                flags[start:stop, j] = True
    return flags.reshape(arr.shape)


def tkeo(x: ArrayLike) -> NDArray[np.float64]:
    """Teager-Kaiser energy operator psi[n] = x[n]^2 - x[n-1] x[n+1] along the time axis.

    Args:
        x: (N,) or (N, C) signal, N >= 3.

    Returns:
        Same shape; the two end samples repeat their neighbours.
    """
    arr = as_signal(x, min_samples=3, require_variance=False, what="EMG")
    out = np.empty_like(arr)
    out[1:-1] = arr[1:-1] ** 2 - arr[:-2] * arr[2:]
    out[0] = out[1]
    out[-1] = out[-2]
    return out


def baseline_stats(
    x: NDArray[np.float64],
    rate: float,
    *,
    baseline: tuple[float, float] | None = None,
    window: float = 0.5,
) -> tuple[float, float]:
    """Mean and SD of a 1-D signal over its rest period.

    Args:
        x: (N,) signal (envelope).
        rate: sampling rate [Hz].
        baseline: (start, end) of a known rest period [s from the first sample]; None picks the
            ``window``-long stretch with the lowest mean, i.e. the quietest rest.
        window: length of the automatically chosen rest period [s].

    Returns:
        (mean, standard deviation) in the unit of ``x``.
    """
    n = x.shape[0]
    if baseline is not None:
        i0 = max(round(baseline[0] * rate), 0)
        i1 = min(round(baseline[1] * rate), n)
        if i1 - i0 < 2:
            raise RecordingError(
                f"baseline {baseline} s holds fewer than 2 samples",
                expected=f"a period inside 0-{n / rate:g} s",
            )
        seg = x[i0:i1]
    else:
        w = min(max(round(window * rate), 2), n)
        csum = np.concatenate(([0.0], np.cumsum(x)))
        means = (csum[w:] - csum[:-w]) / w
        i0 = int(np.argmin(means))
        seg = x[i0 : i0 + w]
    return float(seg.mean()), float(seg.std())


def detect_onsets(
    x: ArrayLike,
    rate: float,
    *,
    method: OnsetMethod = "threshold",
    k: float = 3.0,
    baseline: tuple[float, float] | None = None,
    baseline_window: float = 0.5,
    floor: float = 0.1,
    min_duration: float = 0.1,
    min_gap: float = 0.1,
    tkeo_lowpass: float = 50.0,
    name: str | None = None,
) -> NDArray[np.float64]:
    """Onset and offset times of muscle activity in one channel.

    ``"threshold"``: ``x`` is an envelope; active where it exceeds baseline mean + k SD, but at
    least ``floor`` of the way from the baseline mean to the signal's 99th percentile. The floor
    matters because a smooth envelope has a tiny SD at rest, so mean + k SD alone is crossed by
    slow drifts of a non-stationary baseline (``floor=0`` gives the classic rule).
    ``"tkeo"``: ``x`` is band-passed EMG; the Teager-Kaiser energy is rectified and low-passed at
    ``tkeo_lowpass`` Hz before the same threshold is applied (sharper onsets, Solnik et al. 2010).
    Active stretches closer than ``min_gap`` are merged, then those shorter than ``min_duration``
    are dropped.

    Args:
        x: (N,) envelope (threshold) or band-passed EMG (tkeo).
        rate: sampling rate [Hz].
        method: ``"threshold"`` or ``"tkeo"``.
        k: threshold in baseline standard deviations above the baseline mean.
        floor: lowest threshold as a fraction of (99th percentile - baseline mean).
        baseline: (start, end) rest period [s from the first sample], or None for the quietest
            ``baseline_window`` stretch.
        baseline_window: length of the automatic rest period [s].
        min_duration: shortest activation kept [s].
        min_gap: shorter pauses between activations are bridged [s].
        tkeo_lowpass: low-pass cut-off of the TKEO envelope [Hz].
        name: channel name for error messages.

    Returns:
        (M, 2) onset and offset times [s from the first sample].
    """
    rate = check_rate(rate)
    arr = as_signal(x, names=[name] if name else None, min_samples=3, what="EMG")
    if arr.ndim != 1:
        raise RecordingError(
            f"onset detection takes one channel, got shape {arr.shape}", expected="(N,)"
        )
    if method == "tkeo":
        energy = np.abs(tkeo(arr))
        sos, _ = bandpass_sos((0.0, tkeo_lowpass), rate, order=2)
        arr = _filtfilt(sos, energy[None, :], [name] if name else None)[0]
    elif method != "threshold":
        raise RecordingError(f"unknown onset method {method!r}", expected="'threshold' or 'tkeo'")
    # The statistics only need the signal's slow shape: on long recordings read them from a
    # 200 Hz subsample (the envelope is low-passed far below 100 Hz), which is ten times faster.
    step = max(1, int(rate // 200.0)) if len(arr) > 20_000 else 1
    sub = arr[::step]
    mean, sd = baseline_stats(sub, rate / step, baseline=baseline, window=baseline_window)
    threshold = max(mean + k * sd, mean + floor * (float(np.percentile(sub, 99)) - mean))
    runs = active_runs(
        arr > threshold,
        rate,
        min_duration=min_duration,
        min_gap=min_gap,
    )
    return runs.astype(np.float64) / rate


def active_runs(
    active: NDArray[np.bool_], rate: float, *, min_duration: float, min_gap: float
) -> NDArray[np.intp]:
    """Clean a 1-D activity mask into (M, 2) [start, stop) sample index pairs.

    Pauses shorter than ``min_gap`` [s] are bridged first, then runs shorter than
    ``min_duration`` [s] are dropped.
    """
    runs = true_runs(active)
    if len(runs) > 1:
        bridged = (runs[1:, 0] - runs[:-1, 1]) < min_gap * rate
        # A merged run starts after every pause that is not bridged and ends before one.
        starts = runs[np.r_[True, ~bridged], 0]
        stops = runs[np.r_[~bridged, True], 1]
        runs = np.stack([starts, stops], axis=1)
    if len(runs):
        runs = runs[(runs[:, 1] - runs[:, 0]) >= min_duration * rate]
    return runs


def peak_times(
    envelope: ArrayLike, rate: float, intervals: ArrayLike, *, start: float = 0.0
) -> NDArray[np.float64]:
    """Time of the envelope maximum inside each interval.

    Args:
        envelope: (N,) or (N, C) envelope.
        rate: sampling rate [Hz].
        intervals: (M, 2) (start, end) times [s, same clock as ``start``].
        start: time of the first envelope sample [s].

    Returns:
        (M,) or (M, C) peak times [s]; NaN where an interval holds no sample.
    """
    rate = check_rate(rate)
    arr = as_signal(envelope, min_samples=1, require_variance=False, what="envelope")
    iv = np.asarray(intervals, dtype=np.float64).reshape(-1, 2)
    cols = arr.reshape(arr.shape[0], -1)
    out = np.full((len(iv), cols.shape[1]), np.nan)
    n = cols.shape[0]
    for m, (t0, t1) in enumerate(iv):
        i0 = max(int(np.ceil((t0 - start) * rate - 1e-9)), 0)
        i1 = min(int(np.floor((t1 - start) * rate + 1e-9)) + 1, n)
        if i1 > i0:
            out[m] = start + (i0 + np.argmax(cols[i0:i1], axis=0)) / rate
    return out[:, 0] if arr.ndim == 1 else out


def activation_order(
    onsets: Mapping[str, ArrayLike], window: tuple[float, float]
) -> list[tuple[str, float]]:
    """Muscles ordered by when they switch on inside a window (one repetition).

    A muscle counts from the first activation that overlaps the window; if it was already active
    when the window opened, its onset is the window's start.

    Args:
        onsets: muscle -> (M, 2) onset/offset times [s].
        window: (start, end) of the repetition [s], usually widened a little before the
            movement starts since EMG leads motion.

    Returns:
        [(muscle, onset time [s])] sorted by onset; muscles silent in the window are left out.
    """
    t0, t1 = window
    found: list[tuple[str, float]] = []
    for muscle, iv_like in onsets.items():
        iv = np.asarray(iv_like, dtype=np.float64).reshape(-1, 2)
        hit = iv[(iv[:, 1] > t0) & (iv[:, 0] < t1)]
        if len(hit):
            found.append((muscle, max(float(hit[0, 0]), t0)))
    found.sort(key=lambda item: item[1])
    return found
