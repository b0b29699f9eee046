"""Video to pose: the MediaPipe worker in its own environment, progress, cancel, bad videos.

The tests that run MediaPipe need the pose environment (``make test`` creates it); they skip
with the reason otherwise. The real video is the shared Sports2D demo (230 frames, 30 fps,
1768 x 994 px; two people, one walking).
"""

from __future__ import annotations

import itertools
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from app.progress import Progress
from app.recordings import (
    PoseCancelled,
    PoseExtraction,
    RecordingError,
    extract_pose,
    find_pose_python,
    is_video,
    read_bytes,
)
from tests.conftest import shared_file

DEMO = "video_sports2d_demo/demo.mp4"


def _pose_python() -> Path:
    try:
        return find_pose_python()
    except RecordingError:
        pytest.skip(
            "no pose environment (make test creates it; or set BIOPLAN_POSE_PYTHON /"
            " run 'bioplan pose-env')"
        )


def _write_video(path: Path, frames: list[np.ndarray], fps: float = 30.0) -> Path:
    """A small mp4 written with the pose environment's OpenCV (the main one has none)."""
    import subprocess
    import sys

    stack = np.stack(frames).astype(np.uint8)
    raw = path.with_suffix(".npy")
    np.save(raw, stack)
    code = (
        "import sys, numpy as np, cv2\n"
        "a = np.load(sys.argv[1]); h, w = a.shape[1:3]\n"
        "out = cv2.VideoWriter(sys.argv[2], cv2.VideoWriter_fourcc(*'mp4v'), float(sys.argv[3]),"
        " (w, h))\n"
        "[out.write(f) for f in a]\nout.release()\n"
    )
    subprocess.run(
        [str(_pose_python()), "-I", "-c", code, str(raw), str(path), str(fps)],
        check=True,
        stdout=sys.stderr,
    )
    return path


def test_is_video_by_extension() -> None:
    assert is_video("a/curl.MP4") and is_video("x.mov") and is_video("x.avi")
    assert not is_video("pose.csv") and not is_video("trial.c3d")


def test_missing_environment_names_every_way_to_give_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("BIOPLAN_POSE_PYTHON", raising=False)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))
    monkeypatch.chdir(tmp_path)  # no ./.venv-pose here
    with pytest.raises(RecordingError) as err:
        find_pose_python()
    text = str(err.value)
    assert "--pose-python" in text and "BIOPLAN_POSE_PYTHON" in text and "pose-env" in text
    with pytest.raises(RecordingError, match="does not exist"):
        find_pose_python(tmp_path / "no" / "python")


def test_a_video_read_as_a_recording_points_to_pose_extraction() -> None:
    with pytest.raises(RecordingError, match="video") as err:
        read_bytes(b"\x00\x00\x00\x18ftypisom" + bytes(600), "curl.mp4")
    assert "pose" in str(err.value)


@pytest.fixture(scope="module")
def demo_pose() -> tuple[PoseExtraction, list[Progress]]:
    """The demo video's pose, extracted once for the tests that read it (the whole video
    through MediaPipe), and the progress updates the extraction sent."""
    py = _pose_python()
    updates: list[Progress] = []
    x = extract_pose(shared_file(DEMO), pose_python=py, progress=updates.append)
    return x, updates


def test_demo_video_gives_pose_with_size_rate_progress_and_skeletons(
    demo_pose: tuple[PoseExtraction, list[Progress]],
) -> None:
    x, updates = demo_pose
    assert (x.frames, x.fps, x.image_size) == (230, 30.0, (1768, 994))
    assert x.frames_with_pose >= 200  # a person is on screen throughout
    assert [u.stage for u in updates] == ["pose"] * len(updates)
    assert updates[-1].done == updates[-1].of == 230
    assert all(a.done <= b.done for a, b in itertools.pairwise(updates))
    assert 1 <= len(x.skeletons) <= 4
    assert all(s.jpeg[:2] == b"\xff\xd8" for s in x.skeletons)
    rec = x.recording()
    assert rec.format == "mediapipe_json" and rec.metadata["image_size"] == [1768, 994]
    assert rec.channels["right_elbow"].rate == pytest.approx(30.0)


