"""Video to pose: MediaPipe Pose landmarks from a video file, in a separate environment.

MediaPipe 0.10.21 is the last release whose ``solutions.pose`` ships its model inside the wheel
(so it works offline); it needs numpy<2 and protobuf<5, which BioPlan's own environment cannot
have. So extraction runs a small worker script (``_pose_worker.py``, shipped in this package)
with the Python of a separate *pose environment*, found from, in order: the ``pose_python``
argument (CLI ``--pose-python``), the ``BIOPLAN_POSE_PYTHON`` environment variable, a
``.venv-pose`` in the current directory (what ``make`` creates), or the default location that
``bioplan pose-env`` creates (:func:`default_pose_env`). The worker reports
progress as JSON lines (frames done / total) and writes the landmarks as MediaPipe JSON with the
video's frame rate and image size, so they are read and analysed exactly like an uploaded
MediaPipe file (true angles: the image size undoes the aspect distortion). Cancelling stops the
worker at once.

MediaPipe Pose follows one person. The worker also looks for another person a few times a
second (the tracked person painted over); the landmarks tell when the track jumped to someone
(or something) else. Both become a warning that says in which frames the tracked person is
shown, and the skeleton frames returned are picked among more candidates: the tracked person,
arm well seen, limbs of plausible lengths, spread over the video; each says whom it shows.
"""

from __future__ import annotations

import json
import logging
import math
import os
import queue
import shutil
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import IO, Any

import numpy as np

from app.names import MAX_VIDEO_SECONDS
from app.progress import ProgressFn, report
from app.recordings._pose_quality import FrameQuality, arm_quality, frame_ranges, image_landmarks
from app.recordings.types import Recording, RecordingError

logger = logging.getLogger("bioplan.recordings")

#: Environment variable naming the pose environment's Python.
POSE_PYTHON_ENV = "BIOPLAN_POSE_PYTHON"
#: Video containers accepted (by extension; the content is checked by decoding).
VIDEO_EXTENSIONS: tuple[str, ...] = (".mp4", ".mov", ".avi")
#: What the pose environment holds (mediapipe goes in without its dependencies, whose pins
#: would pull a numpy 2 build it does not support).
POSE_REQUIREMENTS: tuple[str, ...] = (
    "numpy<2",
    "opencv-python-headless>=4.8,<5",
    "protobuf>=4.25,<5",
    "absl-py",
    "attrs",
    "flatbuffers>=2.0",
    "matplotlib",
)
MEDIAPIPE = "mediapipe==0.10.21"
#: A skeleton frame is shown as good when it and this many frames each side are good quality.
SKELETON_CONTEXT = 5


@dataclass(frozen=True)
class SkeletonFrame:
    """One video frame with the detected skeleton drawn on it.

    Attributes:
        frame: 0-based frame index.
        time: its time in the video [s].
        jpeg: the image (JPEG bytes, at most 640 px wide).
        person: whom the skeleton is on: 0 the tracked person (the one followed in most
            frames), 1, 2... someone (or something) else the track jumped to, -1 unknown.
        quality: the frame's detection quality (the better arm's score, 0-1; NaN unknown).
        note: the same in words, for the page.
    """

    frame: int
    time: float
    jpeg: bytes
    person: int = -1
    quality: float = math.nan
    note: str = ""


