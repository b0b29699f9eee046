"""Recording jobs: parse an upload, analyse a session, turn a video into pose landmarks.

The science packages are imported inside the functions, so the API process, which parses
uploads through :func:`parse_recording`, starts without them.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from app.jobs.tasks.types import AnalysisPayload, JobResult, PosePayload, UploadedFile
from app.jsonsafe import json_safe
from app.progress import ProgressFn, no_progress, report

if TYPE_CHECKING:
    from app.recordings import PoseExtraction, Recording, SkeletonFrame


class ParsedRecording(TypedDict):
    """One uploaded recording file as plain data (:func:`parse_recording`)."""

    format: str
    metadata: dict[str, object]
    #: ``{"name", "kind", "unit", "rate", "start", "site", "data", "confidence", "time"}``
    channels: list[dict[str, object]]


def parse_recording(
    data: bytes,
    filename: str,
    options: dict[str, Any],
    sidecars: dict[str, bytes] | None = None,
) -> ParsedRecording:
    """Read one uploaded file into plain data (run inline by the upload route).

    Args:
        data: the file's bytes.
        filename: the user's file name (used for format detection and error messages).
        options: reader overrides ``rate, emg_rate, muscle_map, image_size, frame_rate, format``.
        sidecars: file name -> bytes of the files uploaded beside it that belong to it (BIDS
            ``_channels.tsv`` / ``_emg.json`` of an EDF).

    Returns:
        ``{"format", "metadata", "channels": [{"name", "kind", "unit", "rate", "start",
        "site", "data" ((N,) or (N, 3) float64), "confidence", "time"}]}``.

    Raises:
        app.recordings.types.RecordingError: the file cannot be read (message names the file).
    """
    from app.recordings import read_bytes

    kwargs = {k: v for k, v in options.items() if v is not None}
    if kwargs.get("image_size") is not None:
        kwargs["image_size"] = tuple(kwargs["image_size"])
    rec = read_bytes(data, filename, sidecars=sidecars or None, **kwargs)
    channels = []
    for ch in rec.channels.values():
        channels.append(
            {
                "name": ch.name,
                "kind": ch.kind,
                "unit": ch.unit,
                "rate": float(ch.rate),
                "start": float(ch.start),
                "site": ch.site,
                "data": np.asarray(ch.data, dtype=np.float64),
                "confidence": None if ch.confidence is None else np.asarray(ch.confidence),
                "time": None if ch.time is None else np.asarray(ch.time),
            }
        )
    return {"format": rec.format, "metadata": json_safe(rec.metadata), "channels": channels}


def read_upload(f: UploadedFile, read_options: Mapping[str, Any]) -> Recording:
    """One file of an analysis payload as a Recording, with the warnings stored beside it
    (e.g. what the pose extraction of its video said) in front of the reader's."""
    from app.recordings import read_bytes

    options = {k: v for k, v in f.get("read_options", read_options).items() if v is not None}
    if options.get("image_size") is not None:
        options["image_size"] = tuple(options["image_size"])
    rec = read_bytes(f["data"], f["name"], sidecars=f.get("sidecars") or None, **options)
    extra = [str(w) for w in f.get("warnings", ())]
    if extra:
        rec.metadata["warnings"] = extra + list(rec.metadata.get("warnings", []))
    return rec


def _analysis_options(payload: AnalysisPayload) -> dict[str, Any]:
    """Keyword options of ``analyze_recordings`` from an analysis payload."""
    options = {k: v for k, v in payload.get("options", {}).items() if v is not None}
    if "phase_bounds_deg" in options:
        options["phase_bounds_deg"] = tuple(options["phase_bounds_deg"])
    side = options.pop("side", None)
    if side not in (None, "auto"):
        options["pose_options"] = {**options.get("pose_options", {}), "side": side}
    landmarks = options.pop("landmarks", None)
    if landmarks:
        options["pose_options"] = {**options.get("pose_options", {}), "landmarks": landmarks}
    return options


def analyse(payload: AnalysisPayload, progress: ProgressFn = no_progress) -> JobResult:
    """Analyse the files of one recording session.

    Payload: ``files`` [{"name", "data": bytes, "sidecars" {name: bytes}, "read_options"
    (reader overrides of this file; default the payload's ``read_options``), "warnings"}],
    ``options``: those of ``analyze_recordings`` (``emg_rate, muscle_map, exclude_channels,
    phase_bounds_deg, body_mass, body_height, load_mass, together, offset``) and ``side``
    (``auto``, ``left``, ``right``); ``echo``: more settings to echo in the result (the
    reader options the files were read with).

    Returns:
        ``{"result": AnalysisResult.to_dict(), "template": HumanTemplate.to_dict(), "arrays":
        AnalysisOverlays.to_arrays()}``: the overlays are what the recording detail page
        plots, decimated here once so the page never runs the analysis itself.
    """
    from app.analysis import AnalysisOverlays, analyze_recordings

    files = payload["files"]
    read_options = dict(payload.get("read_options", {}))
    recordings = []
    for i, f in enumerate(files):
        report(progress, "read", i, len(files), fraction=0.4 * i / max(len(files), 1),
               message=f"reading {f['name']}")  # fmt: skip
        recordings.append(read_upload(f, read_options))
    report(progress, "analyse", 0, 1, fraction=0.4, message="analysing")
    result = analyze_recordings(recordings, **_analysis_options(payload))
    result.settings.update(payload.get("echo", {}))
    report(progress, "analyse", 1, 1, fraction=0.95, message="decimating the plot overlays")
    overlays = AnalysisOverlays.from_result(result)
    report(progress, "done", 1, 1, message="analysed")
    return {
        "result": json_safe(result.to_dict()),
        "template": result.template.to_dict(),
        "arrays": overlays.to_arrays(),
    }


