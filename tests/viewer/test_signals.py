"""The recording detail's analysis series, on the synthetic demo session (known truth)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from app.viewer.demo_seed import DEMO_MUSCLES, DEMO_NAME, synthetic_curls, synthetic_curls_csv
from app.viewer.signals import RecordingSignals, analyse_stored


@pytest.fixture(scope="module")
def signals() -> RecordingSignals:
    files = [(DEMO_NAME, synthetic_curls_csv(lifts=3, seed=5))]
    return RecordingSignals(3, analyse_stored(files, {"muscle_map": DEMO_MUSCLES}, 12.0))


@pytest.fixture(scope="module")
def truth() -> dict[str, Any]:
    return synthetic_curls(lifts=3, seed=5)


def test_angles_follow_the_recorded_goniometer(
    signals: RecordingSignals, truth: dict[str, Any]
) -> None:
    out = signals.series(points=800)
    elbow = out["angles"]["elbow_deg"]
    assert len(elbow["t"]) <= 800
    expected = np.interp(elbow["t"], truth["t"], truth["elbow_flexion"])
    # Low-pass filtered (6 Hz) against the raw curve: within a degree or two.
    assert np.max(np.abs(np.asarray(elbow["y"]) - expected)) < 2.5
    velocity = out["angles"]["elbow_velocity_deg_s"]
    from scipy.ndimage import uniform_filter1d

    # The goniometer's 0.03 deg noise differentiated at 1 kHz swamps the peak: average 41 ms.
    smooth = uniform_filter1d(truth["elbow_flexion"], 41)
    true_velocity = np.gradient(smooth, truth["t"])
    peak = np.max(np.abs(velocity["y"]))
    assert peak == pytest.approx(np.max(np.abs(true_velocity)), rel=0.1)


def test_lifts_phases_onsets_and_template(signals: RecordingSignals) -> None:
    out = signals.series(points=500)
    assert len(out["lifts"]) == 3
    for lift in out["lifts"]:
        names = [p["name"] for p in lift["phases"] if p["part"] == "concentric"]
        assert names == ["A", "B", "C"]
        # The synthetic lifts start every 4.9 s after 1.6 s of rest.
        assert (lift["start_s"] - 1.6) % 4.9 == pytest.approx(0.0, abs=0.3)
    sites = {e["muscle"] for e in out["emg"]}
    assert sites == set(DEMO_MUSCLES.values())
    assert all(len(e["envelope"]["t"]) <= 500 for e in out["emg"])
    # The synthetic deltoid switches on 0.12 s before the biceps, in every lift.
    onsets = {e["muscle"]: np.asarray(e["onsets"]) for e in out["emg"]}
    assert len(onsets["deltoid"]) == len(onsets["biceps"]) == 3
    assert np.all(onsets["deltoid"][:, 0] < onsets["biceps"][:, 0])
    template = out["template"]
    assert template["n_lifts"] == 3
    assert 50.0 < template["peak_velocity_angle_deg"] < 75.0
    assert template["activation_order"][0] == "deltoid"


def test_windows_cut_the_series(signals: RecordingSignals) -> None:
    out = signals.series(points=300, t0=5.0, t1=8.0)
    assert out["window"] == [5.0, 8.0]
    for e in out["emg"]:
        t = np.asarray(e["envelope"]["t"])
        assert t.min() >= 5.0 and t.max() <= 8.0 and len(t) <= 300
    assert out["span"][0] == 0.0 and out["span"][1] == pytest.approx(16.3, abs=0.01)
    with pytest.raises(ValueError, match="must be after its start"):
        signals.series(t0=3.0, t1=2.0)
    with pytest.raises(ValueError, match="points must be >= 2"):
        signals.series(points=1)


def test_gaps_stay_gaps() -> None:
    from app.viewer.signals import _window

    t = np.arange(1000) / 100.0
    y = np.sin(t)
    y[300:420] = np.nan  # 1.2 s without data
    out = _window(t, y, 200, None, None)
    nulls = [i for i, v in enumerate(out["y"]) if v is None]
    assert len(nulls) == 1
    i = nulls[0]
    assert out["t"][i - 1] < 3.0 and out["t"][i + 1] >= 4.2
    assert out["t"] == sorted(out["t"])
    # Without missing samples nothing is added.
    assert None not in _window(t, np.sin(t), 200, None, None)["y"]