@dataclass(frozen=True)
class PoseExtraction:
    """Pose landmarks extracted from a video.

    Attributes:
        source: the video's file name.
        landmarks_json: MediaPipe JSON (``fps``, ``image_width``, ``image_height``, ``frames``)
            as :func:`app.recordings.read_bytes` reads it; store it like an uploaded file.
        fps: the video's frame rate [Hz].
        image_size: (width, height) [px].
        frames: frames decoded.
        frames_with_pose: frames in which a person was detected.
        skeletons: a few frames with the skeleton drawn, for the user to check the fit.
        warnings: what the user should know (e.g. many frames without a pose).
    """

    source: str
    landmarks_json: bytes
    fps: float
    image_size: tuple[int, int]
    frames: int
    frames_with_pose: int
    skeletons: list[SkeletonFrame] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def landmarks_name(self) -> str:
        """File name for the stored landmarks (``<video stem>.pose.json``)."""
        return f"{Path(self.source).stem}.pose.json"

    def recording(self) -> Recording:
        """The landmarks as a :class:`Recording` (format ``mediapipe_json``)."""
        from app.recordings._read import read_bytes

        rec = read_bytes(self.landmarks_json, self.landmarks_name, format="mediapipe_json")
        rec.metadata["video"] = {
            "source": self.source,
            "frames": self.frames,
            "frames_with_pose": self.frames_with_pose,
        }
        rec.metadata["warnings"] = list(self.warnings) + list(rec.metadata["warnings"])
        return rec


def is_video(path: str | Path) -> bool:
    """True when the file name has a video extension (mp4, mov, avi)."""
    return Path(path).suffix.lower() in VIDEO_EXTENSIONS


def default_pose_env() -> Path:
    """Where ``bioplan pose-env`` puts the pose environment by default:
    ``$XDG_DATA_HOME/bioplan/pose-env`` (``~/.local/share/bioplan/pose-env``)."""
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "bioplan" / "pose-env"


def _env_python(env: Path) -> Path:
    return env / ("Scripts/python.exe" if sys.platform == "win32" else "bin/python")


#: The pose environment ``make`` creates in the project folder (looked for in the current
#: directory, never by walking up from a source file).
PROJECT_POSE_ENV = ".venv-pose"


def find_pose_python(pose_python: str | Path | None = None) -> Path:
    """The pose environment's Python: ``pose_python``, else ``$BIOPLAN_POSE_PYTHON``, else
    ``./.venv-pose`` (what ``make`` creates), else the default environment's.

    Raises:
        RecordingError: none of them exists; the message names the ways to give it.
    """
    given = pose_python or os.environ.get(POSE_PYTHON_ENV)
    candidate = Path(given) if given else _env_python(default_pose_env())
    if not given and _env_python(Path(PROJECT_POSE_ENV)).is_file():
        candidate = _env_python(Path(PROJECT_POSE_ENV)).absolute()
    if candidate.is_dir():
        candidate = _env_python(candidate)
    if candidate.is_file() and os.access(candidate, os.X_OK):
        return candidate
    where = f"{candidate} does not exist" if given else "no pose environment found"
    raise RecordingError(
        f"video needs the pose environment (MediaPipe 0.10.21): {where}",
        expected=f"--pose-python PATH or {POSE_PYTHON_ENV}=PATH naming its python,"
        f" or create it with 'bioplan pose-env' (default {default_pose_env()})",
    )


def create_pose_env(
    target: str | Path | None = None, *, python: str | None = None, quiet: bool = True
) -> Path:
    """Create (or complete) the pose environment and return its Python.

    Uses ``uv`` when it is on PATH, else ``venv`` + ``pip``; needs the package index.

    Args:
        target: the environment's directory (default :func:`default_pose_env`).
        python: the interpreter to base it on (default: this one; MediaPipe 0.10.21 has wheels
            for CPython 3.9-3.12).
        quiet: keep the installers' output short.
    """
    env = Path(target) if target is not None else default_pose_env()
    py = _env_python(env)
    base = python or sys.executable
    uv = shutil.which("uv")
    q = ["--quiet"] if quiet else []
    steps: list[list[str]] = []
    if uv:
        if not py.is_file():
            steps.append([uv, "venv", *q, "--python", base, str(env)])
        # Bytecode now: with PYTHONDONTWRITEBYTECODE set nothing writes it later, and every
        # video would compile MediaPipe's imports from source again.
        pip = [uv, "pip", "install", *q, "--compile-bytecode", "--python", str(py)]
    else:
        if not py.is_file():
            steps.append([base, "-m", "venv", str(env)])
        pip = [str(py), "-m", "pip", "install", *q]
    steps += [[*pip, "--no-deps", MEDIAPIPE], [*pip, *POSE_REQUIREMENTS]]
    for cmd in steps:
        done = subprocess.run(cmd, capture_output=quiet, text=True, check=False)
        if done.returncode != 0:
            tail = (done.stderr or "").strip().splitlines()[-1:] if quiet else []
            raise RecordingError(
                f"creating the pose environment failed: {' '.join(cmd[:4])} ... exited"
                f" {done.returncode}" + (f": {tail[0]}" if tail else ""),
                expected="network access to the package index and a CPython 3.9-3.12",
            )
    check = [str(py), "-I", "-c", "import cv2, mediapipe; mediapipe.solutions.pose.Pose"]
    if subprocess.run(check, capture_output=True, check=False).returncode != 0:
        raise RecordingError(
            f"the pose environment at {env} cannot import mediapipe.solutions.pose",
            expected="remove the folder and run 'bioplan pose-env' again",
        )
    return py