class _Terminated(Exception):
    """SIGTERM arrived (the job was cancelled): unwind, so temporary files go and the pose
    worker is killed, instead of dying on the spot."""


@contextmanager
def _unwind_on_sigterm() -> Iterator[None]:
    """Turn SIGTERM into :class:`_Terminated` while the block runs (main thread only)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: FrameType | None) -> None:
        raise _Terminated(f"terminated by signal {signum}")

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _pid_alive(pid: int) -> bool:
    import os

    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process holds that pid now
        return True
    return True


def _scratch(scratch_dir: str | None) -> str | None:
    """The folder for this job's temporary copy of the video (created), after removing what
    jobs killed outright (a server crash: SIGKILL, no unwinding) left there.

    Each job's folder is named ``pose-<pid>-...``: a folder whose process is gone is stale.
    """
    if scratch_dir is None:
        return None
    import re
    import shutil

    folder = Path(scratch_dir)
    folder.mkdir(parents=True, exist_ok=True)
    for entry in folder.glob("pose-*"):
        m = re.match(r"pose-(\d+)-", entry.name)
        if m and not _pid_alive(int(m.group(1))):
            shutil.rmtree(entry, ignore_errors=True)
    return str(folder)


def extract_pose_job(payload: PosePayload, progress: ProgressFn = no_progress) -> JobResult:
    """Pose landmarks of an uploaded video (``app.recordings.extract_pose``), read back as a
    MediaPipe file.

    Payload: ``name`` (the user's file name), ``data`` (the video's bytes), ``max_seconds``,
    ``skeleton_frames``, ``scratch_dir`` (folder for the temporary copy; None: the system's).

    Progress: stage ``pose``, frames done of the video's frames; then ``read``.

    Returns:
        ``{"result": {"source", "fps", "image_size", "frames", "frames_with_pose",
        "warnings", "skeleton_frames", "skeletons": [{"frame", "time", "person", "quality",
        "note"}]}, "landmarks": {"name", "data", "format", "metadata", "channels"} (a parsed
        file, as the upload stores it), "skeletons": [{"frame", "time", "person", "quality",
        "note", "jpeg"}]}``.

    Raises:
        RecordingError: no pose environment, a corrupt video, one longer than ``max_seconds``,
            or one without a person; nothing is left behind.
    """
    import os

    from app.recordings import extract_pose

    name = str(payload["name"])
    suffix = Path(name).suffix.lower()
    suffix = suffix if suffix in (".mp4", ".mov", ".avi", ".m4v") else ".mp4"
    scratch = _scratch(payload.get("scratch_dir"))
    with (
        _unwind_on_sigterm(),
        tempfile.TemporaryDirectory(prefix=f"pose-{os.getpid()}-", dir=scratch) as tmp,
    ):
        video = Path(tmp) / f"video{suffix}"  # a fixed name: the user's is never a path
        video.write_bytes(payload["data"])
        extraction = extract_pose(
            video,
            name=name,
            max_seconds=float(payload["max_seconds"]),
            skeleton_frames=int(payload.get("skeleton_frames", 4)),
            progress=progress,
        )
    report(progress, "read", 0, 1, fraction=0.97, message="reading the landmarks")
    return _pose_output(extraction)


def _pose_output(extraction: PoseExtraction) -> JobResult:
    """The plain-data result of :func:`extract_pose_job`."""
    parsed = parse_recording(
        extraction.landmarks_json, extraction.landmarks_name, {"format": "mediapipe_json"}
    )
    summary = {
        "source": extraction.source,
        "fps": extraction.fps,
        "image_size": list(extraction.image_size),
        "frames": extraction.frames,
        "frames_with_pose": extraction.frames_with_pose,
        "warnings": list(extraction.warnings),
        "skeleton_frames": len(extraction.skeletons),
        # whom each skeleton frame shows: the stored frames keep only the image, and the page
        # must say when a skeleton is drawn on someone (or something) else
        "skeletons": [_skeleton_label(s) for s in extraction.skeletons],
    }
    metadata = dict(parsed["metadata"])
    metadata["video"] = {k: summary[k] for k in ("source", "frames", "frames_with_pose")}
    metadata["pose_warnings"] = list(extraction.warnings)
    earlier = metadata.get("warnings")
    metadata["warnings"] = list(extraction.warnings) + (
        earlier if isinstance(earlier, list) else []
    )
    return {
        "result": json_safe(summary),
        "landmarks": {
            "name": extraction.landmarks_name,
            "data": extraction.landmarks_json,
            "format": parsed["format"],
            "metadata": metadata,
            "channels": parsed["channels"],
        },
        "skeletons": [{**_skeleton_label(s), "jpeg": s.jpeg} for s in extraction.skeletons],
    }


def _skeleton_label(s: SkeletonFrame) -> dict[str, object]:
    """A skeleton frame's index, time [s] and whom it shows (``app.recordings.SkeletonFrame``:
    person 0 = the tracked person, >0 another, -1 unknown; quality 0-1 or None; note)."""
    quality = float(s.quality)
    return {
        "frame": int(s.frame),
        "time": float(s.time),
        "person": int(s.person),
        "quality": quality if quality == quality else None,  # NaN: unknown
        "note": str(s.note),
    }
