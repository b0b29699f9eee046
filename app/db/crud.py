"""Database functions (keyword-only arguments): recordings, robots, jobs and job results.

Every function takes an open ``Session``; the ones that change data commit it themselves, so a
caller never sees half of an operation: an upload is one transaction (session, files, channels),
and a deletion removes the rows first and only then the blobs nobody refers to any more.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, TypedDict, Unpack

import numpy as np
from sqlalchemy import Select, delete, event, func, or_, select, update
from sqlalchemy.orm import Session, selectinload, undefer
from sqlalchemy.orm.attributes import set_committed_value

from app.db.arrays import encode_array, encode_arrays
from app.db.blobs import BlobStore
from app.db.models import (
    RESULT_BLOB_KEY,
    RESULT_MODELS,
    TERMINAL_STATES,
    Base,
    ChannelRecord,
    JobRecord,
    PoseExtraction,
    RecordingFile,
    RecordingSession,
    ResultBlob,
    RobotLogRecord,
    RobotRecord,
    SkeletonFrame,
    utcnow,
)
from app.jsonsafe import json_safe

logger = logging.getLogger(__name__)

#: A SELECT of any columns (SQLAlchemy 2.1 types Select by its column tuple).
AnySelect = Select[*tuple[Any, ...]]


# --------------------------------------------------------------------------------- recordings


@dataclass
class ParsedFile:
    """One uploaded file after parsing (plain data from ``app.jobs.tasks.parse_recording``).

    Attributes:
        name: the user's file name (kept as metadata only; storage is by SHA-256).
        data: the raw bytes.
        format: detected format.
        metadata: what the file states about itself (JSON-ready).
        channels: one dict per channel: ``name, kind, unit, rate, start, site, data``
            ((N,) or (N, 3) float64), ``confidence`` and ``time`` ((N,) or None).
        role: ``recording``, ``sidecar`` or ``video`` (``app.db.models.FILE_ROLES``).
        parent: index (in the same upload) of the file this one belongs to, or None.
    """

    name: str
    data: bytes
    format: str
    metadata: dict[str, Any] = field(default_factory=dict)
    channels: list[dict[str, Any]] = field(default_factory=list)
    role: str = "recording"
    parent: int | None = None


def _channel_row(ch: dict[str, Any]) -> ChannelRecord:
    data = np.asarray(ch["data"], dtype=np.float64)
    conf = ch.get("confidence")
    time = ch.get("time")
    return ChannelRecord(
        name=str(ch["name"])[:200],
        kind=str(ch["kind"]),
        unit=str(ch.get("unit", "")),
        rate=float(ch["rate"]),
        start=float(ch.get("start", 0.0)),
        site=ch.get("site"),
        n_samples=int(data.shape[0]),
        dims=1 if data.ndim == 1 else int(data.shape[1]),
        data=encode_array(data),
        confidence=None if conf is None else encode_array(np.asarray(conf, np.float64)),
        time=None if time is None else encode_array(np.asarray(time, np.float64)),
    )


def create_recording(
    *,
    session: Session,
    blobs: BlobStore,
    meta: dict[str, Any],
    files: Sequence[ParsedFile],
) -> RecordingSession:
    """Store a recording session with its files and channels in one transaction.

    The raw bytes go to the blob store first (atomic renames); the rows are committed after, so
    a crash leaves either the whole recording or none of it (plus, at worst, an unreferenced blob
    that :func:`collect_garbage` removes).

    Args:
        session: open database session.
        blobs: the file store.
        meta: ``subject, task, load_kg, notes, label, condition, options, session_mode`` of the
            session.
        files: parsed files, at least one; a file's ``parent`` is the index of an earlier one.
    """
    if not files:
        raise ValueError("a recording needs at least one file")
    # Encode outside the lock: it is the slow part and touches nothing shared.
    rows = [[_channel_row(ch) for ch in f.channels] for f in files]
    rec = RecordingSession(
        subject=meta.get("subject"),
        task=meta.get("task"),
        load_kg=meta.get("load_kg"),
        notes=meta.get("notes"),
        label=meta.get("label"),
        condition=meta.get("condition"),
        options=json_safe(meta.get("options") or {}),
        session_mode=meta.get("session_mode") or "separate",
        created_at=utcnow(),
    )
    with blobs.lock:
        stored: list[RecordingFile] = []
        for f, channel_rows in zip(files, rows, strict=True):
            row = _file_row(blobs, f, channel_rows)
            if f.parent is not None:
                row.parent = stored[f.parent]
            stored.append(row)
            rec.files.append(row)
        session.add(rec)
        _commit(session)
    return rec


def _file_row(blobs: BlobStore, f: ParsedFile, channel_rows: list[ChannelRecord]) -> RecordingFile:
    """A file row, its bytes put in the blob store (call with ``blobs.lock`` held)."""
    return RecordingFile(
        original_name=f.name[:255],
        format=f.format,
        size=len(f.data),
        sha256=blobs.put(f.data),
        file_metadata=json_safe(f.metadata),
        role=f.role,
        channels=channel_rows,
    )


def _commit(session: Session) -> None:
    """Commit, or roll back and re-raise: a failed commit leaves nothing half-written."""
    try:
        session.commit()
    except BaseException:
        session.rollback()
        raise


class RecordingFilters(TypedDict, total=False):
    """The filters of a recordings listing, as keyword arguments (absent/``None``: not filtered
    on; ``q``: text in names and notes; dates in UTC)."""

    subject: str | None
    task: str | None
    format: str | None
    q: str | None
    created_after: datetime | None
    created_before: datetime | None


@dataclass(frozen=True)
class _RecordingFilter:
    """The filters of a recordings listing (``None``/empty: not filtered on)."""

    subject: str | None = None
    task: str | None = None
    format: str | None = None
    q: str | None = None
    created_after: datetime | None = None
    created_before: datetime | None = None

    def apply(self, stmt: AnySelect) -> AnySelect:
        """``stmt`` restricted to the sessions matching every filter."""
        if self.subject is not None:
            stmt = stmt.where(RecordingSession.subject == self.subject)
        if self.task is not None:
            stmt = stmt.where(RecordingSession.task == self.task)
        if self.format is not None:
            stmt = stmt.where(RecordingSession.files.any(RecordingFile.format == self.format))
        if self.q:
            like = f"%{self.q}%"
            stmt = stmt.where(
                or_(
                    RecordingSession.subject.ilike(like),
                    RecordingSession.task.ilike(like),
                    RecordingSession.notes.ilike(like),
                    RecordingSession.label.ilike(like),
                    RecordingSession.condition.ilike(like),
                    RecordingSession.files.any(RecordingFile.original_name.ilike(like)),
                )
            )
        if self.created_after is not None:
            stmt = stmt.where(RecordingSession.created_at >= self.created_after)
        if self.created_before is not None:
            stmt = stmt.where(RecordingSession.created_at < self.created_before)
        return stmt

    def count(self, session: Session) -> int:
        """How many sessions match."""
        return int(session.scalar(self.apply(select(func.count(RecordingSession.id)))) or 0)

    def page(self, stmt: AnySelect, limit: int, offset: int) -> AnySelect:
        """``stmt`` restricted to the matching sessions, newest first, one page of them."""
        newest_first = (RecordingSession.created_at.desc(), RecordingSession.id.desc())
        return self.apply(stmt).order_by(*newest_first).limit(limit).offset(offset)


def list_recordings(
    *,
    session: Session,
    limit: int = 50,
    offset: int = 0,
    **filters: Unpack[RecordingFilters],
) -> tuple[list[RecordingSession], int]:
    """A page of recording sessions, newest first, and the total matching the filters."""
    where = _RecordingFilter(**filters)
    stmt = where.page(select(RecordingSession), limit, offset)
    stmt = stmt.options(selectinload(RecordingSession.files))
    return list(session.scalars(stmt)), where.count(session)


def list_recording_summaries(
    *,
    session: Session,
    limit: int = 50,
    offset: int = 0,
    **filters: Unpack[RecordingFilters],
) -> tuple[list[dict[str, Any]], int]:
    """Like :func:`list_recordings`, as plain dicts, reading only the listed columns.

    The list is the most frequent request; two narrow queries (sessions, then their files'
    names and formats) avoid loading JSON metadata and building ORM objects.
    """
    where = _RecordingFilter(**filters)
    total = where.count(session)
    cols = (
        RecordingSession.id,
        RecordingSession.subject,
        RecordingSession.task,
        RecordingSession.load_kg,
        RecordingSession.notes,
        RecordingSession.label,
        RecordingSession.condition,
        RecordingSession.created_at,
        RecordingSession.session_mode.label("session"),
    )
    rows = session.execute(where.page(select(*cols), limit, offset)).all()
    out = {r.id: {**r._asdict(), "file_names": [], "formats": set()} for r in rows}
    if out:
        # The files the user uploaded; not the landmarks a pose job extracts from a video
        # (a page cached until the next upload stays right).
        uploaded = or_(RecordingFile.role != "recording", RecordingFile.parent_id.is_(None))
        files = session.execute(
            select(RecordingFile.session_id, RecordingFile.original_name, RecordingFile.format)
            .where(RecordingFile.session_id.in_(list(out)), uploaded)
            .order_by(RecordingFile.id)
        )
        for sid, name, fmt in files:
            out[sid]["file_names"].append(name)
            out[sid]["formats"].add(fmt)
    items = []
    for item in out.values():
        item["formats"] = sorted(item["formats"])
        item["n_files"] = len(item["file_names"])
        items.append(item)
    return items, total


def get_recording(*, session: Session, recording_id: int) -> RecordingSession | None:
    """A recording session with its files and channel metadata (samples not loaded)."""
    stmt = (
        select(RecordingSession)
        .where(RecordingSession.id == recording_id)
        .options(selectinload(RecordingSession.files).selectinload(RecordingFile.channels))
    )
    return session.scalars(stmt).first()


def get_channels(
    *, session: Session, recording_id: int, channel_ids: Iterable[int] | None = None
) -> list[ChannelRecord]:
    """Channels of a recording with their samples loaded, in file and channel order."""
    stmt = (
        select(ChannelRecord)
        .join(RecordingFile)
        .where(RecordingFile.session_id == recording_id)
        .options(
            undefer(ChannelRecord.data),
            undefer(ChannelRecord.time),
            selectinload(ChannelRecord.file),
        )
        .order_by(RecordingFile.id, ChannelRecord.id)
    )
    if channel_ids is not None:
        stmt = stmt.where(ChannelRecord.id.in_(list(channel_ids)))
    return list(session.scalars(stmt))


def referenced_hashes(*, session: Session) -> set[str]:
    """SHA-256 of every blob some row refers to."""
    refs = set(session.scalars(select(RecordingFile.sha256)))
    refs |= set(session.scalars(select(ResultBlob.sha256)))
    refs |= set(session.scalars(select(RobotLogRecord.sha256)))
    for column in (
        RobotRecord.urdf_sha256,
        RobotRecord.mjcf_sha256,
        RobotRecord.package_sha256,
        RobotRecord.sidecar_sha256,
    ):
        refs |= {h for h in session.scalars(select(column)) if h}
    return refs


def collect_garbage(*, session: Session, blobs: BlobStore) -> int:
    """Delete blobs no row refers to (left by a crash or a deletion); returns how many."""
    with blobs.lock:
        blobs.remove_temporaries()
        refs = referenced_hashes(session=session)
        blobs.recover_detached(refs)
        n = 0
        for sha in list(blobs.hashes()):
            if sha not in refs:
                blobs.delete(sha)
                n += 1
        return n


def delete_recording(*, session: Session, blobs: BlobStore, recording_id: int) -> bool:
    """Delete a recording session (files and channels cascade) and its unreferenced blobs."""
    with blobs.lock:
        rec = session.get(RecordingSession, recording_id)
        if rec is None:
            return False
        _delete_with_blobs(session, blobs, rec, {f.sha256 for f in rec.files})
    return True


def _delete_with_blobs(session: Session, blobs: BlobStore, row: Base, hashes: set[str]) -> None:
    """Delete ``row`` and the blobs among ``hashes`` no other row refers to, all or nothing
    (``blobs.lock`` held): the blobs are moved aside first, so a disk that refuses (read-only,
    failing) leaves both the row and its files as they were, and the error propagates."""
    session.delete(row)
    session.flush()
    try:
        moved = blobs.detach(hashes - referenced_hashes(session=session))
    except BaseException:
        session.rollback()
        raise
    try:
        session.commit()
    except BaseException:
        session.rollback()
        blobs.restore(moved)
        raise
    blobs.purge(moved)


def update_recording(
    *,
    session: Session,
    recording_id: int,
    values: dict[str, Any],
    reparsed: dict[int, ParsedFile],
) -> RecordingSession | None:
    """Change a recording's metadata and options and replace its files' parsed channels, in one
    transaction (what ``PATCH /api/recordings/{id}`` does after reading the files again).

    Args:
        values: columns of the session to set (``subject, task, load_kg, notes, options,
            session_mode``); ``updated_at`` is set here.
        reparsed: file id -> the file read again with the new options (its ``format``,
            ``metadata`` and ``channels`` replace the stored ones; the bytes are unchanged).

    Returns:
        The session, or None when it does not exist (nothing changed).
    """
    rec = get_recording(session=session, recording_id=recording_id)
    if rec is None:
        return None
    rows = {fid: [_channel_row(ch) for ch in f.channels] for fid, f in reparsed.items()}
    for key, value in values.items():
        setattr(rec, key, json_safe(value) if key == "options" else value)
    rec.updated_at = utcnow()
    for f in rec.files:
        if f.id in reparsed:
            f.format = reparsed[f.id].format
            f.file_metadata = json_safe(reparsed[f.id].metadata)
            f.channels = rows[f.id]
    _commit(session)
    return get_recording(session=session, recording_id=recording_id)


@dataclass(frozen=True)
class SkeletonImage:
    """A video frame with the skeleton drawn: frame index, time in the video [s], JPEG bytes."""

    frame: int
    time: float
    jpeg: bytes


def store_pose_result(
    *,
    session: Session,
    blobs: BlobStore,
    job_id: int,
    landmarks: ParsedFile,
    skeletons: Sequence[SkeletonImage],
    result: dict[str, Any],
) -> int | None:
    """Store what a pose job extracted from a video and mark the job succeeded, in one
    transaction: the landmarks as a file of the recording (child of the video), the skeleton
    frames, the job's result. Landmarks and frames of an earlier extraction of the same video
    are replaced.

    Returns:
        The landmarks file's id, or None when nothing was stored (the job ended meanwhile, or
        its video or recording was deleted).
    """
    rows = [_channel_row(ch) for ch in landmarks.channels]
    with blobs.lock:
        job = session.get(JobRecord, job_id, with_for_update=True, populate_existing=True)
        row = session.get(PoseExtraction, job_id)
        video = None if row is None or row.video_file_id is None else row.video_file_id
        video_file = None if video is None else session.get(RecordingFile, video)
        if job is None or job.state in TERMINAL_STATES or row is None or video_file is None:
            session.rollback()
            return None
        old = _pose_children(session, video_file.id)
        for child in old:
            session.delete(child)
        session.execute(delete(SkeletonFrame).where(SkeletonFrame.file_id == video_file.id))
        new = _file_row(blobs, landmarks, rows)
        new.parent_id, new.session_id = video_file.id, video_file.session_id
        session.add(new)
        for s in skeletons:
            session.add(
                SkeletonFrame(
                    file_id=video_file.id,
                    frame=int(s.frame),
                    time=float(s.time),
                    sha256=hashlib.sha256(s.jpeg).hexdigest(),
                    jpeg=s.jpeg,
                )
            )
        session.flush()
        row.result = json_safe({**result, "landmarks_file_id": new.id})
        _succeed(job)
        _commit(session)
        _drop_unreferenced(session, blobs, {c.sha256 for c in old})
        return new.id


def _pose_children(session: Session, video_id: int) -> list[RecordingFile]:
    stmt = select(RecordingFile).where(
        RecordingFile.parent_id == video_id, RecordingFile.role == "recording"
    )
    return list(session.scalars(stmt))


def _succeed(job: JobRecord, message: str = "done") -> None:
    now = utcnow()
    job.state = "succeeded"
    job.progress = 1.0
    job.message = message
    job.finished_at = now
    job.updated_at = now


def _drop_unreferenced(session: Session, blobs: BlobStore, hashes: set[str]) -> None:
    """Delete the blobs among ``hashes`` that no row refers to any more (``blobs.lock`` held,
    the rows' deletion committed). A blob that cannot be removed now (a read-only or failing
    disk) stays unreferenced, and :func:`collect_garbage` removes it at the next start: the
    deletion the client asked for has happened."""
    if hashes:
        refs = referenced_hashes(session=session)
        for sha in hashes - refs:
            try:
                blobs.delete(sha)
            except OSError as exc:
                logger.warning("blob %s left for the next start's clean-up: %s", sha, exc)


def skeleton_frames(*, session: Session, recording_id: int) -> list[tuple[SkeletonFrame, str]]:
    """The recording's skeleton frames (JPEG not loaded) with their video's file name, in
    file and frame order."""
    stmt = (
        select(SkeletonFrame, RecordingFile.original_name)
        .join(RecordingFile, RecordingFile.id == SkeletonFrame.file_id)
        .where(RecordingFile.session_id == recording_id)
        .order_by(RecordingFile.id, SkeletonFrame.frame)
    )
    return [(frame, name) for frame, name in session.execute(stmt).all()]


def skeleton_jpeg(*, session: Session, frame_id: int) -> bytes | None:
    return session.scalars(select(SkeletonFrame.jpeg).where(SkeletonFrame.id == frame_id)).first()


def pose_jobs(*, session: Session, recording_id: int) -> dict[int, JobRecord]:
    """Video file id -> its newest pose-extraction job, for one recording."""
    stmt = (
        select(PoseExtraction.video_file_id, JobRecord)
        .join(JobRecord, JobRecord.id == PoseExtraction.id)
        .where(PoseExtraction.recording_id == recording_id)
        .order_by(JobRecord.id)
    )
    return {fid: job for fid, job in session.execute(stmt).all() if fid is not None}


def list_pose_extractions(
    *,
    session: Session,
    limit: int = 50,
    offset: int = 0,
    state: str | None = None,
    recording_id: int | None = None,
) -> tuple[list[tuple[PoseExtraction, JobRecord]], int]:
    """A page of pose extractions with their jobs, newest first, and the total."""
    stmt, total = _job_page(
        session,
        select(PoseExtraction, JobRecord).join(JobRecord, JobRecord.id == PoseExtraction.id),
        limit,
        offset,
        state=state,
        recording_id=(PoseExtraction.recording_id, recording_id),
    )
    return [(row, job) for row, job in session.execute(stmt).all()], total


# ------------------------------------------------------------------------------------- robots


def create_robot(
    *,
    session: Session,
    blobs: BlobStore,
    name: str,
    urdf: tuple[str, bytes] | None,
    mjcf: tuple[str, bytes] | None,
    payload: float | None,
    description: dict[str, Any],
    package: tuple[str, bytes] | None = None,
    sidecar: tuple[str, bytes] | None = None,
    options: dict[str, Any] | None = None,
) -> RobotRecord:
    """Store an uploaded robot (files by hash, row in one transaction)."""

    def name_of(f: tuple[str, bytes] | None) -> str | None:
        return None if f is None else f[0][:255]

    with blobs.lock:
        row = RobotRecord(
            name=name,
            urdf_name=name_of(urdf),
            urdf_sha256=None if urdf is None else blobs.put(urdf[1]),
            mjcf_name=name_of(mjcf),
            mjcf_sha256=None if mjcf is None else blobs.put(mjcf[1]),
            package_name=name_of(package),
            package_sha256=None if package is None else blobs.put(package[1]),
            sidecar_name=name_of(sidecar),
            sidecar_sha256=None if sidecar is None else blobs.put(sidecar[1]),
            options=json_safe(options or {}),
            payload=payload,
            description=json_safe(description),
            created_at=utcnow(),
        )
        session.add(row)
        _commit(session)
    return row


def get_robot(*, session: Session, name: str) -> RobotRecord | None:
    return session.scalars(select(RobotRecord).where(RobotRecord.name == name)).first()


def list_robots(*, session: Session) -> list[RobotRecord]:
    return list(session.scalars(select(RobotRecord).order_by(RobotRecord.name)))


def delete_robot(*, session: Session, blobs: BlobStore, name: str) -> bool:
    with blobs.lock:
        row = get_robot(session=session, name=name)
        if row is None:
            return False
        hashes = {
            h
            for h in (row.urdf_sha256, row.mjcf_sha256, row.package_sha256, row.sidecar_sha256)
            if h
        }
        _delete_with_blobs(session, blobs, row, hashes)
    return True


# ---------------------------------------------------------------------------------- robot logs


def create_robot_log(
    *,
    session: Session,
    blobs: BlobStore,
    robot: str,
    file: tuple[str, bytes],
    format: str,
    topic: str | None,
    summary: dict[str, Any],
    label: str | None = None,
) -> RobotLogRecord:
    """Store a robot log (bytes by hash, row in one transaction: both or neither)."""
    with blobs.lock:
        row = RobotLogRecord(
            robot=robot,
            original_name=file[0][:255],
            format=format,
            size=len(file[1]),
            sha256=blobs.put(file[1]),
            topic=topic,
            summary=json_safe(summary),
            label=label,
            created_at=utcnow(),
        )
        session.add(row)
        _commit(session)
    return row


def get_robot_log(*, session: Session, log_id: int) -> RobotLogRecord | None:
    return session.get(RobotLogRecord, log_id)


def list_robot_logs(*, session: Session, robot: str | None = None) -> list[RobotLogRecord]:
    """Stored robot logs, newest first (of one robot when ``robot`` is given)."""
    stmt = select(RobotLogRecord).order_by(RobotLogRecord.id.desc())
    if robot is not None:
        stmt = stmt.where(RobotLogRecord.robot == robot)
    return list(session.scalars(stmt))


def delete_robot_log(*, session: Session, blobs: BlobStore, log_id: int) -> bool:
    with blobs.lock:
        row = session.get(RobotLogRecord, log_id)
        if row is None:
            return False
        _delete_with_blobs(session, blobs, row, {row.sha256})
    return True


# --------------------------------------------------------------------------------------- jobs


def create_job(
    *,
    session: Session,
    kind: str,
    params: dict[str, Any],
    resource: dict[str, Any],
    label: str | None = None,
) -> JobRecord:
    """Create a queued job and its (empty) result row in one transaction.

    Args:
        kind: ``analysis``, ``plan``, ``simulation`` or ``sweep``.
        params: the request (CLI field names), JSON-ready.
        resource: columns of the result row (e.g. ``{"robot": "human_arm_2dof"}``).
    """
    model = RESULT_MODELS[kind]
    now = utcnow()
    job = JobRecord(
        kind=kind,
        state="queued",
        progress=0.0,
        message="queued",
        params=json_safe(params),
        label=label,
        attempts=0,
        created_at=now,
        updated_at=now,
    )
    session.add(job)
    session.flush()
    session.add(model(id=job.id, **resource))
    session.commit()
    return job


def delete_job(*, session: Session, blobs: BlobStore, job_id: int) -> bool:
    """Delete a job with its result row (they cascade) and its result in the file store when
    no other row refers to it; False when there is no such job."""
    with blobs.lock:
        job = session.get(JobRecord, job_id)
        if job is None:
            return False
        hashes = set(session.scalars(select(ResultBlob.sha256).where(ResultBlob.job_id == job_id)))
        _delete_with_blobs(session, blobs, job, hashes)
    return True


def get_job(*, session: Session, job_id: int) -> JobRecord | None:
    return session.get(JobRecord, job_id, populate_existing=True)


def list_jobs(
    *,
    session: Session,
    limit: int = 50,
    offset: int = 0,
    kind: str | None = None,
    state: str | None = None,
) -> tuple[list[JobRecord], int]:
    """A page of jobs, newest first, and the total matching the filters."""
    stmt, total = _job_page(
        session, select(JobRecord), limit, offset, state=state, kind=(JobRecord.kind, kind)
    )
    return list(session.scalars(stmt)), total


def _job_page(
    session: Session,
    stmt: AnySelect,
    limit: int,
    offset: int,
    *,
    state: str | None,
    **equal: tuple[Any, object | None],
) -> tuple[AnySelect, int]:
    """``stmt`` (which selects from ``JobRecord``) restricted to the job ``state`` and to every
    ``column == value`` of ``equal`` whose value is not None, newest job first, one page of
    it; and how many rows match in all."""
    where = [column == value for column, value in equal.values() if value is not None]
    if state is not None:
        where.append(JobRecord.state == state)
    stmt = stmt.where(*where)
    total = session.scalar(stmt.with_only_columns(func.count(JobRecord.id)).order_by(None))
    return stmt.order_by(JobRecord.id.desc()).limit(limit).offset(offset), int(total or 0)


def update_job(
    *, session: Session, job_id: int, only_if_active: bool = True, **values: Any
) -> bool:
    """Set columns of a job; with ``only_if_active`` a finished job is left as it is.

    Returns:
        True when a row changed.
    """
    stmt = update(JobRecord).where(JobRecord.id == job_id)
    if only_if_active:
        stmt = stmt.where(JobRecord.state.not_in(TERMINAL_STATES))
    values.setdefault("updated_at", utcnow())
    result = session.execute(stmt.values(**values))
    session.commit()
    return bool(getattr(result, "rowcount", 0))


def store_result(
    *,
    session: Session,
    job_id: int,
    kind: str,
    result: dict[str, Any],
    arrays: dict[str, Any] | None = None,
    template: dict[str, Any] | None = None,
    message: str = "done",
    blobs: BlobStore | None = None,
    inline_bytes: int | None = None,
) -> bool:
    """Store a job's result and mark it succeeded, in one transaction.

    A job that was cancelled (or failed) meanwhile keeps its state and gets no result. With
    ``blobs`` and ``inline_bytes``, a result whose JSON is larger than ``inline_bytes`` goes to
    the file store and the row keeps a reference (a ``ResultBlob`` keeps the file referenced);
    rows loaded through a session whose ``info[BLOBS_KEY]`` is the store read it back as if it
    were in the row.
    """
    job = session.get(JobRecord, job_id, with_for_update=True, populate_existing=True)
    if job is None or job.state in TERMINAL_STATES:
        session.rollback()
        return False
    row: Any = session.get(RESULT_MODELS[kind], job_id)
    if row is None:
        session.rollback()
        return False
    safe = json_safe(result)
    if arrays is not None and hasattr(row, "arrays"):
        row.arrays = encode_arrays(arrays)
    if template is not None and hasattr(row, "template"):
        row.template = json_safe(template)
    _succeed(job, message)
    text = None if blobs is None or inline_bytes is None else _json_bytes(safe)
    if text is None or len(text) <= inline_bytes:  # type: ignore[operator]
        row.result = safe
        session.commit()
        return True
    assert blobs is not None
    with blobs.lock:  # put and commit together: a clean-up between them would drop the file
        sha = blobs.put(text)
        row.result = {RESULT_BLOB_KEY: sha, "bytes": len(text)}
        session.merge(ResultBlob(job_id=job_id, sha256=sha, size=len(text)))
        _commit(session)
    return True


def _json_bytes(value: Any) -> bytes:
    return json.dumps(value, separators=(",", ":"), allow_nan=False).encode("utf-8")


#: ``Session.info`` key of the file store that results too large for their row are read from.
BLOBS_KEY = "bioplan_blobs"


def _inflate(target: Any, context: Any, attrs: Any = None) -> None:
    """A result row whose ``result`` is a reference to the file store gets its result back
    (as if it had been in the row), without marking the row changed."""
    ref = target.__dict__.get("result")
    if not (isinstance(ref, dict) and RESULT_BLOB_KEY in ref):
        return
    session = getattr(context, "session", None)
    blobs = None if session is None else session.info.get(BLOBS_KEY)
    if not isinstance(blobs, BlobStore):
        raise RuntimeError(
            f"the result of job {target.id} is kept in the file store, and this session has no "
            f"file store (Session.info[{BLOBS_KEY!r}])"
        )
    set_committed_value(target, "result", json.loads(blobs.get(str(ref[RESULT_BLOB_KEY]))))


for _model in set(RESULT_MODELS.values()):
    event.listen(_model, "load", _inflate)
    event.listen(_model, "refresh", _inflate)


def count_jobs(*, session: Session, state: str | None = None) -> int:
    """How many jobs there are (in ``state``)."""
    stmt = select(func.count(JobRecord.id))
    if state is not None:
        stmt = stmt.where(JobRecord.state == state)
    return int(session.scalar(stmt) or 0)


def active_jobs(*, session: Session) -> list[JobRecord]:
    """Jobs queued or running, oldest first."""
    stmt = (
        select(JobRecord).where(JobRecord.state.in_(("queued", "running"))).order_by(JobRecord.id)
    )
    return list(session.scalars(stmt))
