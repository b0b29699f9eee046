"""Arm angles from landmarks: closed-form arm geometry, derivatives, gaps, and real files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from app.analysis.pose import arm_angles, joint_angles
from app.recordings.types import Channel, Recording, RecordingError
from tests.analysis._data import mediapipe_csv, pyomeca_c3d
from tests.utils.markers import curl_markers, write_trc

L1, L2 = 0.30, 0.35  # upper arm, forearm [m]


def _arm(q1: NDArray[np.float64], q2: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
    """Sagittal-plane points (x forward, y up) of an arm with shoulder/elbow flexion q1, q2."""
    zero = np.zeros_like(q1)
    shoulder = np.stack([zero, zero], axis=1)
    hip = np.stack([zero, zero - 0.5], axis=1)
    elbow = L1 * np.stack([np.sin(q1), -np.cos(q1)], axis=1)
    wrist = elbow + L2 * np.stack([np.sin(q1 + q2), -np.cos(q1 + q2)], axis=1)
    return {"shoulder": shoulder, "elbow": elbow, "wrist": wrist, "hip": hip}


def _to_3d(points: NDArray[np.float64], heading: float) -> NDArray[np.float64]:
    fwd = np.array([np.cos(heading), np.sin(heading), 0.0])
    return points[:, :1] * fwd + points[:, 1:2] * np.array([0.0, 0.0, 1.0]) + [0.2, -0.1, 1.3]


def _curl(rate: float, seconds: float = 6.0) -> tuple[NDArray[np.float64], ...]:
    t = np.arange(int(seconds * rate)) / rate
    q1 = np.deg2rad(10.0) + np.deg2rad(15.0) * (1 - np.cos(2 * np.pi * 0.5 * t)) / 2
    q2 = np.deg2rad(10.0) + np.deg2rad(130.0) * (1 - np.cos(2 * np.pi * 0.5 * t)) / 2
    return t, q1, q2


def _image_recording(
    t: NDArray[np.float64],
    points: dict[str, NDArray[np.float64]],
    *,
    size: tuple[float, float] = (1280.0, 720.0),
    side: str = "left",
    visibility: float = 0.99,
) -> Recording:
    # Subject faces image-left (forward = -x), image y points down, coordinates normalised.
    scale = 400.0
    channels = {}
    for role, p in points.items():
        x = (640.0 - scale * p[:, 0]) / size[0]
        y = (300.0 - scale * p[:, 1]) / size[1]
        data = np.stack([x, y, np.zeros_like(x)], axis=1)
        name = f"{side}_{role}"
        conf = np.full(len(t), visibility)
        channels[name] = Channel(name, data, 1 / (t[1] - t[0]), "norm", "landmark", confidence=conf)
    return Recording(channels, "synthetic.csv", "mediapipe_csv")


def test_joint_angles_closed_form_2d_and_3d() -> None:
    _, q1, q2 = _curl(50.0)
    pts = _arm(q1, q2)
    s, e = joint_angles(pts["shoulder"], pts["elbow"], pts["wrist"], hip=pts["hip"])
    np.testing.assert_allclose(s, q1, atol=1e-12)
    np.testing.assert_allclose(e, q2, atol=1e-12)
    # Same arm in a lab frame with z up, facing an arbitrary heading; no hip marker.
    p3 = {k: _to_3d(v, heading=2.1) for k, v in pts.items()}
    s3, e3 = joint_angles(p3["shoulder"], p3["elbow"], p3["wrist"])
    np.testing.assert_allclose(s3, q1, atol=1e-9)
    np.testing.assert_allclose(e3, q2, atol=1e-9)


def test_image_landmarks_with_y_down_give_the_true_angles() -> None:
    t, q1, q2 = _curl(30.0)
    rec = _image_recording(t, _arm(q1, q2))
    angles = arm_angles(rec, lowpass=None, image_size=(1280.0, 720.0))
    assert angles.side == "left"
    np.testing.assert_allclose(angles.shoulder, q1, atol=1e-9)
    np.testing.assert_allclose(angles.elbow, q2, atol=1e-9)
    assert angles.position_unit == "px"
    # A reader that already scaled x by width/height says so with metadata["image_size"]:
    # then the coordinates are used as they are, not scaled twice.
    for ch in rec.channels.values():
        ch.data[:, 0] *= 1280.0 / 720.0
    rec.metadata["image_size"] = [1280, 720]
    again = arm_angles(rec, lowpass=None, image_size=(1280.0, 720.0))
    np.testing.assert_allclose(again.elbow, q2, atol=1e-9)


@pytest.mark.parametrize("method", ["savgol", "spline"])
def test_velocity_and_acceleration_match_the_analytic_derivatives(method: str) -> None:
    rate = 100.0
    t, q1, q2 = _curl(rate)
    pts = {k: _to_3d(v, 0.4) for k, v in _arm(q1, q2).items()}
    rec = Recording(
        {k: Channel(k, v, rate, "m", "marker") for k, v in _rename(pts, "L").items()},
        "synthetic.c3d",
        "c3d",
    )
    a = arm_angles(rec, derivative=method)  # type: ignore[arg-type]
    w = 2 * np.pi * 0.5
    amp = np.deg2rad(130.0) / 2
    core = slice(50, -50)
    np.testing.assert_allclose(a.elbow_velocity[core], (amp * w * np.sin(w * t))[core], atol=0.02)
    np.testing.assert_allclose(
        a.elbow_acceleration[core], (amp * w**2 * np.cos(w * t))[core], atol=0.1
    )


def _rename(points: dict[str, NDArray[np.float64]], s: str) -> dict[str, NDArray[np.float64]]:
    names = {"shoulder": f"{s}SHO", "elbow": f"{s}ELB", "wrist": f"{s}WRA", "hip": f"{s}ASI"}
    out = {names[k]: v for k, v in points.items()}
    out[f"{s}WRB"] = out[f"{s}WRA"]
    out[f"{s}PSI"] = out[f"{s}ASI"]
    return out


def test_wrist_acceleration_is_centripetal_for_a_steady_forearm_swing() -> None:
    # Upper arm fixed, forearm turning at constant w (0.3 -> 2.7 rad): the wrist accelerates
    # w^2 L2 toward the elbow.
    rate, w = 100.0, 0.6
    t = np.arange(400) / rate
    q1 = np.full_like(t, 0.2)
    q2 = 0.3 + w * t
    pts = {k: _to_3d(v, 1.0) for k, v in _arm(q1, q2).items()}
    rec = Recording(
        {k: Channel(k, v, rate, "m", "marker") for k, v in _rename(pts, "R").items()}, "s", "c3d"
    )
    a = arm_angles(rec, lowpass=None, max_speed=50.0)
    acc = np.linalg.norm(a.wrist_acceleration[20:-20], axis=1)
    # Savitzky-Golay (cubic, 15 samples) on a sampled circle is biased by well under 0.5 %.
    np.testing.assert_allclose(acc, w**2 * L2, rtol=5e-3)
    np.testing.assert_allclose(a.elbow_velocity[20:-20], w, rtol=1e-6)


def test_short_holes_are_filled_long_holes_and_jumps_split_without_derivatives() -> None:
    t, q1, q2 = _curl(30.0, seconds=10.0)
    rec = _image_recording(t, _arm(q1, q2))
    rec.metadata["image_size"] = [1280, 720]  # as a reader that already rescaled x says
    elbow = rec.channels["left_elbow"]
    assert elbow.confidence is not None
    elbow.confidence[40:42] = 0.1  # 67 ms: interpolated
    elbow.confidence[100:115] = 0.1  # 0.5 s: a gap
    for ch in rec.channels.values():  # frames 200-209 lost by the recorder: a jump
        ch.data[200:] = np.roll(ch.data, 10, axis=0)[200:]
    a = arm_angles(rec)
    assert a.valid[40:42].all()
    assert not a.valid[100:115].any()
    np.testing.assert_array_equal(a.segments, [[0, 100], [115, 200], [200, 300]])
    assert a.gaps.shape == (2, 2)
    np.testing.assert_allclose(a.gaps[0], [t[99], t[115]])
    # No derivative reaches across a gap or a jump.
    for edge in (100, 115, 200):
        assert np.isnan(a.elbow_velocity[edge - 1 : edge + 1]).all()
        assert np.isnan(a.elbow_acceleration[edge - 1 : edge + 1]).all()
    assert np.isfinite(a.elbow_velocity[50:90]).all()


def test_side_with_better_visibility_is_chosen() -> None:
    t, q1, q2 = _curl(30.0)
    pts = _arm(q1, q2)
    left = _image_recording(t, pts, side="left", visibility=0.3)
    right = _image_recording(t, pts, side="right", visibility=0.95)
    both = Recording({**left.channels, **right.channels}, "x.csv", "mediapipe_csv")
    assert arm_angles(both).side == "right"
    assert arm_angles(both, side="left", min_visibility=0.2).side == "left"


def test_no_arm_landmarks_is_a_clear_error() -> None:
    rec = Recording(
        {"nose": Channel("nose", np.zeros((10, 3)), 30.0, "norm", "landmark")},
        "face_only.csv",
        "mediapipe_csv",
    )
    with pytest.raises(RecordingError, match=r"face_only\.csv: no arm landmarks.*shoulder"):
        arm_angles(rec)


def test_pyomeca_marker_elbow_spans_42_to_155_deg_included() -> None:
    a = arm_angles(pyomeca_c3d())
    included = 180.0 - np.rad2deg(a.elbow)
    assert np.nanmin(included) == pytest.approx(42.0, abs=2.0)
    assert np.nanmax(included) == pytest.approx(155.0, abs=2.0)
    assert a.position_unit == "m"
    assert np.isfinite(a.elbow_velocity[10:-10]).all()


def test_mediapipe_frames_angles_gaps_and_no_derivative_across_them() -> None:
    rec = mediapipe_csv()
    a = arm_angles(rec, lowpass=None)
    finite = a.elbow[np.isfinite(a.elbow)]
    assert finite.size > 200
    assert np.all((finite >= 0) & (finite <= np.pi))
    assert len(a.gaps) >= 5  # the file holds 12 labelled runs with skipped frames between
    # Independent angle: 180 deg minus the included angle from the raw x, y columns.
    s = rec.channels[f"{a.side}_shoulder"].data[:, :2] * [1, -1]
    e = rec.channels[f"{a.side}_elbow"].data[:, :2] * [1, -1]
    w = rec.channels[f"{a.side}_wrist"].data[:, :2] * [1, -1]
    u, v = s - e, w - e
    cos_inc = np.sum(u * v, axis=1) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)
    flex = np.pi - np.arccos(np.clip(cos_inc, -1, 1))
    seen = np.isfinite(a.elbow)
    np.testing.assert_allclose(a.elbow[seen], flex[seen], atol=1e-9)
    # Every segment edge that borders a gap has no derivative.
    assert np.isnan(a.elbow_velocity[a.segments[1:, 0]]).all()
    assert np.isnan(a.elbow_velocity[a.segments[:-1, 1] - 1]).all()


def test_angles_from_joint_angle_channels() -> None:
    from app.analysis.pose import angles_from_channels

    rate = 100.0
    t, q1, q2 = _curl(rate)
    rec = Recording(
        {
            "elbow_flexion": Channel("elbow_flexion", q2, rate, "rad", "angle"),
            "shoulder_ele": Channel("shoulder_ele", q1, rate, "rad", "angle"),
            "pro_sup": Channel("pro_sup", 0 * q1 + 0.1, rate, "rad", "angle"),
        },
        "ik.mot",
        "mot",
    )
    a = angles_from_channels(rec)
    assert a is not None
    w, amp = 2 * np.pi * 0.5, np.deg2rad(130.0) / 2
    np.testing.assert_allclose(a.elbow[50:-50], q2[50:-50], atol=2e-3)
    np.testing.assert_allclose(a.shoulder[50:-50], q1[50:-50], atol=2e-3)
    np.testing.assert_allclose(
        a.elbow_velocity[50:-50], (amp * w * np.sin(w * t))[50:-50], atol=0.02
    )
    assert a.wrist_acceleration.shape == (len(t), 0)
    no_elbow = Recording({"pro_sup": rec.channels["pro_sup"]}, "x.mot", "mot")
    assert angles_from_channels(no_elbow) is None


@pytest.mark.parametrize(("n", "deriv"), [(50, 1), (5000, 1), (5000, 2), (4001, 0)])
def test_fft_savgol_matches_scipy(n: int, deriv: int) -> None:
    """The overlap-add Savitzky-Golay gives scipy's ``mode="interp"`` numbers, ends included."""
    from scipy.signal import savgol_filter

    from app.analysis.pose import savgol

    rng = np.random.default_rng(n)
    y = np.cumsum(rng.standard_normal((n, 2)), axis=0)
    ref = savgol_filter(y, 31, 3, deriv=deriv, delta=0.01, axis=0, mode="interp")
    got = savgol(y, 31, 3, deriv=deriv, delta=0.01)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9 * float(np.max(np.abs(ref))))


