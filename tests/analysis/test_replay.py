"""A recorded lift replayed on a plan's time grid: closed forms and a real recording's angles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.analysis.replay import (
    ReplayError,
    lift_time_map,
    lifts_with_angles,
    replay_from_overlays,
    replay_lift,
    two_link_points,
)


def test_lift_time_map_sends_start_to_zero_and_top_to_the_end() -> None:
    t = np.linspace(0.0, 2.0, 5)
    # start 3 s, top 4 s: the plan's 0, 0.5, ..., 2 s show the recording's 3, 3.25, ..., 4 s.
    np.testing.assert_allclose(lift_time_map(t, 3.0, 4.0), [3.0, 3.25, 3.5, 3.75, 4.0])
    with pytest.raises(ReplayError, match="start < top"):
        lift_time_map(t, 4.0, 4.0)
    with pytest.raises(ReplayError, match="positive duration"):
        lift_time_map(np.zeros(3), 0.0, 1.0)


def test_two_link_points_closed_form() -> None:
    """elbow = l1 (sin qs, -cos qs); the hand's distance from the shoulder obeys the law of
    cosines |hand|^2 = l1^2 + l2^2 + 2 l1 l2 cos(qe) (qe = 0: straight, reach l1 + l2)."""
    qs = np.radians([0.0, 90.0, 30.0, -20.0])
    qe = np.radians([0.0, 0.0, 90.0, 150.0])
    l1, l2 = 0.3, 0.35
    at_elbow, hand = two_link_points(qs, qe, l1, l2)
    np.testing.assert_allclose(at_elbow, l1 * np.column_stack([np.sin(qs), -np.cos(qs)]))
    np.testing.assert_allclose(at_elbow[:2], [[0.0, -0.3], [0.3, 0.0]], atol=1e-15)
    np.testing.assert_allclose(hand[0], [0.0, -0.65], atol=1e-15)  # hanging straight
    np.testing.assert_allclose(hand[1], [0.65, 0.0], atol=1e-15)  # held out forward
    np.testing.assert_allclose(hand[2], [0.15 + 0.35 * math.cos(math.radians(30)),
                                         -0.3 * math.cos(math.radians(30)) + 0.175])  # fmt: skip
    np.testing.assert_allclose(
        np.sum(hand**2, axis=1), l1**2 + l2**2 + 2 * l1 * l2 * np.cos(qe), rtol=1e-12
    )


def test_replay_lift_samples_the_recording_at_the_mapped_times() -> None:
    """Angles linear in time resample exactly: at plan time tau the elbow shows the recording
    at start + (top - start) tau / T."""
    t_rec = np.arange(0.0, 10.0, 0.01)
    elbow_deg = 10.0 * t_rec  # 10 deg/s
    shoulder_deg = np.where(t_rec < 5.0, 2.0 * t_rec, np.nan)  # a gap after 5 s
    t_plan = np.linspace(0.0, 1.5, 301)
    r = replay_lift(t_plan, t_rec, shoulder_deg, elbow_deg, start=2.0, top=6.0, body_height=1.75)
    mapped = 2.0 + 4.0 * t_plan / 1.5
    np.testing.assert_allclose(np.degrees(r.elbow), 10.0 * mapped, atol=1e-9)
    # Shoulder: exact before the gap, held at the last finite sample across it.
    before = mapped < 4.99
    np.testing.assert_allclose(np.degrees(r.shoulder[before]), 2.0 * mapped[before], atol=1e-9)
    assert np.degrees(r.shoulder[-1]) == pytest.approx(2.0 * 4.99)
    # De Leva's upper arm (0.2817 m) and forearm + hand scaled from a 1.741 m sample.
    from app.planning.robots import human_arm_segments

    seg = human_arm_segments(body_height=1.75)
    assert r.upper_arm == pytest.approx(0.2817 * 1.75 / 1.741, rel=1e-5) == seg.l1
    assert r.forearm == seg.l2 and 0.3 < r.forearm < 0.45
    assert not r.notes
    no_shoulder = replay_lift(t_plan, t_rec, None, elbow_deg, start=2.0, top=6.0)
    assert np.all(no_shoulder.shoulder == 0.0) and "no shoulder angle" in no_shoulder.notes[0]
    with pytest.raises(ReplayError, match="no elbow angle"):
        replay_lift(t_plan, t_rec, None, np.full_like(t_rec, np.nan), start=2.0, top=6.0)


@pytest.fixture(scope="module")
def c3d_analysis() -> object:
    from app.analysis import analyze_files
    from tests.conftest import shared_file

    return analyze_files([shared_file("pyomeca_upperlimb_c3d_emg/markers_analogs.c3d")])


def test_replay_of_a_real_recording_shows_the_analysis_own_angles(c3d_analysis: object) -> None:
    """The pyomeca upper-limb trial (Vicon markers, 100 Hz, three curls): the replay, read back
    from the stored overlays, shows at each plan sample the analysis' own angles at the mapped
    recording time, and its elbow sits where the closed form puts it."""
    from app.analysis import AnalysisOverlays

    result = c3d_analysis
    overlays = AnalysisOverlays.from_arrays(AnalysisOverlays.from_result(result).to_arrays())  # type: ignore[arg-type]
    assert lifts_with_angles(overlays) == 3
    rec = result.recordings[0]  # type: ignore[attr-defined]
    angles, lift = rec.angles, rec.lifts[1].lift
    t_plan = np.linspace(0.0, 1.0, 201)
    replay = replay_from_overlays(overlays, t_plan, lift=1, body_height=1.80)
    assert replay.lift["start_s"] == pytest.approx(lift.start)
    assert replay.lift["top_s"] == pytest.approx(lift.top)
    t_pose = angles.t + rec.offset
    for k in (0, 50, 100, 150, 200):  # known frames: start, quarters, top
        when = lift.start + (lift.top - lift.start) * t_plan[k]
        elbow = np.interp(when, t_pose, angles.elbow)
        shoulder = np.interp(when, t_pose, angles.shoulder)
        # Stored as float32 degrees: 1e-4 deg.
        assert replay.elbow[k] == pytest.approx(elbow, abs=1e-5)
        assert replay.shoulder[k] == pytest.approx(shoulder, abs=1e-5)
        at_elbow, _ = replay.points()
        np.testing.assert_allclose(
            at_elbow[k], replay.upper_arm * np.array([np.sin(shoulder), -np.cos(shoulder)]),
            atol=1e-5,
        )  # fmt: skip
    # A curl: the elbow flexes from start to top, by the lift's own range.
    assert math.degrees(replay.elbow[-1] - replay.elbow[0]) > 60.0
    with pytest.raises(ReplayError, match="lift 3 does not exist"):
        replay_from_overlays(overlays, t_plan, lift=3)
