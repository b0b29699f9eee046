"""Recordings in the service: uploads (recordings, BIDS sidecars, videos), changes after upload,
and the inputs and outputs of their analysis and pose-extraction jobs.

Every uploaded file is read by :func:`parse_upload` (the one place where untrusted bytes are
parsed in the API process; the security layer runs it in a sandbox). What an upload stores is
all of its files or none:

- a **recording** is read with the session's reader options and stored with its channels;
- a **sidecar** (BIDS ``<stem>_channels.tsv`` / ``<stem>_emg.json`` sent beside
  ``<stem>_emg.edf``) is given to its EDF's reader and stored as that file's child, never read
  on its own;
- a **video** (mp4, mov, avi) has its container checked (readable, video track, stated duration
  within ``max_video_seconds``) and is stored; a pose job then adds its landmarks (a MediaPipe
  JSON file, child of the video) and skeleton frames in one transaction when it succeeds.

A session's muscle map may name channels of several files: each file gets the entries naming
its own channels, and an entry naming no channel of any file is refused.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db import crud
from app.db.blobs import BlobStore
from app.db.models import (
    Analysis,
    JobRecord,
    PoseExtraction,
    RecordingFile,
    RecordingSession,
    SkeletonFrame,
)
from app.errors import BioPlanError
from app.jobs.tasks import parse_recording
from app.names import MAX_VIDEO_SECONDS, SKELETON_FRAMES
from app.recordings.video import find_pose_python
from app.services.errors import (
    ConflictError,
    NotFoundError,
    ParseLimitError,
    ServiceError,
    found,
)
from app.services.sandbox import read_untrusted

#: Options the readers take (stored with the session; a change reads the files again).
READER_OPTIONS = ("rate", "emg_rate", "muscle_map", "image_size", "frame_rate", "format")
#: Options of the session's analysis stored with it (``PATCH``).
ANALYSIS_DEFAULTS = ("exclude_channels",)
#: Analysis options that come from the recording unless a request gives them.
RECORDING_LEVEL = ("emg_rate", "muscle_map", "exclude_channels", "together")
#: BIDS sidecars of ``<stem>_emg.edf``: ``<stem>_channels.tsv`` and ``<stem>_emg.json``.
BIDS_SIDECARS = ("_channels.tsv", "_emg.json")
_EDF_SUFFIXES = ("_emg.edf", "_emg.bdf", ".edf", ".bdf")
_VIDEO_SUFFIXES = (".mp4", ".mov", ".avi", ".m4v")
_UNIT_IN_LABEL = re.compile(r"^(?P<name>.*?)\s*[\(\[][^\)\]]*[\)\]]\s*$")


# ------------------------------------------------------------------------------------ parsing


def is_video_upload(name: str, data: bytes) -> bool:
    """Whether an uploaded file is a video (by its name's extension or its first bytes)."""
    from app.recordings import looks_like_video

    return Path(name).suffix.lower() in _VIDEO_SUFFIXES or looks_like_video(data[:16])


def parse_upload(
    name: str,
    data: bytes,
    options: dict[str, object],
    sidecars: dict[str, bytes] | None = None,
) -> crud.ParsedFile:
    """Read one uploaded file (format detected from its content).

    Args:
        name: the user's file name (a base name; kept as metadata only).
        data: its bytes.
        options: reader overrides (``rate, emg_rate, muscle_map, image_size, frame_rate,
            format``), None values left out; videos take none.
        sidecars: file name -> bytes of its sidecars uploaded beside it (BIDS).

    Returns:
        The parsed file; a video has no channels and its container's description in
        ``metadata["video"]`` (``app.recordings.VideoProbe.to_dict``), role ``video``.

    Raises:
        ServiceError: the file is empty, unreadable or has no channels (``file`` names it).
    """
    if not data:
        raise ServiceError(f"{name}: the file is empty", file=name)
    try:
        if is_video_upload(name, data):
            from app.recordings import probe_video

            probe = probe_video(data, name)
            return crud.ParsedFile(
                name=name,
                data=data,
                format="video",
                metadata={"video": probe.to_dict(), "warnings": []},
                role="video",
            )
        out = read_untrusted(parse_recording, data, name, options, sidecars, what=name)
    except ParseLimitError:
        raise  # a 413 naming the limit
    except BioPlanError as exc:  # RecordingError: bad input, named
        text = str(exc)
        raise ServiceError(text if name in text else f"{name}: {text}", file=name) from None
    if not out["channels"]:
        raise ServiceError(f"{name}: no channels found", file=name)
    return crud.ParsedFile(
        name=name,
        data=data,
        format=out["format"],
        metadata=out["metadata"],
        channels=out["channels"],
    )


@dataclass
class Upload:
    """One uploaded file and what it is to the session.

    Attributes:
        name, data: the user's base name and the bytes.
        role: ``recording``, ``sidecar`` or ``video``.
        parent: index of the file a sidecar belongs to.
        sidecars: name -> bytes of a recording's sidecars.
    """

    name: str
    data: bytes
    role: str = "recording"
    parent: int | None = None
    sidecars: dict[str, bytes] = field(default_factory=dict)


def bids_stem(name: str) -> str | None:
    """``sub-01_task-x`` of ``sub-01_task-x_emg.edf`` (None for a file that is no EDF/BDF)."""
    low = name.lower()
    for suffix in _EDF_SUFFIXES:
        if low.endswith(suffix):
            return name[: -len(suffix)]
    return None


def classify_uploads(files: Sequence[tuple[str, bytes]]) -> list[Upload]:
    """Sort an upload's files into recordings, videos and the EDF files' BIDS sidecars.

    Raises:
        ServiceError: a file named like a BIDS sidecar whose EDF is not in the upload, or two
            files of the same name.
    """
    uploads = [Upload(name, data) for name, data in files]
    names = [u.name.lower() for u in uploads]
    for i, low in enumerate(names):
        if low in names[:i]:
            raise ServiceError(f"{uploads[i].name}: uploaded twice", file=uploads[i].name)
    owners = {}
    for i, u in enumerate(uploads):
        stem = bids_stem(u.name)
        for suffix in BIDS_SIDECARS if stem is not None else ():
            owners[f"{stem}{suffix}".lower()] = i
    for u in uploads:
        low = u.name.lower()
        if low in owners:
            u.role, u.parent = "sidecar", owners[low]
            uploads[owners[low]].sidecars[u.name] = u.data
        elif low.endswith(BIDS_SIDECARS):
            edf = re.sub(r"(_channels\.tsv|_emg\.json)$", "_emg.edf", u.name, flags=re.I)
            raise ServiceError(
                f"{u.name} is a BIDS sidecar, but its EDF ({edf}) is not in the upload: send"
                " them together",
                file=u.name,
            )
        elif is_video_upload(u.name, u.data):
            u.role = "video"
    return uploads


def label_matches(label: str, channel: str) -> bool:
    """Whether a muscle-map label names a channel as the readers match it: exactly, ignoring
    case, or without a bracketed unit (``"Biceps (uV)"`` names ``Biceps``)."""
    name = channel.strip().lower()
    low = label.strip().lower()
    m = _UNIT_IN_LABEL.match(label)
    return name in (low, (m.group("name").strip().lower() if m else low))


def map_for(muscle_map: Mapping[str, str] | None, channels: Iterable[str]) -> dict[str, str]:
    """The entries of ``muscle_map`` that name one of ``channels``."""
    names = list(channels)
    return {k: v for k, v in (muscle_map or {}).items() if any(label_matches(k, n) for n in names)}


def _check_map_used(
    muscle_map: Mapping[str, str] | None, channels: Iterable[str], *, field: str = "muscle_map"
) -> None:
    names = sorted(set(channels))
    unknown = [k for k in muscle_map or {} if not any(label_matches(k, n) for n in names)]
    if unknown:
        shown = ", ".join(repr(n) for n in names[:20]) + (" ..." if len(names) > 20 else "")
        raise ServiceError(
            f"{field} names channel {unknown[0]!r}, which no file of the recording has"
            f" (channels: {shown})",
            field=field,
        )


def _parse_recording_file(u: Upload, options: dict[str, Any], shared: bool) -> crud.ParsedFile:
    """A recording file with the session's options; in a session of several files, with only
    the muscle-map entries naming its own channels."""
    muscle_map = options.get("muscle_map")
    if not (shared and muscle_map):
        return parse_upload(u.name, u.data, options, u.sidecars)
    try:
        return parse_upload(u.name, u.data, options, u.sidecars)
    except ServiceError:
        # The map names channels of other files too: learn this file's, keep its entries.
        plain = {k: v for k, v in options.items() if k != "muscle_map"}
        names = [c["name"] for c in parse_upload(u.name, u.data, plain, u.sidecars).channels]
        mine = map_for(muscle_map, names)
        return parse_upload(u.name, u.data, {**plain, "muscle_map": mine or None}, u.sidecars)


def parse_session(
    uploads: Sequence[Upload], options: dict[str, Any], *, max_video_seconds: float
) -> list[crud.ParsedFile]:
    """Read every file of an upload (sidecars go with their EDF; videos are probed).

    Raises:
        ServiceError: a file cannot be read, a video is longer than ``max_video_seconds``, or
            the muscle map names a channel no file has.
    """
    recordings = [u for u in uploads if u.role == "recording"]
    parsed: list[crud.ParsedFile] = []
    refused: list[ServiceError] = []
    for u in uploads:
        try:
            p = _parse_one(u, options, len(recordings) > 1, max_video_seconds)
        except ParseLimitError:
            raise  # the server's limit: the other files are not worth reading now
        except ServiceError as exc:
            if exc.file is None:  # not about this file (a muscle map entry): as it is
                raise
            refused.append(exc)  # every unreadable file is named, not only the first
            continue
        p.parent = u.parent
        parsed.append(p)
    if refused:
        raise UnreadableFiles(refused)
    if len(recordings) > 1:
        _check_map_used(options.get("muscle_map"), (c["name"] for p in parsed for c in p.channels))
    return parsed


def _parse_one(
    u: Upload, options: dict[str, object], shared: bool, max_video_seconds: float
) -> crud.ParsedFile:
    if u.role == "sidecar":
        return crud.ParsedFile(name=u.name, data=u.data, format="bids_sidecar", role="sidecar")
    if u.role == "video":
        p = parse_upload(u.name, u.data, {})
        _check_duration(p, max_video_seconds)
        return p
    return _parse_recording_file(u, options, shared)


class UnreadableFiles(ServiceError):
    """Files of one upload that cannot be read: every one named, with its own message.

    Attributes:
        files: ``[{"file": name, "detail": message}]`` in upload order.
    """

    def __init__(self, refused: Sequence[ServiceError]) -> None:
        first = refused[0]
        text = "; ".join(str(e) for e in refused)
        super().__init__(text, file=first.file, field=first.field)
        self.files = [{"file": e.file, "detail": str(e)} for e in refused]


def _check_duration(p: crud.ParsedFile, limit: float) -> None:
    seconds = p.metadata["video"].get("duration_s")
    if seconds is not None and seconds > limit:
        raise ServiceError(
            f"{p.name}: the video lasts {seconds:.1f} s, longer than this server's limit of"
            f" {limit:g} s (BIOPLAN_MAX_VIDEO_SECONDS); cut it, or raise the limit",
            file=p.name,
        )


def store_recording(
    *,
    session: Session,
    blobs: BlobStore,
    files: Sequence[tuple[str, bytes]],
    meta: Mapping[str, object],
    options: Mapping[str, object],
    session_mode: str = "separate",
    max_video_seconds: float = MAX_VIDEO_SECONDS,
) -> RecordingSession:
    """Parse every file, then store the session in one transaction (all files or none).

    Args:
        files: (base name, bytes) of each uploaded file.
        meta: ``subject, task, load_kg, notes``.
        options: reader overrides, stored with the session so an analysis rereads the raw
            bytes the same way.
        session_mode: ``separate`` trials or recorded ``together``.
        max_video_seconds: longest video accepted [s].

    Returns:
        The stored session with its files and channels loaded.

    Raises:
        ServiceError: no file, or one of them cannot be read (nothing is stored).
    """
    if not files:
        raise ServiceError("at least one file is required", field="files")
    uploads = classify_uploads(files)
    if not any(u.role in ("recording", "video") for u in uploads):
        raise ServiceError("the upload holds sidecars only: send the recordings", field="files")
    parsed = parse_session(uploads, dict(options), max_video_seconds=max_video_seconds)
    named, stored = _condition_from_names(uploads, dict(meta), dict(options))
    rec = crud.create_recording(
        session=session,
        blobs=blobs,
        meta={**named, "options": stored, "session_mode": session_mode},
        files=parsed,
    )
    return _loaded(session, rec.id)


def _condition_from_names(
    uploads: Sequence[Upload], meta: dict[str, object], options: dict[str, object]
) -> tuple[dict[str, object], dict[str, object]]:
    """The condition named by the files (``app.recordings.CONDITION_RULE``) when the user gave
    none; where it came from is kept in ``options["condition_from"]`` for the page."""
    if meta.get("condition"):
        return meta, options
    from app.recordings import condition_from_files

    found = condition_from_files(
        [u.name for u in uploads if u.role in ("recording", "video")],
        {name: data for u in uploads for name, data in u.sidecars.items()},
    )
    if found is None:
        return meta, options
    condition, where = found
    return {**meta, "condition": condition}, {**options, "condition_from": where}


def _loaded(session: Session, recording_id: int) -> RecordingSession:
    loaded = crud.get_recording(session=session, recording_id=recording_id)
    if loaded is None:  # pragma: no cover - deleted between two statements of this request
        raise NotFoundError(f"recording {recording_id} was deleted meanwhile")
    return loaded


# ------------------------------------------------------------------------------ stored files


def is_pose_file(f: RecordingFile) -> bool:
    """A landmarks file extracted from a video of the session."""
    return f.role == "recording" and f.parent is not None and f.parent.role == "video"


def file_read_options(f: RecordingFile, options: Mapping[str, Any]) -> dict[str, object]:
    """Reader options of one stored recording file: the session's (muscle map entries naming
    its channels only); a video's landmarks are MediaPipe JSON that states its own timing."""
    if is_pose_file(f):
        return {"format": "mediapipe_json"}
    out = {k: options[k] for k in READER_OPTIONS if options.get(k) is not None}
    if out.get("muscle_map"):
        out["muscle_map"] = map_for(out["muscle_map"], (c.name for c in f.channels)) or None
    return {k: v for k, v in out.items() if v is not None}


def sidecars_of(
    f: RecordingFile, files: Sequence[RecordingFile], blobs: BlobStore
) -> dict[str, bytes]:
    return {
        s.original_name: blobs.get(s.sha256)
        for s in files
        if s.role == "sidecar" and s.parent_id == f.id
    }


def channel_names(rec: RecordingSession) -> list[str]:
    """Names of the channels of the session's recording files."""
    return [c.name for f in rec.files if f.role == "recording" for c in f.channels]


def _check_excluded(rec: RecordingSession, names: Sequence[str] | None) -> None:
    known = {n.lower() for n in channel_names(rec)}
    unknown = [n for n in names or () if n.strip().lower() not in known]
    if unknown:
        raise ServiceError(
            f"exclude_channels names {unknown[0]!r}, which no file of recording {rec.id} has",
            field="exclude_channels",
        )


def get_recording(session: Session, recording_id: int) -> RecordingSession:
    """A recording with its files and channel metadata.

    Raises:
        NotFoundError: no such recording.
    """
    return found(
        crud.get_recording(session=session, recording_id=recording_id), f"recording {recording_id}"
    )


# ----------------------------------------------------------------------------------- changes


_META_FIELDS = ("subject", "task", "notes", "load_kg", "label", "condition")


def update_recording(
    *, session: Session, blobs: BlobStore, recording_id: int, changes: dict[str, Any]
) -> RecordingSession:
    """Change a stored recording (``PATCH``): metadata, session mode, reader options and
    excluded channels. Changed reader options read every recording file again from its stored
    bytes; the new channels replace the old in one transaction, or nothing changes.

    Args:
        changes: the fields the request sets (absent: unchanged; None clears an option):
            ``subject, task, notes, load_kg, label, condition, session`` and the keys of
            ``READER_OPTIONS`` and ``ANALYSIS_DEFAULTS``.

    Raises:
        NotFoundError: no such recording.
        ServiceError: a file cannot be read with the new options, an excluded channel or a
            mapped label that no file has.
    """
    rec = get_recording(session, recording_id)
    options = dict(rec.options)
    for key in (*READER_OPTIONS, *ANALYSIS_DEFAULTS):
        if key in changes:
            if changes[key] is None:
                options.pop(key, None)
            else:
                options[key] = list(changes[key]) if key == "image_size" else changes[key]
    _check_excluded(rec, options.get("exclude_channels"))
    reread = any(key in changes for key in READER_OPTIONS)
    reparsed = _reparse(rec, options, blobs) if reread else {}
    if "condition" in changes:  # the user's own now, not the file names'
        options.pop("condition_from", None)
    values: dict[str, object] = {k: changes[k] for k in _META_FIELDS if k in changes}
    if changes.get("session") is not None:
        values["session_mode"] = changes["session"]
    values["options"] = options
    updated = crud.update_recording(
        session=session, recording_id=recording_id, values=values, reparsed=reparsed
    )
    if updated is None:  # pragma: no cover - deleted during this request
        raise NotFoundError(f"recording {recording_id} was deleted meanwhile")
    return updated


def _reparse(
    rec: RecordingSession, options: dict[str, Any], blobs: BlobStore
) -> dict[int, crud.ParsedFile]:
    """Every recording file read again from its bytes with ``options`` (file id -> parsed)."""
    out: dict[int, crud.ParsedFile] = {}
    for f in rec.files:
        if f.role != "recording":
            continue
        read = file_read_options(f, options)
        out[f.id] = parse_upload(
            f.original_name, blobs.get(f.sha256), read, sidecars_of(f, rec.files, blobs)
        )
    _check_map_used(
        options.get("muscle_map"), (c["name"] for p in out.values() for c in p.channels)
    )
    return out


# ---------------------------------------------------------------------------------- analyses


def _active_pose_job(session: Session, rec: RecordingSession) -> JobRecord | None:
    jobs = crud.pose_jobs(session=session, recording_id=rec.id)
    return next((j for j in jobs.values() if j.state in ("queued", "running")), None)


def analysis_params(session: Session, request: dict[str, Any]) -> dict[str, Any]:
    """The options an analysis runs with: the request's, the recording's where the request
    leaves them out (``emg_rate, muscle_map, exclude_channels, together, load_mass``).

    Raises:
        NotFoundError: no such recording (``recording_id``).
        ServiceError: an excluded channel it lacks.
        ConflictError: its video is still being turned into pose (``job``: that pose job), or
            it has nothing to analyse (its only video's pose extraction failed).
    """
    from app.services.job_views import job_to_dict

    rid = request["recording_id"]
    rec = crud.get_recording(session=session, recording_id=rid)
    if rec is None:
        raise NotFoundError(f"recording {rid} does not exist", field="recording_id")
    pending = _active_pose_job(session, rec)
    if pending is not None:
        raise ConflictError(
            f"recording {rid}'s video is being turned into pose (job {pending.id},"
            f" {pending.state}); its analysis starts when that job succeeds",
            job=job_to_dict(pending),
        )
    if not any(f.role == "recording" for f in rec.files):
        raise ConflictError(
            f"recording {rid} has nothing to analyse: its video has no pose landmarks (start"
            f" the extraction again with POST /api/recordings/{rid}/pose)"
        )
    params = dict(request)
    stored = rec.options
    for key in ("emg_rate", "muscle_map", "exclude_channels"):
        if params.get(key) is None:
            params[key] = stored.get(key)
    if params.get("together") is None:
        params["together"] = rec.session_mode == "together"
    if params.get("load_mass") is None:
        params["load_mass"] = rec.load_kg
    _check_excluded(rec, params.get("exclude_channels"))
    return params


def rerun_params(session: Session, recording_id: int) -> dict[str, object]:
    """Options to analyse a recording again after a change: those of its newest analysis,
    except the ones the recording itself holds (taken as they are now)."""
    newest = session.scalars(
        select(JobRecord)
        .join(Analysis, Analysis.id == JobRecord.id)
        .where(Analysis.recording_id == recording_id)
        .order_by(JobRecord.id.desc())
        .limit(1)
    ).first()
    previous = {} if newest is None else dict(newest.params)
    for key in (*RECORDING_LEVEL, "load_mass"):
        previous.pop(key, None)
    return analysis_params(session, {**previous, "recording_id": recording_id})


def analysis_payload(session: Session, blobs: BlobStore, params: dict[str, Any]) -> dict[str, Any]:
    """An analysis job's input: the recording's files (bytes, sidecars, reader options) and
    the options of ``analyze_recordings`` (see ``app.jobs.tasks.analyse``).

    Raises:
        NotFoundError: the recording was deleted.
    """
    rec = crud.get_recording(session=session, recording_id=params["recording_id"])
    if rec is None:
        raise NotFoundError(f"recording {params['recording_id']} no longer exists")
    options = dict(rec.options)
    for key in ("emg_rate", "muscle_map"):
        options[key] = params.get(key)
    files = []
    for f in rec.files:
        if f.role != "recording":
            continue
        read = file_read_options(f, options)
        files.append(
            {
                "name": f.original_name,
                "data": blobs.get(f.sha256),
                "sidecars": sidecars_of(f, rec.files, blobs),
                "read_options": read,
                "warnings": list(f.file_metadata.get("pose_warnings", [])),
            }
        )
    keys = ("emg_rate", "muscle_map", "exclude_channels", "phase_bounds_deg", "body_mass",
            "body_height", "load_mass", "together", "offset", "side", "landmarks",
            "keep_low_quality_lifts")  # fmt: skip
    size = options.get("image_size")
    echo = {
        "rate_hz": options.get("rate"),
        "frame_rate_hz": options.get("frame_rate"),
        "image_size_px": list(size) if size else None,
        "format": options.get("format"),
        "side": params.get("side") or "auto",
    }
    return {"files": files, "options": {k: params.get(k) for k in keys}, "echo": echo}


# -------------------------------------------------------------------------------------- pose


def videos_without_pose(rec: RecordingSession) -> list[RecordingFile]:
    """The session's videos that have no landmarks file yet."""
    parents = {f.parent_id for f in rec.files if f.role == "recording"}
    return [f for f in rec.files if f.role == "video" and f.id not in parents]


def pose_payload(
    session: Session,
    blobs: BlobStore,
    params: dict[str, object],
    *,
    max_seconds: float,
    scratch_dir: str | None,
) -> dict[str, object]:
    """A pose job's input (``app.jobs.tasks.extract_pose_job``).

    Raises:
        NotFoundError: the video (or its recording) was deleted.
    """
    f = session.get(RecordingFile, params["video_file_id"])
    if f is None or f.role != "video" or f.session_id != params["recording_id"]:
        raise NotFoundError(
            f"video {params['video_file_id']} of recording {params['recording_id']} no longer"
            " exists"
        )
    return {
        "name": f.original_name,
        "data": blobs.get(f.sha256),
        "max_seconds": max_seconds,
        "skeleton_frames": SKELETON_FRAMES,
        "scratch_dir": scratch_dir,
    }


def skeleton_frame_list(session: Session, recording_id: int) -> list[dict[str, object]]:
    """The recording's skeleton frames (``GET /api/recordings/{id}/frames``), each with whom it
    shows as its pose extraction decided (person 0 = the tracked person, >0 someone or
    something else, -1 unknown; quality 0-1; note in words), None where the extraction
    predates these labels."""
    jobs = crud.pose_jobs(session=session, recording_id=recording_id)
    labels: dict[tuple[int, int], dict[str, object]] = {}
    for file_id, job in jobs.items():
        row = session.get(PoseExtraction, job.id)
        for s in ((row.result or {}).get("skeletons") or []) if row is not None else []:
            labels[(file_id, int(s["frame"]))] = s
    out = []
    for k, (frame, video) in enumerate(
        crud.skeleton_frames(session=session, recording_id=recording_id)
    ):
        label = labels.get((frame.file_id, frame.frame), {})
        out.append(
            {
                "k": k,
                "file_id": frame.file_id,
                "video": video,
                "frame": frame.frame,
                "time_s": frame.time,
                "url": f"/api/recordings/{recording_id}/frames/{k}.jpg",
                "person": label.get("person"),
                "quality": label.get("quality"),
                "note": label.get("note"),
            }
        )
    return out


def store_pose(session: Session, blobs: BlobStore, job_id: int, output: dict[str, Any]) -> bool:
    """Store a pose job's output (landmarks file, skeleton frames, result) and mark the job
    succeeded, all in one transaction.

    Returns:
        False when nothing was stored (the job was cancelled, or the video deleted, meanwhile).
    """
    lm = output["landmarks"]
    landmarks = crud.ParsedFile(
        name=str(lm["name"]),
        data=lm["data"],
        format=str(lm["format"]),
        metadata=lm["metadata"],
        channels=lm["channels"],
    )
    frames = [
        crud.SkeletonImage(frame=int(s["frame"]), time=float(s["time"]), jpeg=s["jpeg"])
        for s in output.get("skeletons", [])
    ]
    stored = crud.store_pose_result(
        session=session,
        blobs=blobs,
        job_id=job_id,
        landmarks=landmarks,
        skeletons=frames,
        result=output["result"],
    )
    return stored is not None


# ------------------------------------------------------------------------------------ reads


def list_recordings(
    session: Session,
    *,
    limit: int,
    offset: int,
    subject: str | None = None,
    task: str | None = None,
    format: str | None = None,
    q: str | None = None,
    created_after: datetime | None = None,
    created_before: datetime | None = None,
) -> tuple[list[dict[str, object]], int]:
    """A page of recording summaries, newest first, and how many match in all (``q``: text in
    names and notes; dates in UTC)."""
    return crud.list_recording_summaries(
        session=session,
        limit=limit,
        offset=offset,
        subject=subject,
        task=task,
        format=format,
        q=q,
        created_after=created_after,
        created_before=created_before,
    )


def active_pose_jobs(session: Session, recording_id: int) -> list[JobRecord]:
    """The recording's pose jobs still queued or running."""
    jobs = crud.pose_jobs(session=session, recording_id=recording_id).values()
    return [j for j in jobs if j.state in ("queued", "running")]


def skeleton_frame(session: Session, recording_id: int, k: int) -> SkeletonFrame:
    """Frame ``k`` of :func:`skeleton_frame_list` (its JPEG not loaded).

    Raises:
        NotFoundError: the recording has no frame ``k``.
    """
    frames = crud.skeleton_frames(session=session, recording_id=recording_id)
    if k >= len(frames):
        raise NotFoundError(f"recording {recording_id} has {len(frames)} skeleton frame(s)")
    return frames[k][0]


def skeleton_jpeg(session: Session, recording_id: int, k: int, frame_id: int) -> bytes:
    """The JPEG of frame ``k`` (``frame_id``, from :func:`skeleton_frame`).

    Raises:
        NotFoundError: the frame was replaced since (a new pose extraction).
    """
    jpeg = crud.skeleton_jpeg(session=session, frame_id=frame_id)
    if jpeg is None:  # pragma: no cover - replaced between two statements
        raise NotFoundError(f"frame {k} of recording {recording_id} was just replaced")
    return jpeg


def raw_file(
    session: Session, blobs: BlobStore, recording_id: int, file_id: int
) -> tuple[str, bytes]:
    """An uploaded file's name and bytes, byte for byte.

    Raises:
        NotFoundError: the recording has no such file.
    """
    f = session.get(RecordingFile, file_id)
    if f is None or f.session_id != recording_id:
        raise NotFoundError(f"recording {recording_id} has no file {file_id}")
    return f.original_name, blobs.get(f.sha256)


def delete_recording(session: Session, blobs: BlobStore, recording_id: int) -> None:
    """Delete a recording with its files, landmarks and skeleton frames (cancel its pose jobs
    first: :func:`active_pose_jobs`).

    Raises:
        NotFoundError: no such recording.
    """
    if not crud.delete_recording(session=session, blobs=blobs, recording_id=recording_id):
        raise NotFoundError(f"recording {recording_id} does not exist")


def pose_environment_problem() -> str | None:
    """Why this machine cannot turn videos into pose (None: it can)."""
    try:
        find_pose_python()
    except BioPlanError as exc:
        return str(exc)
    return None