# ---------------------------------------------------------------------------------------------
# landmark presets and mappings (issue 29)


def test_plugin_gait_right_with_one_wrist_marker_needs_the_preset() -> None:
    rec, q2 = curl_markers({"shoulder": "RSHO", "elbow": "RELB", "wrist": "RWRA"})
    with pytest.raises(RecordingError) as err:
        arm_angles(rec)
    message = str(err.value)
    # the message lists the names present and the presets
    assert "RSHO, RELB, RWRA, C7" in message
    assert "plugin_gait_right" in message and "opencap_left" in message and "pose2sim" in message
    for spec in ("plugin_gait_right", "plugin_gait", "shoulder=RSHO,elbow=RELB,wrist=RWRA"):
        a = arm_angles(rec, landmarks=spec, lowpass=None)
        ok = a.valid
        np.testing.assert_allclose(a.elbow[ok], q2[ok], atol=1e-6)
    assert arm_angles(rec, landmarks="plugin_gait_right").side == "right"
    with pytest.raises(RecordingError, match="left side with landmarks 'plugin_gait_left'"):
        arm_angles(rec, landmarks="plugin_gait_left")
    with pytest.raises(RecordingError, match="is the right arm"):
        arm_angles(rec, landmarks="plugin_gait_right", side="left")


