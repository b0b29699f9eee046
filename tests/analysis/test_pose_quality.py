"""Video honesty: per-frame detection quality, a switch of the tracked person, and lifts on
low-quality frames kept out of the template (unless asked for).

Synthetic MediaPipe JSON (no video needed): a side view of four curls with the torso and both
arms, with planted faults in chosen lifts: a flickering arm (every other frame poorly seen),
the track jumping to another person (elsewhere, smaller) for part of a lift, a skeleton with
limbs of the wrong lengths. The real demo video (two people) runs when the pose environment
and the shared data are there.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.analysis import analyze_recordings
from app.recordings import Recording, read_bytes
from app.recordings._mediapipe import LANDMARK_NAMES
from app.recordings._pose_quality import arm_quality, frame_ranges, identity, image_landmarks
from tests.analysis import _synthetic as syn

RATE = 30.0
W, H = syn.IMAGE
CYCLE = syn.RISE_S + syn.HOLD_S + syn.LOWER_S + syn.REST_S
SHOULDER = (900.0, 300.0)
TORSO_PX = 450.0


def _lift_frames(k: int, rate: float = RATE) -> slice:
    """Frames of lift ``k`` (0-based): its rise, hold and lowering."""
    t0 = syn.REST_S + k * CYCLE
    return slice(round(t0 * rate), round((t0 + syn.RISE_S + syn.HOLD_S + syn.LOWER_S) * rate))


def _skeleton(n_lifts: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """(T, 33, 2) pixel positions and (T, 33) visibility of a side view of curls."""
    _, elbow = syn.elbow_curls(n_lifts, RATE)
    n = len(elbow)
    pos = np.zeros((n, len(LANDMARK_NAMES), 2))
    vis = np.full((n, len(LANDMARK_NAMES)), 0.95)
    sx, sy = SHOULDER
    base = np.array([sx, sy])
    head, feet = base + np.array([0.0, -120.0]), base + np.array([0.0, TORSO_PX + 400.0])
    for k in range(len(LANDMARK_NAMES)):  # the head and legs: somewhere on the body
        pos[:, k] = head if k < 11 else feet
    arm = syn.arm_pixels(elbow, shoulder=SHOULDER)
    for side, dx in (("right", 0.0), ("left", 20.0)):
        for j, joint in enumerate(("shoulder", "elbow", "wrist")):
            pos[:, LANDMARK_NAMES.index(f"{side}_{joint}")] = arm[:, j] + (dx, 0.0)
        pos[:, LANDMARK_NAMES.index(f"{side}_hip")] = base + np.array([dx, TORSO_PX])
    return pos, vis


def _flicker(vis: np.ndarray, frames: slice) -> None:
    """Every other frame of ``frames`` with both wrists poorly seen (short holes only)."""
    idx = np.arange(frames.start, frames.stop)[::2]
    for side in ("right", "left"):
        vis[idx, LANDMARK_NAMES.index(f"{side}_wrist")] = 0.2


def _switch(pos: np.ndarray, frames: slice, *, shift: float = 700.0, scale: float = 0.6) -> None:
    """The track on another person for ``frames``: the skeleton elsewhere and smaller (the
    elbow angle unchanged, so the lift itself still looks whole)."""
    anchor = np.array(SHOULDER)
    pos[frames] = anchor + (pos[frames] - anchor) * scale + (shift, 80.0)


def _stretch(pos: np.ndarray, frames: slice, factor: float = 2.0) -> None:
    """Forearm drawn ``factor`` times too long (a skeleton fitted to something else)."""
    e, w = LANDMARK_NAMES.index("right_elbow"), LANDMARK_NAMES.index("right_wrist")
    pos[frames, w] = pos[frames, e] + factor * (pos[frames, w] - pos[frames, e])


def _doc(pos: np.ndarray, vis: np.ndarray, persons: dict[str, Any] | None = None) -> bytes:
    frames = [
        {
            "frame": i,
            "timestamp_ms": 1000.0 * i / RATE,
            "pose_landmarks": [
                [
                    {"x": float(p[0] / W), "y": float(p[1] / H), "z": 0.0, "visibility": float(v)}
                    for p, v in zip(pos[i], vis[i], strict=True)
                ]
            ],
        }
        for i in range(len(pos))
    ]
    doc: dict[str, Any] = {"fps": RATE, "image_width": W, "image_height": H, "frames": frames}
    if persons is not None:
        doc["persons"] = persons
    return json.dumps(doc).encode()


def _recording(pos: np.ndarray, vis: np.ndarray, name: str = "curls.pose.json") -> Recording:
    return read_bytes(_doc(pos, vis), name, format="mediapipe_json")


def _faulty() -> tuple[np.ndarray, np.ndarray]:
    """Four curls: lift 2 flickers, lift 3 is partly someone else; lifts 1 and 4 are clean."""
    pos, vis = _skeleton()
    _flicker(vis, _lift_frames(1))
    rise = _lift_frames(2)
    _switch(pos, slice(rise.start + 10, rise.start + 50))
    return pos, vis


# ------------------------------------------------------------------------------ frame quality


def test_clean_curls_have_no_low_quality_frames_and_one_person() -> None:
    rec = _recording(*_skeleton())
    lms = image_landmarks(rec.channels)
    t = rec.channels["right_elbow"].times
    q = arm_quality(lms, t, "right")
    assert not q.low.any() and q.n_persons == 1 and q.switches == ()
    assert np.allclose(q.visibility, 0.95)
    assert np.allclose(q.upper_arm_ratio, 1.0) and np.allclose(q.forearm_ratio, 1.0)
    assert "pose_track" not in rec.metadata
    assert not any("jumps" in w for w in rec.metadata["warnings"])


def test_planted_faults_are_found_frame_by_frame() -> None:
    pos, vis = _faulty()
    stretched = _lift_frames(3)
    _stretch(pos, slice(stretched.start + 5, stretched.start + 40))
    rec = _recording(pos, vis)
    lms = image_landmarks(rec.channels)
    t = rec.channels["right_elbow"].times
    q = arm_quality(lms, t, "right")
    flick = np.arange(_lift_frames(1).start, _lift_frames(1).stop)
    assert q.low[flick[::2]].all() and not q.low[flick[1::2]].any()
    assert q.visibility[flick[::2]] == pytest.approx(0.2)
    other = np.arange(_lift_frames(2).start + 10, _lift_frames(2).start + 50)
    assert (q.person[other] == 1).all() and (np.delete(q.person, other) == 0).all()
    assert q.switches == (other[0], other[-1] + 1) and q.n_persons == 2
    assert q.low[other].all() and q.score[other].max() == 0.0
    bad = np.arange(stretched.start + 5, stretched.start + 40)
    assert not q.plausible[bad].any() and q.low[bad].all()
    assert q.forearm_ratio[bad] == pytest.approx(2.0, rel=0.05)
    s = q.summary()
    assert s["reasons"] == {
        "no_pose": 0,
        "other_person": 40,
        "implausible_lengths": 35,
        "low_visibility": len(flick[::2]),
    }
    assert s["low_quality_frames"] == 40 + 35 + len(flick[::2])


def test_the_switch_is_on_the_recording_with_the_tracked_frames() -> None:
    rec = _recording(*_faulty())
    track = rec.metadata["pose_track"]
    lift = _lift_frames(2)
    a, b = lift.start + 10, lift.start + 49
    assert track["switch_frames"] == [a, b + 1] and track["persons"] == 2
    n = rec.channels["right_elbow"].n_samples
    assert track["tracked_frames"] == f"0-{a - 1}, {b + 1}-{n - 1}"
    assert any(f"jumps to another person (or object) at frame(s) {a}, {b + 1}" in w
               for w in rec.metadata["warnings"])  # fmt: skip


def test_a_person_coming_back_keeps_their_number_and_slow_motion_is_no_switch() -> None:
    pos, vis = _skeleton(2)
    n = len(pos)
    pos += np.linspace(0.0, 400.0, n)[:, None, None] * np.array([1.0, 0.0])  # walking slowly
    rec = _recording(pos, vis)
    who = identity(image_landmarks(rec.channels), rec.channels["right_elbow"].times)
    assert who.switches == () and who.n_persons == 1
    _switch(pos, slice(20, 30))
    _switch(pos, slice(50, 60), shift=-600.0, scale=1.8)
    rec = _recording(pos, vis)
    who = identity(image_landmarks(rec.channels), rec.channels["right_elbow"].times)
    assert who.n_persons == 3 and who.switches == (20, 30, 50, 60)
    assert (who.person[20:30] == 1).all() and (who.person[50:60] == 2).all()
    assert (who.person[30:50] == 0).all() and (who.person[60:] == 0).all()


def test_frame_ranges_reads_like_a_person_wrote_it() -> None:
    assert frame_ranges(np.array([3, 4, 5, 9, 12, 13])) == "3-5, 9, 12-13"
    assert frame_ranges(np.array([], dtype=np.intp)) == "none"
    assert frame_ranges(np.arange(0, 20, 2), limit=2) == "0, 2 and 8 more"


# --------------------------------------------------------------------------- lifts, template


def test_low_quality_lifts_are_flagged_and_left_out_of_the_template() -> None:
    rec = _recording(*_faulty())
    result = analyze_recordings([rec])
    lifts = result.recordings[0].lifts
    assert len(lifts) == 4
    assert [r.low_quality for r in lifts] == [False, True, True, False]
    assert lifts[0].low_quality_share == 0.0 and lifts[3].low_quality_share == 0.0
    assert set(lifts[1].quality_reasons) == {"low_visibility"}
    assert lifts[1].low_quality_share == pytest.approx(0.5, abs=0.05)  # every other frame
    assert lifts[2].quality_reasons == {"other_person": 40}
    assert all(r.profile.has_kinematics for r in lifts)  # measurable, yet not trusted
    tpl = result.template
    assert tpl.n_lifts == 2
    assert tpl.source == "2 lift(s) with kinematics; 2 lift(s) left out (low pose quality)"
    d = result.to_dict()
    assert d["files"][0]["lifts"][1]["quality"]["low_quality"] is True
    assert d["files"][0]["pose"]["quality"]["persons_tracked"] == 2
    assert d["settings"]["keep_low_quality_lifts"] is False
    assert any("2 lift(s) (#2, #3) rest on low-quality pose frames" in w
               for w in result.recordings[0].warnings)  # fmt: skip
    assert "LOW POSE QUALITY" in result.summary()


def test_keeping_low_quality_lifts_changes_the_template() -> None:
    rec = _recording(*_faulty())
    left_out = analyze_recordings([rec]).template
    kept = analyze_recordings([rec], keep_low_quality_lifts=True)
    assert kept.template.n_lifts == 4 and kept.template.source == "4 lift(s) with kinematics"
    assert kept.template.peak_velocity_angle_deg != left_out.peak_velocity_angle_deg
    assert kept.settings["keep_low_quality_lifts"] is True
    assert any("2 lift(s) with low pose quality kept" in w for w in kept.warnings)


def test_all_lifts_low_quality_falls_back_to_the_paper_default_and_says_why() -> None:
    pos, vis = _skeleton(3)
    for k in range(3):
        _flicker(vis, _lift_frames(k))
    rec = _recording(pos, vis)
    result = analyze_recordings([rec])
    tpl = result.template
    assert tpl.is_paper_default
    assert tpl.source == "paper default: every lift found was left out (3 for low pose quality)"
    assert any("paper's defaults" in w for w in result.warnings)
    kept = analyze_recordings([rec], keep_low_quality_lifts=True).template
    assert kept.n_lifts == 3


def test_markers_have_no_frame_quality_and_nothing_is_flagged() -> None:
    from tests.utils.markers import curl_markers

    rec, _ = curl_markers({"shoulder": "RSHO", "elbow": "RELB", "wrist": "RWRA"}, 12.0)
    result = analyze_recordings([rec], pose_options={"landmarks": "plugin_gait_right"})
    assert result.recordings[0].angles is not None
    assert result.recordings[0].angles.quality is None
    assert all(r.low_quality_share is None and not r.low_quality for r in result.lifts)
    assert "left out" not in result.template.source


# ---------------------------------------------------------------------------------- the edges


def test_cli_flag_keeps_low_quality_lifts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from app.cli import main

    path = tmp_path / "curls.pose.json"
    path.write_bytes(_doc(*_faulty()))
    out = []
    for extra in ([], ["--keep-low-quality-lifts"]):
        assert main(["analyze", str(path), "--json", *extra]) == 0
        out.append(json.loads(capsys.readouterr().out))
    assert out[0]["template"]["n_lifts"] == 2 and out[1]["template"]["n_lifts"] == 4
    assert "left out (low pose quality)" in out[0]["template"]["source"]
    assert out[1]["settings"]["keep_low_quality_lifts"] is True


def test_api_request_and_job_take_the_option() -> None:
    from app.api.schemas import AnalysisRequest
    from app.jobs.tasks import analyse

    assert AnalysisRequest(recording_id=1).keep_low_quality_lifts is False
    assert AnalysisRequest(recording_id=1, keep_low_quality_lifts=True).keep_low_quality_lifts
    files = [{"name": "curls.pose.json", "data": _doc(*_faulty()), "sidecars": {}}]
    n = [
        analyse({"files": files, "options": {"keep_low_quality_lifts": keep}})["template"][
            "n_lifts"
        ]
        for keep in (False, True)
    ]
    assert n == [2, 4]


def test_skeleton_frames_prefer_the_tracked_person_well_seen() -> None:
    from app.recordings.video import _frame_quality, _pick_skeletons

    pos, vis = _faulty()
    q = _frame_quality(_doc(pos, vis))
    assert q is not None
    other = range(_lift_frames(2).start + 10, _lift_frames(2).start + 50)
    flick = range(_lift_frames(1).start, _lift_frames(1).stop, 2)
    candidates = [0, flick[1], other[5], other[20], 60, 420, 500]
    picked = _pick_skeletons(candidates, q, 4)
    assert len(picked) == 4 and not set(picked) & {flick[1], *other}
    assert picked == [0, 60, 420, 500]
    # Too few good frames: the best of the rest fill up, never a frame of someone else.
    assert _pick_skeletons([0, flick[1], other[5]], q, 2) == [0, flick[1]]
    assert _pick_skeletons(candidates, q, 0) == []