# ---------------------------------------------------------------------------------------------


def _read_lines(stream: IO[str], out: queue.Queue[str | None]) -> None:
    for line in stream:
        out.put(line)
    out.put(None)


def _events(
    proc: subprocess.Popen[str], cancel: threading.Event | None
) -> Iterator[dict[str, Any]]:
    """The worker's JSON events as they come; checks ``cancel`` between them."""
    assert proc.stdout is not None
    lines: queue.Queue[str | None] = queue.Queue()
    threading.Thread(target=_read_lines, args=(proc.stdout, lines), daemon=True).start()
    while True:
        if cancel is not None and cancel.is_set():
            raise PoseCancelled("pose extraction cancelled")
        try:
            line = lines.get(timeout=0.1)
        except queue.Empty:
            continue
        if line is None:
            return
        try:
            yield json.loads(line)
        except json.JSONDecodeError:
            continue  # a library printed to stdout; only our JSON lines count


class PoseCancelled(Exception):
    """Raised by :func:`extract_pose` when its ``cancel`` event is set (the worker is gone)."""


def extract_pose(
    video: str | Path,
    *,
    name: str | None = None,
    pose_python: str | Path | None = None,
    max_seconds: float = MAX_VIDEO_SECONDS,
    skeleton_frames: int = 4,
    progress: ProgressFn | None = None,
    cancel: threading.Event | None = None,
) -> PoseExtraction:
    """MediaPipe Pose landmarks of every frame of a video, with progress and cancellation.

    Args:
        video: the video file (mp4, mov, avi).
        name: the user's file name for messages (default: the path's name).
        pose_python: the pose environment's Python (see :func:`find_pose_python`).
        max_seconds: longest video accepted [s].
        skeleton_frames: how many frames to return with the skeleton drawn (0 for none).
        progress: called with stage ``"pose"``, frames done / total.
        cancel: set it (from another thread) to stop the worker at once; an exception raised by
            ``progress`` (a job's cancellation) stops it too.

    Returns:
        The landmarks and a few skeleton frames.

    Raises:
        RecordingError: no pose environment; the file is missing, not a decodable video, longer
            than ``max_seconds``, or shows no person. Nothing is left behind.
        PoseCancelled: ``cancel`` was set.
    """
    path = Path(video)
    label = name or path.name
    if not path.is_file():
        raise RecordingError("file not found", file=label, expected="an existing video file")
    if not max_seconds > 0:
        raise RecordingError(f"max_seconds is {max_seconds}", expected="a positive duration")
    py = find_pose_python(pose_python)
    with tempfile.TemporaryDirectory(prefix="bioplan-pose-") as tmp:
        worker = _Worker(py, path, Path(tmp), label)
        done = worker.run(max_seconds, skeleton_frames, progress, cancel)
        return _collect(done, label, max(skeleton_frames, 0))