@pytest.mark.parametrize(
    ("preset", "names"),
    [
        (
            "opencap_right",
            {"shoulder": "r_shoulder_study", "elbow": "r_melbow_study", "wrist": "r_mwrist_study"},
        ),
        (
            "opencap_left",
            {"shoulder": "L_shoulder_study", "elbow": "L_lelbow_study", "wrist": "L_lwrist_study"},
        ),
        ("pose2sim_right", {"shoulder": "RShoulder", "elbow": "RElbow", "wrist": "RWrist"}),
        ("pose2sim_left", {"shoulder": "LShoulder", "elbow": "LElbow", "wrist": "LWrist"}),
        ("plugin_gait_left", {"shoulder": "LSHO", "elbow": "LELB", "wrist": "LWRB"}),
    ],
)
def test_presets_find_their_marker_sets(preset: str, names: dict[str, str]) -> None:
    rec, q2 = curl_markers(names)
    with pytest.raises(RecordingError, match="no arm landmarks"):
        arm_angles(rec)
    a = arm_angles(rec, landmarks=preset, lowpass=None)
    assert a.side == preset.rsplit("_", 1)[1]
    np.testing.assert_allclose(a.elbow[a.valid], q2[a.valid], atol=1e-6)


def test_preset_averages_the_markers_present() -> None:
    # OpenCap's lateral and medial elbow markers straddle the joint centre: the preset averages.
    rec, q2 = curl_markers(
        {"shoulder": "r_shoulder_study", "elbow": "r_lelbow_study", "wrist": "r_lwrist_study"}
    )
    elbow = rec.channels["r_lelbow_study"].data
    # markers 3 cm either side of the joint centre, along the elbow's flexion axis
    offset = np.cross(elbow[0] - rec.channels["r_shoulder_study"].data[0], [0.0, 0.0, 1.0])
    offset = 0.03 * offset / np.linalg.norm(offset)
    rec.channels["r_lelbow_study"] = Channel("r_lelbow_study", elbow + offset, 100.0, "m", "marker")
    rec.channels["r_melbow_study"] = Channel("r_melbow_study", elbow - offset, 100.0, "m", "marker")
    a = arm_angles(rec, landmarks="opencap_right", lowpass=None)
    np.testing.assert_allclose(a.elbow[a.valid], q2[a.valid], atol=1e-6)
    lateral = arm_angles(rec, landmarks="shoulder=r_shoulder_study,elbow=r_lelbow_study,"
                         "wrist=r_lwrist_study", lowpass=None)  # fmt: skip
    assert np.nanmax(np.abs(lateral.elbow - q2)) > 1e-3  # one marker alone is off the centre


