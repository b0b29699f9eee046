"""The analysis entry point on real recordings, its JSON, the template, and bad input."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from app.analysis import analyze_recordings
from app.analysis.pose import arm_angles
from app.analysis.segmentation import detect_lifts
from app.planning.human_template import HumanTemplate
from app.recordings.types import Channel, Recording, RecordingError
from tests.analysis._data import mediapipe_csv, noraxon_recording, pyomeca_c3d


@pytest.fixture(scope="module")
def pyomeca_result():  # type: ignore[no-untyped-def]
    return analyze_recordings([pyomeca_c3d()], body_mass=60.0, body_height=1.65, load_mass=2.0)


def test_pyomeca_lifts_phases_and_template(pyomeca_result) -> None:  # type: ignore[no-untyped-def]
    result = pyomeca_result
    (rec,) = result.recordings
    # Independent count: elbow maxima above 100 deg separated by dips below 60 deg.
    elbow_deg = np.rad2deg(rec.angles.elbow)
    above = elbow_deg > 100
    assert len(rec.lifts) == int(np.sum(above[1:] & ~above[:-1])) == 3
    for report in rec.lifts:
        concentric = [p for p in report.phases if p.phase.part == "concentric"]
        assert [p.phase.name for p in concentric][-2:] == ["B", "C"]
        assert concentric[0].phase.start == pytest.approx(report.lift.start)
        assert concentric[-1].phase.end == pytest.approx(report.lift.top)
        # Per-phase peak velocity never exceeds the lift's concentric peak velocity.
        assert max(p.peak_velocity for p in concentric) == pytest.approx(
            report.profile.peak_velocity, rel=1e-6
        )
        assert report.energetics is not None
    tpl = result.template
    angles = [np.rad2deg(r.profile.peak_velocity_angle) for r in rec.lifts]
    assert tpl.n_lifts == 3
    assert tpl.peak_velocity_angle_deg == pytest.approx(np.mean(angles))
    assert tpl.peak_velocity_angle_sd_deg == pytest.approx(np.std(angles, ddof=1))
    assert len(tpl.velocity_mean) == 101
    assert max(tpl.velocity_mean) <= 1.0 + 1e-9
    assert set(tpl.activation_order) == {"deltoid", "biceps", "triceps"}
    assert HumanTemplate.from_json(tpl.to_json()) == tpl


def test_to_dict_is_json_and_in_degrees(pyomeca_result) -> None:  # type: ignore[no-untyped-def]
    data = json.loads(json.dumps(pyomeca_result.to_dict(), allow_nan=False))
    f = data["files"][0]
    lo, hi = f["pose"]["elbow_range_deg"]
    assert 180 - hi == pytest.approx(42.0, abs=2.0)
    assert 180 - lo == pytest.approx(155.0, abs=2.0)
    assert set(f["emg"]) == {"deltoid", "biceps", "triceps"}
    lift = f["lifts"][0]
    assert {p["name"] for p in lift["phases"]} >= {"B", "C"}
    for p, stats in zip(lift["phases"], pyomeca_result.recordings[0].lifts[0].phases, strict=True):
        assert list(p)[:5] == ["name", "part", "start_s", "end_s", "duration_s"]
        assert (p["name"], p["part"]) == (stats.phase.name, stats.phase.part)
        assert (p["start_s"], p["end_s"]) == (stats.phase.start, stats.phase.end)
        assert p["duration_s"] == pytest.approx(p["end_s"] - p["start_s"])
    assert lift["energetics"]["metrics"]["abs_work"] > 0
    assert data["template"]["n_lifts"] == 3
    # EMG peaks aligned with the velocity peak: offsets agree with the absolute peak times.
    vpeak = lift["concentric_s"][0] + lift["peak_velocity_time_fraction"] * (
        lift["concentric_s"][1] - lift["concentric_s"][0]
    )
    for muscle, dt in lift["emg_peak_after_velocity_peak_s"].items():
        assert dt == pytest.approx(lift["emg_peak_s"][muscle] - vpeak)
    assert "lifts: 3" in pyomeca_result.summary()


def test_noraxon_curls_ten_lifts_each_from_emg_alone() -> None:
    result = analyze_recordings([noraxon_recording("NT-01"), noraxon_recording("SP-01")])
    assert [len(r.lifts) for r in result.recordings] == [10, 10]
    assert all(r.lift.source == "emg" for r in result.lifts)
    assert result.template.n_lifts == 0  # no angle: kinematics keep the paper's defaults
    assert result.template.peak_velocity_angle_deg == 62.0
    json.dumps(result.to_dict(), allow_nan=False)
    assert set(result.template.activation_order) == {"biceps", "forearm"}


def test_user_offset_moves_pose_events_onto_the_emg_clock(pyomeca_result) -> None:  # type: ignore[no-untyped-def]
    shifted = analyze_recordings([pyomeca_c3d()], offset=1.25, load_mass=2.0)
    base = [r.lift.top for r in pyomeca_result.lifts]
    np.testing.assert_allclose([r.lift.top for r in shifted.lifts], np.add(base, 1.25))


def test_separate_emg_and_pose_files_are_aligned_automatically() -> None:
    rec = pyomeca_c3d()
    emg = Recording({k: c for k, c in rec.channels.items() if c.kind == "emg"}, "emg.csv", "csv")
    # The video clock started 0.3 s after the EMG clock: t_emg = t_pose + 0.3.
    pose = Recording(
        {k: replace(c, start=c.start - 0.3) for k, c in rec.channels.items() if c.kind != "emg"},
        "pose.c3d",
        "c3d",
    )
    result = analyze_recordings([emg, pose], together=True, load_mass=2.0)
    (one,) = result.recordings
    assert one.offset == pytest.approx(0.3, abs=0.05)
    assert len(one.lifts) == 3


def test_mediapipe_frames_with_gaps_give_no_kinematics_across_them() -> None:
    result = analyze_recordings([mediapipe_csv()])
    (rec,) = result.recordings
    assert rec.angles is not None and len(rec.angles.gaps) >= 5
    independent = detect_lifts(rec.angles.elbow, rec.angles.t, segments=rec.angles.segments)
    assert len(rec.lifts) == len(independent)
    finite = rec.angles.elbow[np.isfinite(rec.angles.elbow)]
    assert np.all((finite >= 0) & (finite <= np.pi))
    json.dumps(result.to_dict(), allow_nan=False)


def _emg_rec(x: np.ndarray, names: list[str]) -> Recording:
    chans = {n: Channel(n, x[:, j], 1000.0, "V", "emg") for j, n in enumerate(names)}
    return Recording(chans, "bad.csv", "csv")


def test_bad_recordings_raise_errors_naming_file_and_channel() -> None:
    rng = np.random.default_rng(0)
    x = rng.standard_normal((5000, 2))
    x[100, 1] = np.nan
    with pytest.raises(RecordingError, match=r"bad\.csv, channel 'Biceps'.*NaN") as info:
        analyze_recordings([_emg_rec(x, ["Deltoid", "Biceps"])])
    assert info.value.file == "bad.csv"
    with pytest.raises(RecordingError, match="1 sample"):
        analyze_recordings([_emg_rec(np.ones((1, 1)), ["Biceps"])])
    flat = rng.standard_normal((5000, 2))
    flat[:, 0] = 1e-3
    # A flat channel the user mapped to a site is an error ...
    with pytest.raises(RecordingError, match=r"'Deltoid'.*zero variance"):
        analyze_recordings(
            [_emg_rec(flat, ["Deltoid", "Biceps"])], muscle_map={"Deltoid": "deltoid"}
        )
    # ... and so is a recording whose EMG channels are all flat.
    with pytest.raises(RecordingError, match=r"'Deltoid'.*zero variance"):
        analyze_recordings([_emg_rec(np.full((5000, 2), 0.5), ["Deltoid", "Biceps"])])
    # An unmapped flat channel beside live ones is an unused input: left out with a warning.
    kept = analyze_recordings([_emg_rec(flat, ["Sensor 12", "Biceps"])])
    assert [m.channel for m in kept.recordings[0].emg] == ["Biceps"]
    assert "Sensor 12" in " ".join(kept.recordings[0].warnings)
    face = Recording(
        {"nose": Channel("nose", rng.random((50, 3)), 30.0, "norm", "landmark")},
        "face.csv",
        "mediapipe_csv",
    )
    with pytest.raises(RecordingError, match=r"face\.csv: no arm landmarks"):
        analyze_recordings([face])
    with pytest.raises(RecordingError, match="phase bounds"):
        analyze_recordings([face], phase_bounds_deg=(90.0, 40.0))


def test_muscle_map_assigns_sites() -> None:
    x = np.random.default_rng(1).standard_normal((4000, 2))
    result = analyze_recordings(
        [_emg_rec(x, ["EMG1", "EMG2"])], muscle_map={"EMG1": "deltoid", "EMG2": "forearm"}
    )
    assert [m.muscle for m in result.recordings[0].emg] == ["deltoid", "forearm"]
    with pytest.raises(RecordingError, match="unknown site"):
        analyze_recordings([_emg_rec(x, ["EMG1", "EMG2"])], muscle_map={"EMG1": "calf"})


def test_pose_side_option_is_passed_through() -> None:
    rec = mediapipe_csv()
    result = analyze_recordings([rec], pose_options={"side": "left", "min_visibility": 0.3})
    expected = arm_angles(rec, side="left", min_visibility=0.3)
    assert result.recordings[0].angles is not None
    np.testing.assert_array_equal(result.recordings[0].angles.elbow, expected.elbow)


@pytest.mark.parametrize(("name", "emg_rate"), [("NT-01.mat", 2000.0), ("SP-01.mat", None)])
def test_analyze_files_noraxon_ten_lifts(name: str, emg_rate: float | None) -> None:
    from app.analysis import analyze_files
    from tests.conftest import shared_file

    path = shared_file(f"noraxon_curls_biceps_brachioradialis/{name}")
    result = analyze_files([path], emg_rate=emg_rate)
    assert len(result.lifts) == 10
    assert {m.muscle for m in result.recordings[0].emg} == {"biceps", "forearm"}


def test_analyze_files_c3d_and_mediapipe() -> None:
    from app.analysis import analyze_files
    from tests.conftest import shared_file

    c3d = shared_file("pyomeca_upperlimb_c3d_emg/markers_analogs.c3d")
    frames = shared_file("mediapipe_bicep_curl_frames/test.csv")
    result = analyze_files([c3d, frames], frame_rate=30.0, load_mass=2.0)
    marker, landmarks = result.recordings
    lo, hi = marker.to_dict()["pose"]["elbow_range_deg"]
    assert (180 - hi, 180 - lo) == pytest.approx((42.0, 155.0), abs=2.0)
    assert len(marker.lifts) == 3
    assert landmarks.angles is not None and len(landmarks.angles.gaps) >= 5
    assert "deltoid" in result.template.activation_order


def test_analyze_files_passes_exactly_the_keywords_of_analyze_recordings() -> None:
    """``analyze_files`` forwards ``AnalysisKeywords``: they are ``analyze_recordings``' own
    keyword parameters with the same types, and a misspelt one is refused, not ignored."""
    import inspect
    import typing

    from app.analysis import analyze_files
    from app.analysis.pipeline import AnalysisKeywords
    from tests.conftest import shared_file

    own = inspect.signature(analyze_recordings).parameters
    keywords = [n for n, p in own.items() if p.kind is inspect.Parameter.KEYWORD_ONLY]
    hints = typing.get_type_hints(analyze_recordings)
    assert typing.get_type_hints(AnalysisKeywords) == {n: hints[n] for n in keywords}
    c3d = shared_file("pyomeca_upperlimb_c3d_emg/markers_analogs.c3d")
    with pytest.raises(TypeError, match="load_mas"):
        analyze_files([c3d], load_mas=2.0)  # type: ignore[call-arg]