def _worker_command(py: Path, video: Path, out: Path, max_seconds: float, n: int) -> list[str]:
    script = resources.files("app.recordings").joinpath("_pose_worker.py")
    # -I: the script's folder must not shadow the standard library (it holds types.py).
    return [str(py), "-I", str(script), str(video), str(out), repr(max_seconds), str(max(n, 0))]


@dataclass(frozen=True)
class _Worker:
    py: Path
    video: Path
    out: Path
    label: str

    def run(
        self,
        max_seconds: float,
        n_skeletons: int,
        progress: ProgressFn | None,
        cancel: threading.Event | None,
    ) -> dict[str, Any]:
        """Run the worker to its ``done`` event; any other end raises (and kills it)."""
        with (self.out / "worker.log").open("w") as log:
            proc = subprocess.Popen(
                _worker_command(self.py, self.video, self.out, max_seconds, n_skeletons),
                stdout=subprocess.PIPE,
                stderr=log,
                stdin=subprocess.DEVNULL,
                text=True,
            )
            try:
                return self._follow(proc, progress, cancel)
            finally:
                if proc.poll() is None:
                    proc.kill()
                proc.wait()
                if proc.stdout is not None:
                    proc.stdout.close()

    def _follow(
        self,
        proc: subprocess.Popen[str],
        progress: ProgressFn | None,
        cancel: threading.Event | None,
    ) -> dict[str, Any]:
        for event in _events(proc, cancel):
            kind = event.get("event")
            if kind == "progress":
                done, of = int(event["done"]), int(event["of"])
                report(progress, "pose", done, of, message=f"pose: frame {done}/{of}")
            elif kind == "error":
                code = str(event.get("code"))
                raise RecordingError(
                    str(event.get("message")),
                    file=self.label,
                    expected=_EXPECT.get(code, "a video of a person lifting"),
                )
            elif kind == "done":
                return event
        status = proc.wait()
        raise RecordingError(
            f"the pose worker stopped without a result (exit {status}): {_log_tail(self.out)}",
            file=self.label,
            expected="a video that OpenCV can decode",
        )


_EXPECT = {
    "corrupt": "an mp4, mov or avi video that OpenCV can decode",
    "too_long": "a shorter video (cut it, or raise the limit)",
    "no_person": "a video showing a person, arm visible",
    "environment": "a working pose environment ('bioplan pose-env')",
}


def _log_tail(out: Path) -> str:
    try:
        lines = (out / "worker.log").read_text(errors="replace").strip().splitlines()
    except OSError:
        return "no log"
    return lines[-1][:200] if lines else "no log"


def _collect(done: dict[str, Any], label: str, n_skeletons: int) -> PoseExtraction:
    doc_bytes = Path(done["landmarks"]).read_bytes()
    doc = json.loads(doc_bytes)
    fps = float(doc["fps"])
    frames, with_pose = int(done["frames"]), int(done["with_pose"])
    warnings: list[str] = []
    if with_pose < 0.5 * frames:
        warnings.append(f"{label}: a person was detected in only {with_pose} of {frames} frames")
    quality = _frame_quality(doc_bytes)
    warnings += _people_warnings(label, doc.get("persons"), quality)
    candidates = [int(Path(p).stem.split("_")[-1]) for p in done.get("skeletons", [])]
    paths = dict(zip(candidates, done.get("skeletons", []), strict=True))
    skeletons = []
    for k in _pick_skeletons(candidates, quality, n_skeletons):
        person, score = _who(quality, k)
        skeletons.append(
            SkeletonFrame(
                frame=k,
                time=k / fps,
                jpeg=Path(paths[k]).read_bytes(),
                person=person,
                quality=score,
                note=_note(person, score, quality),
            )
        )
    return PoseExtraction(
        source=label,
        landmarks_json=doc_bytes,
        fps=fps,
        image_size=(int(doc["image_width"]), int(doc["image_height"])),
        frames=frames,
        frames_with_pose=with_pose,
        skeletons=skeletons,
        warnings=warnings,
    )


