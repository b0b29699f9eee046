"""EMG processing checked against closed forms, NeuroKit2 with matched settings, and real files."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.analysis.emg import (
    activation_order,
    bandpass_sos,
    detect_onsets,
    emg_envelope,
    emg_filter,
    moving_rms,
    normalize_amplitude,
    peak_times,
    saturation_flags,
    tkeo,
)
from app.recordings.types import RecordingError
from tests.analysis._data import biosppy_emg, noraxon_mat

RATE = 2000.0


def _tone(freq: float, seconds: float = 4.0, rate: float = RATE) -> np.ndarray:
    t = np.arange(int(seconds * rate)) / rate
    return np.sin(2 * np.pi * freq * t)


def _gain(out: np.ndarray, inp: np.ndarray) -> float:
    # Ignore the edges, where the zero-phase filter's padding transient lives.
    core = slice(len(inp) // 4, 3 * len(inp) // 4)
    return float(np.std(out[core]) / np.std(inp[core]))


def test_bandpass_gain_matches_butterworth_magnitude() -> None:
    # Forward-backward filtering squares the Butterworth magnitude: |H|^2 with
    # |H(f)|^2 = 1 / (1 + (f/fc)^(2n)) for a low-pass edge; at the cut-off that is 1/2.
    lo_edge = emg_filter(_tone(20.0), RATE)
    assert _gain(lo_edge, _tone(20.0)) == pytest.approx(0.5, abs=0.02)
    mid = emg_filter(_tone(100.0), RATE)
    assert _gain(mid, _tone(100.0)) == pytest.approx(1.0, abs=0.01)
    slow = emg_filter(_tone(5.0), RATE)
    # Order-4 high-pass at 20 Hz seen at 5 Hz: |H|^2 = 1/(1+(20/5)^8) ~ 1.5e-5.
    assert _gain(slow, _tone(5.0)) < 1e-4


def test_band_is_capped_below_nyquist_and_empty_band_is_refused() -> None:
    _, (lo, hi) = bandpass_sos((20.0, 450.0), 500.0)
    assert lo == 20.0
    assert hi == pytest.approx(0.95 * 250.0)
    with pytest.raises(RecordingError, match="band-pass"):
        bandpass_sos((300.0, 450.0), 500.0)


def test_notch_removes_mains_and_harmonics() -> None:
    x = _tone(50.0) + _tone(150.0) + _tone(97.0)
    y = emg_filter(x, RATE, notch=50.0, harmonics=3)
    spectrum = np.abs(np.fft.rfft(y[2000:-2000]))
    freqs = np.fft.rfftfreq(len(y) - 4000, 1 / RATE)
    at = {f: spectrum[np.argmin(np.abs(freqs - f))] for f in (50.0, 150.0, 97.0)}
    assert at[50.0] < 0.01 * at[97.0]
    assert at[150.0] < 0.01 * at[97.0]


def test_lowpass_envelope_of_modulated_carrier_is_two_over_pi_amplitude() -> None:
    # Rectified sine has mean 2/pi of its amplitude; a slow modulation passes the 6 Hz low-pass.
    t = np.arange(int(6 * RATE)) / RATE
    amp = 1.0 + 0.5 * np.sin(2 * np.pi * 0.5 * t)
    x = amp * np.sin(2 * np.pi * 150.0 * t)
    env = emg_envelope(x, RATE)
    core = slice(2000, -2000)
    np.testing.assert_allclose(env[core], 2 / np.pi * amp[core], rtol=0.02)
    rms = emg_envelope(x, RATE, method="rms", rms_window=0.1)
    np.testing.assert_allclose(rms[core], amp[core] / np.sqrt(2), rtol=0.02)


def test_moving_rms_matches_direct_window() -> None:
    rng = np.random.default_rng(1)
    x = rng.standard_normal(500)
    got = moving_rms(x, 100.0, window=0.1)  # 5-sample half window
    i = 200
    assert got[i] == pytest.approx(np.sqrt(np.mean(x[i - 5 : i + 6] ** 2)))
    assert got[0] == pytest.approx(np.sqrt(np.mean(x[:6] ** 2)))


def test_envelope_agrees_with_neurokit2_on_real_curls() -> None:
    nk = pytest.importorskip("neurokit2")
    x, rate = noraxon_mat("NT-01")
    ours = emg_envelope(x, rate, band=(20.0, 450.0), lowpass=6.0, order=4)
    for j in range(2):
        band = nk.signal_filter(
            x[:, j] - x[:, j].mean(), sampling_rate=rate, lowcut=20, highcut=450, order=4
        )
        ref = nk.signal_filter(np.abs(band), sampling_rate=rate, highcut=6, order=4)
        corr = np.corrcoef(ours[:, j], ref)[0, 1]
        nrms = np.sqrt(np.mean((ours[:, j] - ref) ** 2)) / np.ptp(ref)
        # Stated tolerance: correlation > 0.99 and normalised RMS difference < 2 %.
        assert corr > 0.99
        assert nrms < 0.02


def test_all_channels_at_once_equal_one_by_one() -> None:
    x, rate = noraxon_mat("SP-01")
    both = emg_envelope(x[:20000], rate)
    one = emg_envelope(x[:20000, 1], rate)
    np.testing.assert_allclose(both[:, 1], one, rtol=1e-12, atol=1e-9)


def test_normalisation_by_peak_and_by_mvc() -> None:
    env = np.array([[1.0, 2.0], [3.0, 8.0], [2.0, 4.0]])
    np.testing.assert_allclose(normalize_amplitude(env).max(axis=0), [1.0, 1.0])
    np.testing.assert_allclose(normalize_amplitude(env, mvc=[6.0, 16.0])[1], [0.5, 0.5])
    with pytest.raises(RecordingError, match="MVC"):
        normalize_amplitude(env, mvc=0.0)


def test_saturation_flags_find_clipped_plateaus() -> None:
    rng = np.random.default_rng(2)
    x = rng.standard_normal(5000)
    clipped = np.clip(x, -2.5, 2.5)
    expected = np.abs(x) >= 2.5
    flags = saturation_flags(clipped, min_run=1)
    np.testing.assert_array_equal(flags, expected)
    # Unclipped noise has a single maximum sample, never a plateau.
    assert not saturation_flags(x).any()
    np.testing.assert_array_equal(saturation_flags(clipped, limit=2.5), expected)


def test_tkeo_of_a_sine_is_constant() -> None:
    # psi[A sin(w n)] = A^2 sin^2(w) exactly.
    w = 2 * np.pi * 0.05
    x = 3.0 * np.sin(w * np.arange(200))
    np.testing.assert_allclose(tkeo(x), 9.0 * np.sin(w) ** 2, rtol=1e-9)


def _bursts(rng: np.random.Generator, onsets: list[float], seconds: float = 12.0) -> np.ndarray:
    n = int(seconds * RATE)
    t = np.arange(n) / RATE
    gain = np.full(n, 0.05)
    for t0 in onsets:
        gain[(t >= t0) & (t < t0 + 1.0)] = 1.0
    return gain * rng.standard_normal(n)


@pytest.mark.parametrize("method", ["threshold", "tkeo"])
def test_onsets_of_synthetic_bursts(method: str) -> None:
    rng = np.random.default_rng(3)
    truth = [2.0, 5.0, 8.5]
    x = _bursts(rng, truth)
    filtered = emg_filter(x, RATE)
    signal = emg_envelope(x, RATE) if method == "threshold" else filtered
    found = detect_onsets(signal, RATE, method=method, k=3.0)  # type: ignore[arg-type]
    assert found.shape == (3, 2)
    # TKEO is sharp; the 6 Hz envelope rises over ~30 ms before crossing its threshold.
    tol = 0.03 if method == "tkeo" else 0.06
    np.testing.assert_allclose(found[:, 0], truth, atol=tol)
    np.testing.assert_allclose(found[:, 1], np.add(truth, 1.0), atol=0.1)


def test_threshold_and_tkeo_onsets_agree_on_real_bursts() -> None:
    x, rate = biosppy_emg("emg_1.txt")
    env = emg_envelope(x, rate)
    filtered = emg_filter(x, rate)
    a = detect_onsets(env, rate, floor=0.2)
    b = detect_onsets(filtered, rate, method="tkeo", floor=0.2)
    # The file's four clear contractions (envelope above 50 % of its maximum), found
    # independently of any threshold rule.
    strong = env > 0.5 * env.max()
    rises = np.flatnonzero(strong[1:] & ~strong[:-1]) / rate
    big = rises[np.r_[True, np.diff(rises) > 0.3]]
    assert len(big) == 4
    for onsets in (a, b):
        assert len(onsets) == 4
        # Each onset comes at most 30 ms after its burst's 50 % crossing (these bursts rise
        # within a few ms) and less than half a second before it.
        lead = big - onsets[:, 0]
        assert np.all((lead > -0.03) & (lead < 0.5))
    # Two different definitions of "on" land within 50 ms of each other.
    np.testing.assert_allclose(a[:, 0], b[:, 0], atol=0.05)
    # The classic rule (no floor) with k = 3 over-segments this non-stationary rest.
    assert len(detect_onsets(env, rate, floor=0.0)) > 10


def test_peak_times_of_gaussian_bumps() -> None:
    t = np.arange(2000) / 100.0
    env = np.exp(-(((t - 4.2) / 0.3) ** 2)) + np.exp(-(((t - 13.7) / 0.5) ** 2))
    got = peak_times(env, 100.0, [[2.0, 8.0], [10.0, 18.0], [30.0, 31.0]], start=0.0)
    np.testing.assert_allclose(got[:2], [4.2, 13.7], atol=0.011)
    assert np.isnan(got[2])


def test_activation_order_sorts_by_onset_inside_the_window() -> None:
    onsets = {
        "biceps": np.array([[1.3, 2.5], [6.1, 7.0]]),
        "deltoid": np.array([[0.8, 2.0], [5.9, 6.5]]),
        "forearm": np.array([[1.6, 1.9]]),
        "triceps": np.zeros((0, 2)),
    }
    first = activation_order(onsets, (0.5, 3.0))
    assert [m for m, _ in first] == ["deltoid", "biceps", "forearm"]
    second = activation_order(onsets, (6.0, 8.0))
    assert second == [("deltoid", 6.0), ("biceps", 6.1)]


def test_bad_input_names_the_channel() -> None:
    x = np.random.default_rng(4).standard_normal((1000, 2))
    x[10, 1] = np.nan
    with pytest.raises(RecordingError, match=r"'brachio'.*non-finite") as info:
        emg_envelope(x, RATE, names=["biceps", "brachio"])
    assert info.value.channel == "brachio"
    with pytest.raises(RecordingError, match="1 sample"):
        emg_envelope(np.ones(1), RATE, names=["biceps"])
    flat = np.random.default_rng(5).standard_normal((1000, 2))
    flat[:, 0] = 0.3
    with pytest.raises(RecordingError, match=r"'biceps'.*zero variance"):
        emg_envelope(flat, RATE, names=["biceps", "brachio"])
    with pytest.raises(RecordingError, match="too short"):
        emg_envelope(np.random.default_rng(6).standard_normal(10), RATE)
    with pytest.raises(RecordingError, match="positive rate"):
        emg_envelope(flat[:, 1], 0.0)


@settings(max_examples=200, deadline=None)
@given(
    mask=st.lists(st.booleans(), min_size=1, max_size=300),
    min_duration=st.integers(0, 10),
    min_gap=st.integers(0, 10),
)
def test_active_runs_are_clean(mask: list[bool], min_duration: int, min_gap: int) -> None:
    from app.analysis.emg import active_runs

    active = np.array(mask)
    runs = active_runs(active, 1.0, min_duration=min_duration, min_gap=min_gap)
    assert np.all(runs[:, 1] - runs[:, 0] >= min_duration)
    if len(runs) > 1:
        assert np.all(runs[1:, 0] - runs[:-1, 1] >= min_gap)
    # Every active sample that survives lies in a run, and runs start and end on active samples.
    for start, stop in runs:
        assert active[start] and active[stop - 1]
    # Runs only drop short bursts or bridge short pauses: any active run of at least
    # min_duration samples is covered.
    padded = np.concatenate(([False], active, [False]))
    edges = np.flatnonzero(padded[1:] != padded[:-1]).reshape(-1, 2)
    for start, stop in edges:
        if stop - start >= min_duration:
            assert np.any((runs[:, 0] <= start) & (runs[:, 1] >= stop))
