"""MediaPipe Pose landmark readers (CSV named/indexed columns, JSON)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from app.recordings import LANDMARK_NAMES, RecordingError, read_bytes, read_recording
from tests.conftest import shared_file
from tests.recordings._writers import mediapipe_frames

REAL = "mediapipe_bicep_curl_frames/test.csv"


def _included_angle_deg(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    u, v = a[:, :2] - b[:, :2], c[:, :2] - b[:, :2]
    cos = np.sum(u * v, axis=1) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def test_landmark_names_follow_mediapipe_indexing() -> None:
    assert len(LANDMARK_NAMES) == 33
    assert LANDMARK_NAMES[0] == "nose"
    assert LANDMARK_NAMES[11:17] == (
        "left_shoulder",
        "right_shoulder",
        "left_elbow",
        "right_elbow",
        "left_wrist",
        "right_wrist",
    )
    assert LANDMARK_NAMES[23:25] == ("left_hip", "right_hip")
    assert LANDMARK_NAMES[32] == "right_foot_index"


def test_real_bicep_curl_csv(shared_data: Path) -> None:
    path = shared_file(REAL)
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    rec = read_recording(path, frame_rate=30.0)

    assert rec.format == "mediapipe_csv"
    # README: 604 rows, 9 landmarks (ids 0, 11-16, 23, 24), labels C = 339 / L = 265
    assert set(rec.channels) == {
        "nose",
        "left_shoulder",
        "right_shoulder",
        "right_elbow",
        "left_elbow",
        "right_wrist",
        "left_wrist",
        "left_hip",
        "right_hip",
    }
    elbow = rec.channels["right_elbow"]
    assert elbow.kind == "landmark" and elbow.unit == "norm" and elbow.data.shape == (604, 3)
    assert elbow.rate == 30.0
    np.testing.assert_array_equal(elbow.data[:, 0], [float(r["right_elbow_x"]) for r in rows])
    assert elbow.confidence is not None
    np.testing.assert_array_equal(elbow.confidence, [float(r["right_elbow_v"]) for r in rows])
    labels = rec.metadata["annotations"]["label"]
    assert labels.count("C") == 339 and labels.count("L") == 265
    minimum = min(
        float(c.confidence.min()) for c in rec.channels.values() if c.confidence is not None
    )
    assert minimum == pytest.approx(0.013, abs=5e-4)
    ch = rec.channels
    right = _included_angle_deg(
        ch["right_shoulder"].data, ch["right_elbow"].data, ch["right_wrist"].data
    )
    left = _included_angle_deg(
        ch["left_shoulder"].data, ch["left_elbow"].data, ch["left_wrist"].data
    )
    assert (right.min(), right.max()) == (
        pytest.approx(30.9, abs=0.05),
        pytest.approx(178.6, abs=0.05),
    )
    assert (left.min(), left.max()) == (
        pytest.approx(28.3, abs=0.05),
        pytest.approx(171.9, abs=0.05),
    )


def test_real_csv_needs_a_frame_rate(shared_data: Path) -> None:
    with pytest.raises(RecordingError, match=r"test\.csv: has no timestamps and no frame rate"):
        read_recording(shared_file(REAL))


def test_image_size_undoes_aspect_distortion(tmp_path: Path) -> None:
    width, height = 1920, 1080
    # 135 deg at the elbow in pixels (a diagonal forearm, so axis scaling changes the angle)
    px = {
        "right_shoulder": (900.0, 300.0),
        "right_elbow": (900.0, 600.0),
        "right_wrist": (1200.0, 900.0),
    }
    n = 5
    header = ["time"] + [f"{k}_{a}" for k in px for a in "xyzv"]
    lines = [",".join(header)]
    for i in range(n):
        vals = [f"{i / 25:.2f}"]
        for x, y in px.values():
            vals += [f"{x / width:.9f}", f"{y / height:.9f}", "0", "0.99"]
        lines.append(",".join(vals))
    path = tmp_path / "pose.csv"
    path.write_text("\n".join(lines) + "\n")

    raw = read_recording(path)
    fixed = read_recording(path, image_size=(width, height))

    def angle(rec: object) -> float:
        ch = rec.channels  # type: ignore[attr-defined]
        return float(
            _included_angle_deg(
                ch["right_shoulder"].data, ch["right_elbow"].data, ch["right_wrist"].data
            )[0]
        )

    assert angle(fixed) == pytest.approx(135.0, abs=1e-6)
    assert abs(angle(raw) - 135.0) > 5.0
    assert fixed.metadata["image_size"] == [width, height]
    assert fixed.channels["right_elbow"].rate == 25.0
    np.testing.assert_allclose(
        fixed.channels["right_wrist"].data[0, :2], [1200 / height, 900 / height]
    )


def test_indexed_columns_with_frame_gaps(tmp_path: Path) -> None:
    lm = mediapipe_frames(40)
    frames = np.r_[0:20, 25:45]
    header = ["frame"] + [f"{a}{k}" for k in range(33) for a in ("x", "y", "z", "v")]
    lines = [",".join(header)]
    for i in range(40):
        lines.append(",".join([str(frames[i])] + [f"{v:.6f}" for v in lm[i].ravel()]))
    path = tmp_path / "ids.csv"
    path.write_text("\n".join(lines) + "\n")

    rec = read_recording(path, frame_rate=30.0)

    assert rec.format == "mediapipe_csv" and len(rec.channels) == 33
    wrist = rec.channels["left_wrist"]  # id 15
    np.testing.assert_allclose(wrist.data, np.round(lm[:, 15, :3], 6))
    assert wrist.time is not None
    np.testing.assert_allclose(wrist.time, frames / 30.0)
    assert any("gap" in w for w in rec.metadata["warnings"])


def _frame_dicts(lm: np.ndarray) -> list[list[dict[str, float]]]:
    return [
        [
            {
                "x": float(p[0]),
                "y": float(p[1]),
                "z": float(p[2]),
                "visibility": float(p[3]),
                "presence": 1.0,
            }
            for p in frame
        ]
        for frame in lm
    ]


def test_tasks_api_json_list_of_frames(tmp_path: Path) -> None:
    lm = mediapipe_frames(30)
    poses = _frame_dicts(lm)
    frames = []
    for i, pose in enumerate(poses):
        entry: dict[str, object] = {"timestamp_ms": 1000 + 40 * i, "pose_landmarks": [pose]}
        if i == 5:
            entry["pose_landmarks"] = []  # no person detected in this frame
        if i == 6:
            entry["pose_landmarks"] = [pose, poses[0]]  # two people: first one is used
        frames.append(entry)
    path = tmp_path / "result.json"
    path.write_text(json.dumps(frames))

    rec = read_recording(path)

    assert rec.format == "mediapipe_json" and len(rec.channels) == 33
    elbow = rec.channels["right_elbow"]
    assert elbow.rate == 25.0 and elbow.start == pytest.approx(1.0)
    assert np.isnan(elbow.data[5]).all() and elbow.confidence is not None
    assert elbow.confidence[5] == 0.0 and elbow.confidence[4] == pytest.approx(0.9)
    np.testing.assert_allclose(rec.channels["left_wrist"].data[6], lm[6, 15, :3])
    assert rec.metadata["multi_pose_frames"] == 1


def test_json_object_with_image_size_and_fps(tmp_path: Path) -> None:
    lm = mediapipe_frames(10)
    obj = {
        "image_width": 1280,
        "image_height": 720,
        "fps": 30,
        "frames": [{"landmark": pose} for pose in _frame_dicts(lm)],
    }
    rec = read_bytes(json.dumps(obj).encode(), "upload.json")
    assert rec.channels["nose"].rate == 30.0
    assert rec.metadata["image_size"] == [1280, 720]
    np.testing.assert_allclose(rec.channels["nose"].data[:, 0], lm[:, 0, 0] * 1280 / 720)
    np.testing.assert_allclose(rec.channels["nose"].data[:, 1], lm[:, 0, 1])


def test_pose_without_arm_landmarks_is_rejected(tmp_path: Path) -> None:
    lines = ["time,nose_x,nose_y,nose_z,nose_v,left_hip_x,left_hip_y,left_hip_z,left_hip_v"]
    lines += [f"{i / 30:.4f},0.5,0.1,0,0.9,0.5,0.6,0,0.9" for i in range(10)]
    path = tmp_path / "head.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordingError, match=r"head\.csv: has no arm landmarks"):
        read_recording(path, format="mediapipe_csv")