def test_corrupt_video_is_a_recording_error(tmp_path: Path) -> None:
    py = _pose_python()
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"\x00\x00\x00\x18ftypisom" + bytes(range(256)) * 40)
    with pytest.raises(RecordingError) as err:
        extract_pose(bad, pose_python=py)
    assert str(err.value).startswith("broken.mp4:") and "decod" in str(err.value)


def test_video_longer_than_the_limit_is_refused(tmp_path: Path) -> None:
    py = _pose_python()
    with pytest.raises(RecordingError, match="longer than the limit of 2 s"):
        extract_pose(shared_file(DEMO), pose_python=py, max_seconds=2.0)


def test_video_without_a_person_is_refused(tmp_path: Path) -> None:
    py = _pose_python()
    rng = np.random.default_rng(0)
    frames = [np.full((120, 160, 3), 90, np.uint8) + rng.integers(0, 20, (120, 160, 3), np.uint8)
              for _ in range(20)]  # fmt: skip
    video = _write_video(tmp_path / "empty.mp4", frames)
    with pytest.raises(RecordingError, match="no person detected in any of its 20 frames"):
        extract_pose(video, pose_python=py)


def test_cancel_stops_the_worker_at_once() -> None:
    py = _pose_python()
    cancel = threading.Event()
    seen: list[int] = []

    def on_progress(update: Progress) -> None:
        seen.append(update.done)
        if update.done >= 10:
            cancel.set()

    start = time.monotonic()
    with pytest.raises(PoseCancelled):
        extract_pose(shared_file(DEMO), pose_python=py, progress=on_progress, cancel=cancel)
    assert seen and max(seen) < 230  # stopped before the end of the video
    assert time.monotonic() - start < 120  # generous: a busy 2-core machine


def test_an_exception_in_progress_stops_the_worker() -> None:
    """A job's cancellation arrives as an exception from its progress callback."""
    py = _pose_python()

    class Stop(Exception):
        pass

    def on_progress(update: Progress) -> None:
        if update.done >= 5:
            raise Stop

    with pytest.raises(Stop):
        extract_pose(shared_file(DEMO), pose_python=py, progress=on_progress)


def test_analyze_files_takes_a_video() -> None:
    from app.analysis import analyze_files

    py = _pose_python()
    result = analyze_files([shared_file(DEMO)], pose_python=py)
    (rec,) = result.recordings
    assert rec.source == "demo.pose.json" and rec.angles is not None
    assert not result.template.assumptions  # the video states its size


def test_demo_video_says_two_people_and_shows_the_tracked_person(
    demo_pose: tuple[PoseExtraction, list[Progress]],
) -> None:
    """Two people: the platform's is tracked in frames 3-168, then the track jumps to the
    walker and to another place; the warning says so, the skeleton frames show the tracked
    person, and the template's lifts come from the tracked person's well-seen frames."""
    from app.analysis import analyze_recordings

    x = demo_pose[0]
    (people,) = [w for w in x.warnings if "people" in w]
    assert people.startswith("demo.mp4: 2 people detected (another person in")
    assert "the tracked person is shown in frames 3-16" in people
    assert x.skeletons and all(s.person == 0 for s in x.skeletons)
    assert all(s.note == "the tracked person" and s.quality >= 0.5 for s in x.skeletons)
    rec = x.recording()
    assert rec.metadata["persons"]["frames_with_another_person"]
    assert rec.metadata["pose_track"]["persons"] >= 2
    assert any("jumps to another person" in w for w in rec.metadata["warnings"])
    result = analyze_recordings([rec])
    a = result.recordings[0].angles
    assert a is not None and a.quality is not None
    assert a.quality.summary()["other_person_frames"] > 30  # the frames after the jump
    assert result.lifts and all(not r.low_quality for r in result.lifts)
    assert all(r.lift.end < 168 / 30 for r in result.lifts)  # within the tracked frames
    assert "left out" not in result.template.source  # nothing was: the source says only that
    assert result.template.n_lifts == len(result.lifts)
