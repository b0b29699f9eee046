"""Plot overlays of an analysis: decimated, stored, windowed; on the synthetic demo session."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from app.analysis import AnalysisOverlays, AnalysisResult, OverlaysError, analyze_recordings
from app.analysis.overlays import downsample_with_gaps
from app.db.arrays import decode_arrays, encode_arrays
from app.recordings import read_bytes
from app.services.demo import DEMO_MUSCLES, DEMO_NAME, synthetic_curls, synthetic_curls_csv


@pytest.fixture(scope="module")
def result() -> AnalysisResult:
    recording = read_bytes(synthetic_curls_csv(lifts=3, seed=5), DEMO_NAME)
    return analyze_recordings([recording], muscle_map=DEMO_MUSCLES, load_mass=12.0)


@pytest.fixture(scope="module")
def overlays(result: AnalysisResult) -> AnalysisOverlays:
    """Through storage and back, as the page gets them."""
    stored = encode_arrays(AnalysisOverlays.from_result(result).to_arrays())
    return AnalysisOverlays.from_arrays(decode_arrays(stored))


@pytest.fixture(scope="module")
def truth() -> dict[str, Any]:
    return synthetic_curls(lifts=3, seed=5)


def test_angles_follow_the_recorded_goniometer(
    overlays: AnalysisOverlays, truth: dict[str, Any]
) -> None:
    out = overlays.window(points=800)
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


def test_lifts_phases_onsets_and_template(
    overlays: AnalysisOverlays, result: AnalysisResult
) -> None:
    out = overlays.window(points=500)
    assert len(out["lifts"]) == 3
    for lift in out["lifts"]:
        names = [p["name"] for p in lift["phases"] if p["part"] == "concentric"]
        assert names == ["A", "B", "C"]
        # The synthetic lifts start every 4.9 s after 1.6 s of rest.
        # (Distance to the nearest multiple, so a start a sample early does not wrap to 4.89.)
        phase = (lift["start_s"] - 1.6) % 4.9
        assert min(phase, 4.9 - phase) == pytest.approx(0.0, abs=0.3)
    # One file, so its clock is the analysis clock: the phases are the analysis's own.
    for lift, report in zip(out["lifts"], result.recordings[0].lifts, strict=True):
        assert [tuple(p.items()) for p in lift["phases"]] == [
            (
                ("name", s.phase.name),
                ("part", s.phase.part),
                ("start_s", s.phase.start),
                ("end_s", s.phase.end),
            )
            for s in report.phases
        ]
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
    # The same template as the analysis's own (what the job stores as JSON).
    assert template["peak_velocity_angle_deg"] == pytest.approx(
        result.template.to_dict()["peak_velocity_angle_deg"]
    )
    json.dumps(out, allow_nan=False)  # strict JSON: what the route sends


def test_decimation_keeps_the_envelope(overlays: AnalysisOverlays, result: AnalysisResult) -> None:
    """200 samples/s (min/max of 10 ms) against the full-rate envelope of the analysis."""
    for i, muscle in enumerate(result.recordings[0].emg):
        t, y = overlays.series[f"emg.{i}"]
        duration = muscle.t[-1] - muscle.t[0]
        assert len(t) <= 200 * duration + 2 < len(muscle.t)
        # Extremes survive exactly (to float32).
        assert y.max() == pytest.approx(muscle.envelope.max(), rel=1e-6)
        assert y.min() == pytest.approx(muscle.envelope.min(), rel=1e-6, abs=1e-12)
        # Between stored samples the 6 Hz envelope is a straight line to within 1 % of its peak.
        between = np.interp(muscle.t, t, y)
        assert np.max(np.abs(between - muscle.envelope)) < 0.01 * muscle.envelope.max()


def test_windows_cut_the_series(overlays: AnalysisOverlays) -> None:
    out = overlays.window(points=300, t0=5.0, t1=8.0)
    assert out["window"] == [5.0, 8.0]
    for e in out["emg"]:
        t = np.asarray(e["envelope"]["t"])
        assert t.min() >= 5.0 and t.max() <= 8.0 and len(t) <= 300
    assert out["span"][0] == 0.0 and out["span"][1] == pytest.approx(16.3, abs=0.01)
    with pytest.raises(OverlaysError, match="must not be before its start"):
        overlays.window(t0=3.0, t1=2.0)
    # An empty window is a window (issue 14: t0 = t1 was refused): the samples at that instant.
    t_stored = np.asarray(overlays.window(points=10**6)["emg"][0]["envelope"]["t"])
    instant = float(t_stored[len(t_stored) // 2])
    for at, expected in ((instant, [instant]), (instant + 1e-7, [])):
        point = overlays.window(points=300, t0=at, t1=at)
        assert point["window"] == [at, at]
        assert point["emg"][0]["envelope"]["t"] == expected
    with pytest.raises(OverlaysError, match="points must be >= 2"):
        overlays.window(points=1)


def test_gaps_stay_gaps_through_storage_and_windows() -> None:
    t = np.arange(10000) / 1000.0
    y = np.sin(t)
    y[3000:4200] = np.nan  # 1.2 s without data
    stored_t, stored_y = downsample_with_gaps(t, y, 2000)
    assert np.isnan(stored_y).sum() == 1
    shown_t, shown_y = downsample_with_gaps(stored_t, stored_y, 200)
    gap = np.flatnonzero(np.isnan(shown_y))
    assert len(gap) == 1
    i = gap[0]
    assert shown_t[i - 1] < 3.0 and shown_t[i + 1] >= 4.2
    assert np.all(np.diff(shown_t) >= 0)
    # Without missing samples nothing is added.
    assert not np.isnan(downsample_with_gaps(t, np.sin(t), 200)[1]).any()


def test_foreign_arrays_are_refused() -> None:
    with pytest.raises(OverlaysError, match=r"no 'meta\.json'"):
        AnalysisOverlays.from_arrays({"emg.0.t": np.zeros(3)})
    meta = np.frombuffer(b"{}", dtype=np.uint8)
    with pytest.raises(OverlaysError, match="no values"):
        AnalysisOverlays.from_arrays({"meta.json": meta, "emg.0.t": np.zeros(3)})
    with pytest.raises(OverlaysError, match="unreadable metadata"):
        AnalysisOverlays.from_arrays({"meta.json": np.frombuffer(b"\xff{", dtype=np.uint8)})


def test_separate_trials_keep_their_own_spans_angles_and_lifts() -> None:
    """Two trials analysed together as separate files: each has its own entry with its span
    on its own clock, its angles and its lifts; nothing of one is drawn on the other's."""
    a = read_bytes(synthetic_curls_csv(lifts=2, seed=1), "trial_a.csv")
    b = read_bytes(synthetic_curls_csv(lifts=3, seed=2), "trial_b.csv")
    result = analyze_recordings([a, b], muscle_map=DEMO_MUSCLES)
    out = AnalysisOverlays.from_result(result).window(points=300)
    assert out["session"] == "separate"
    fa, fb = out["files"]
    assert (fa["file"], fb["file"], fa["lifts"], fb["lifts"]) == (
        "trial_a.csv",
        "trial_b.csv",
        2,
        3,
    )
    assert fa["span"][0] == pytest.approx(0.0, abs=0.01) == fb["span"][0]  # each from 0 s
    assert fb["span"][1] > fa["span"][1]  # the longer trial
    for f in (fa, fb):
        elbow = f["angles"]["elbow_deg"]
        assert elbow["t"] and max(elbow["t"]) <= f["span"][1] + 0.01
    assert sorted({lift["file"] for lift in out["lifts"]}) == ["trial_a.csv", "trial_b.csv"]
    # The first file's angles stay where older pages read them.
    assert out["angles"]["elbow_deg"] == fa["angles"]["elbow_deg"]


def test_overlays_stored_before_per_file_entries_still_window(
    overlays: AnalysisOverlays,
) -> None:
    """Stored overlays of the previous release: angles under ``angles.<name>``, no ``files``."""
    meta = {k: v for k, v in overlays.meta.items() if k not in ("files", "session")}
    series = {
        name.replace("files.0.angles.", "angles."): value for name, value in overlays.series.items()
    }
    old = AnalysisOverlays(meta=meta, series=series)
    out = old.window(points=300)
    assert out["files"] == []
    assert out["angles"]["elbow_deg"] == overlays.window(points=300)["angles"]["elbow_deg"]
    assert out["angles"]["elbow_deg"]["t"]