def test_bad_landmark_specs_are_clear_errors() -> None:
    rec, _ = curl_markers({"shoulder": "RSHO", "elbow": "RELB", "wrist": "RWRA"})
    with pytest.raises(RecordingError, match=r"unknown landmark preset 'vicon'.*plugin_gait_right"):
        arm_angles(rec, landmarks="vicon")
    with pytest.raises(RecordingError, match="unknown landmark role 'hand'"):
        arm_angles(rec, landmarks="shoulder=RSHO,hand=RWRA")
    with pytest.raises(RecordingError, match=r"\['RWRB'\] given for the wrist"):
        arm_angles(rec, landmarks="shoulder=RSHO,elbow=RELB,wrist=RWRB")


def test_cli_landmarks_option_changes_the_result(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from app.cli import main

    rec, _ = curl_markers({"shoulder": "RSHO", "elbow": "RELB", "wrist": "RWRA"}, 12.0)
    trc = write_trc(tmp_path / "pig_right.trc", rec)
    assert main(["analyze", str(trc), "--json"]) != 0
    err = capsys.readouterr().err
    assert "no arm landmarks" in err and "RSHO, RELB, RWRA" in err and "plugin_gait_right" in err
    assert main(["analyze", str(trc), "--json", "--landmarks", "plugin_gait_right"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["settings"]["pose"]["landmarks"] == "plugin_gait_right"
    assert out["files"][0]["pose"]["side"] == "right"
    assert out["n_lifts"] == len(out["files"][0]["lifts"]) == 6  # 12 s of 0.5 Hz curls
    assert main(["analyze", str(trc), "--json", "--landmarks", "wrist"]) != 0
    assert "unknown landmark preset 'wrist'" in capsys.readouterr().err


def test_api_and_job_take_the_landmarks_option(tmp_path: Path) -> None:
    from pydantic import ValidationError

    from app.api.schemas import AnalysisRequest
    from app.jobs.tasks import analyse

    assert AnalysisRequest(recording_id=1, landmarks="opencap_left").landmarks == "opencap_left"
    assert AnalysisRequest(recording_id=1).landmarks is None
    with pytest.raises(ValidationError, match=r"unknown landmark preset 'rsho'.*pose2sim_right"):
        AnalysisRequest(recording_id=1, landmarks="rsho")
    rec, _ = curl_markers({"shoulder": "RSHO", "elbow": "RELB", "wrist": "RWRA"}, 12.0)
    trc = write_trc(tmp_path / "pig_right.trc", rec)
    files = [{"name": trc.name, "data": trc.read_bytes(), "sidecars": {}, "read_options": {}}]
    with pytest.raises(RecordingError, match="no arm landmarks"):
        analyse({"files": files, "options": {"side": "auto"}})
    out = analyse({"files": files, "options": {"side": "auto", "landmarks": "plugin_gait_right"}})
    assert out["result"]["n_lifts"] == 6
    assert out["result"]["settings"]["pose"]["landmarks"] == "plugin_gait_right"


def test_upload_form_offers_every_landmark_preset() -> None:
    import re

    from app.analysis.pose import LANDMARK_PRESETS
    from app.config import PACKAGED_PAGES

    js = (PACKAGED_PAGES / "js" / "recordings.js").read_text(encoding="utf-8")
    listed = re.search(r"const LANDMARK_PRESETS = \[(.*?)\];", js)
    assert listed is not None
    assert re.findall(r'"([a-z0-9_]+)"', listed.group(1)) == list(LANDMARK_PRESETS)