def _frame_quality(doc_bytes: bytes) -> FrameQuality | None:
    """Per-frame quality of the better-seen arm of the extracted landmarks (None if unreadable)."""
    from app.recordings._read import read_bytes

    try:
        rec = read_bytes(doc_bytes, "landmarks.json", format="mediapipe_json")
    except RecordingError as exc:
        # The landmarks are kept; only their per-frame quality (and its warnings) is lost.
        logger.warning("per-frame pose quality not computed: landmarks unreadable: %s", exc)
        return None
    lms = image_landmarks(rec.channels)
    t = next(iter(rec.channels.values())).times
    arms = []
    for side in ("left", "right"):
        try:
            arms.append(arm_quality(lms, t, side))
        except KeyError:
            continue
    if not arms:
        return None
    return max(arms, key=lambda q: float(q.score.mean()))


def _people_warnings(label: str, persons: Any, quality: FrameQuality | None) -> list[str]:
    """The warning when another person was seen or the track jumped to someone else."""
    another: list[int] = []
    checked = 0
    if isinstance(persons, dict):
        another = [int(k) for k in persons.get("another", [])]
        checked = len(persons.get("checked", []))
    switched = quality is not None and quality.n_persons > 1
    if not another and not switched:
        return []
    tracked = (
        frame_ranges(np.flatnonzero(quality.person == 0)) if quality is not None else "unknown"
    )
    if another:
        head = (
            f"{label}: 2 people detected (another person in {len(another)} of {checked} frames"
            " checked)"
        )
    else:
        head = (
            f"{label}: the pose track jumps between {quality.n_persons if quality else 2} persons"
        )
    return [
        f"{head}; the tracked person is shown in frames {tracked}; lifts in other frames are"
        " flagged as low pose quality and left out of the template"
    ]


def _pick_skeletons(candidates: list[int], quality: FrameQuality | None, n: int) -> list[int]:
    """``n`` of the candidate frames: the tracked person well seen first, spread over time."""
    if n <= 0 or not candidates:
        return []
    if quality is None:
        idx = np.unique(np.round(np.linspace(0, len(candidates) - 1, n)).astype(int))
        return [candidates[i] for i in idx]
    # Good: the frame and its neighbours (SKELETON_CONTEXT frames each way) are of good
    # quality, so a frame that merely flickers good amid a drifting track is not shown.
    low = quality.low
    good = [
        k
        for k in candidates
        if k < len(low) and not low[max(0, k - SKELETON_CONTEXT) : k + SKELETON_CONTEXT + 1].any()
    ]
    if len(good) >= n:
        idx = np.unique(np.round(np.linspace(0, len(good) - 1, n)).astype(int))
        return [good[i] for i in idx]
    rest = sorted(
        (k for k in candidates if k not in good),
        key=lambda k: -float(quality.score[k]) if k < len(quality.score) else 0.0,
    )
    return sorted(good + rest[: n - len(good)])


def _who(quality: FrameQuality | None, k: int) -> tuple[int, float]:
    if quality is None or k >= len(quality.person):
        return -1, math.nan
    return int(quality.person[k]), float(quality.score[k])


def _note(person: int, score: float, quality: FrameQuality | None) -> str:
    if person < 0:
        return "person unknown"
    if person > 0:
        return f"not the tracked person (the track jumped to someone or something else, #{person})"
    if quality is not None and score < quality.min_visibility:
        return "the tracked person, but the arm is poorly detected here (low quality)"
    return "the tracked person"


def save_skeletons(extraction: PoseExtraction, folder: str | Path) -> list[Path]:
    """Write the skeleton frames as ``<video stem>_frame<k>.jpg`` into ``folder``."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    stem = Path(extraction.source).stem
    paths: list[Path] = []
    for s in extraction.skeletons:
        p = out / f"{stem}_frame{s.frame:05d}.jpg"
        p.write_bytes(s.jpeg)
        paths.append(p)
    return paths
