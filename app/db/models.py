"""SQLAlchemy 2 models of the service's database.

Entities: recording sessions, their uploaded files (raw bytes in the blob store, by SHA-256) and
parsed channels (arrays as compressed ``.npy`` bytes), the skeleton frames of uploaded videos,
jobs, and one result table per job kind (analyses with their human template, pose extractions,
plans, simulations, sweeps) whose primary key is the job's id, so ``/api/plans/7`` is the result
of job 7. Uploaded robots (URDF + optional MJCF) have their
own table; built-in robots come from the planning package and are not stored.

The schema is owned by the Alembic migrations in ``app/db/migrations/``; keep them in step.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any, ClassVar

from sqlalchemy import (
    JSON,
    BigInteger,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Text,
    TypeDecorator,
)
from sqlalchemy.engine import Dialect
from sqlalchemy.orm import DeclarativeBase, Mapped, declared_attr, mapped_column, relationship

from app import kinds as _kinds
from app import names as _names

# Named constraints so migrations (and SQLite batch mode) can refer to them.
NAMING_CONVENTION = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}

#: Job states and the ones a job never leaves (one home: ``app.names``).
JOB_STATES = _names.JOB_STATES
TERMINAL_STATES = _names.TERMINAL_JOB_STATES
#: The job kinds (one home: ``app.kinds``); each has a result table in :data:`RESULT_MODELS`.
JOB_KINDS = _kinds.KIND_NAMES
#: What an uploaded file is to its session: a recording (read and analysed; also the landmarks
#: extracted from a video), a sidecar of another file (BIDS ``_channels.tsv``/``_emg.json`` of an
#: EDF: used when that file is read, never read on its own), or a video (turned into pose).
FILE_ROLES = ("recording", "sidecar", "video")


def utcnow() -> datetime:
    return datetime.now(UTC)


class UTCDateTime(TypeDecorator[datetime]):
    """A time zone-aware UTC datetime on every backend (SQLite stores no zone: UTC is implied)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING_CONVENTION)
    type_annotation_map: ClassVar[dict[Any, Any]] = {
        dict[str, Any]: JSON,
        datetime: UTCDateTime(),
    }


class RecordingSession(Base):
    """One recording session: metadata and the files uploaded together."""

    __tablename__ = "recording_sessions"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    subject: Mapped[str | None] = mapped_column(String(200), index=True)
    task: Mapped[str | None] = mapped_column(String(200), index=True)
    load_kg: Mapped[float | None] = mapped_column(Float)
    notes: Mapped[str | None] = mapped_column(Text)
    #: the user's short name for the session ("S01 curls, heavy"), None when not given.
    label: Mapped[str | None] = mapped_column(String(200))
    #: the experimental condition ("light", "heavy", "fatigued"): a cohort groups by it.
    condition: Mapped[str | None] = mapped_column(String(100), index=True)
    #: reader options used at upload (rate overrides, muscle map, image size, frame rate), so an
    #: analysis rereads the raw bytes the same way.
    options: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    #: ``separate`` trials (each file on its own clock) or recorded ``together`` (one clock).
    session_mode: Mapped[str] = mapped_column(String(16), default="separate")
    created_at: Mapped[datetime] = mapped_column(default=utcnow, index=True)
    #: when the options or the metadata were last changed (``PATCH``), None if never.
    updated_at: Mapped[datetime | None] = mapped_column()

    files: Mapped[list[RecordingFile]] = relationship(
        back_populates="session",
        cascade="all, delete-orphan",
        passive_deletes=True,
        order_by="RecordingFile.id",
    )


class RecordingFile(Base):
    """One uploaded file: its bytes live in the blob store under ``sha256``."""

    __tablename__ = "recording_files"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(
        ForeignKey("recording_sessions.id", ondelete="CASCADE"), index=True
    )
    original_name: Mapped[str] = mapped_column(String(255))
    format: Mapped[str] = mapped_column(String(64), index=True)
    size: Mapped[int] = mapped_column(BigInteger)
    sha256: Mapped[str] = mapped_column(String(64), index=True)
    file_metadata: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    #: one of ``FILE_ROLES``.
    role: Mapped[str] = mapped_column(String(16), default="recording")
    #: the file this one belongs to: a sidecar's EDF, the video a landmarks file came from.
    parent_id: Mapped[int | None] = mapped_column(
        ForeignKey("recording_files.id", ondelete="CASCADE"), index=True
    )

    session: Mapped[RecordingSession] = relationship(back_populates="files")
    parent: Mapped[RecordingFile | None] = relationship(remote_side=[id])
    channels: Mapped[list[ChannelRecord]] = relationship(
        back_populates="file",
        cascade="all, delete-orphan",
        passive_deletes=True,
        order_by="ChannelRecord.id",
    )


class ChannelRecord(Base):
    """One parsed channel; samples as compressed ``.npy`` bytes (``app.db.arrays``)."""

    __tablename__ = "channels"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    file_id: Mapped[int] = mapped_column(
        ForeignKey("recording_files.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200))
    kind: Mapped[str] = mapped_column(String(16))
    unit: Mapped[str] = mapped_column(String(32))
    rate: Mapped[float] = mapped_column(Float)
    start: Mapped[float] = mapped_column(Float, default=0.0)
    site: Mapped[str | None] = mapped_column(String(16))
    n_samples: Mapped[int] = mapped_column(Integer)
    dims: Mapped[int] = mapped_column(Integer, default=1)
    # Deferred: listing a recording never loads its samples.
    data: Mapped[bytes] = mapped_column(LargeBinary, deferred=True)
    confidence: Mapped[bytes | None] = mapped_column(LargeBinary, deferred=True)
    time: Mapped[bytes | None] = mapped_column(LargeBinary, deferred=True)

    file: Mapped[RecordingFile] = relationship(back_populates="channels")


class SkeletonFrame(Base):
    """One frame of an uploaded video with the detected skeleton drawn (JPEG), for checking
    the pose fit; replaced with the landmarks when the pose is extracted again."""

    __tablename__ = "skeleton_frames"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    #: the video file.
    file_id: Mapped[int] = mapped_column(
        ForeignKey("recording_files.id", ondelete="CASCADE"), index=True
    )
    frame: Mapped[int] = mapped_column(Integer)
    #: time of the frame in the video [s].
    time: Mapped[float] = mapped_column(Float)
    sha256: Mapped[str] = mapped_column(String(64))
    jpeg: Mapped[bytes] = mapped_column(LargeBinary, deferred=True)


class RobotRecord(Base):
    """An uploaded robot model (URDF and/or MJCF, or a package zip with meshes, a sidecar),
    files in the blob store."""

    __tablename__ = "robots"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(100), unique=True)
    urdf_sha256: Mapped[str | None] = mapped_column(String(64))
    urdf_name: Mapped[str | None] = mapped_column(String(255))
    mjcf_sha256: Mapped[str | None] = mapped_column(String(64))
    mjcf_name: Mapped[str | None] = mapped_column(String(255))
    #: a zip of the robot's folder (model files, meshes, sidecar), checked member by member.
    package_sha256: Mapped[str | None] = mapped_column(String(64))
    package_name: Mapped[str | None] = mapped_column(String(255))
    sidecar_sha256: Mapped[str | None] = mapped_column(String(64))
    sidecar_name: Mapped[str | None] = mapped_column(String(255))
    #: ``shoulder_joint``, ``elbow_joint``, ``locks`` (display units) and the package members
    #: ``urdf_member``/``mjcf_member``/``sidecar_member`` (``app.jobs.tasks.robot_from_spec``).
    options: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    payload: Mapped[float | None] = mapped_column(Float)
    #: joint names and limits as read by the planning package (JSON-ready).
    description: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)


class RobotLogRecord(Base):
    """An uploaded robot log (what a real arm measured: joint positions, speeds, torques) of
    one robot; its bytes live in the blob store under ``sha256``. Stored only after it was read,
    matched to the robot's joints and validated against its model."""

    __tablename__ = "robot_logs"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    #: the robot (built-in or uploaded) the log was recorded on; no foreign key: built-ins
    #: have no row.
    robot: Mapped[str] = mapped_column(String(100), index=True)
    original_name: Mapped[str] = mapped_column(String(255))
    format: Mapped[str] = mapped_column(String(32))
    size: Mapped[int] = mapped_column(BigInteger)
    sha256: Mapped[str] = mapped_column(String(64), index=True)
    #: a ROS 2 bag's JointState topic, None for CSV logs or the bag's only one.
    topic: Mapped[str | None] = mapped_column(String(200))
    #: samples, rate [Hz], duration [s], notes, and the validation against the robot at upload
    #: (joints, abs_work).
    summary: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    label: Mapped[str | None] = mapped_column(String(200))
    created_at: Mapped[datetime] = mapped_column(default=utcnow, index=True)


class JobRecord(Base):
    """A background job. Only the API process writes these rows."""

    __tablename__ = "jobs"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    kind: Mapped[str] = mapped_column(String(16), index=True)
    state: Mapped[str] = mapped_column(String(16), index=True, default="queued")
    #: Structured progress (``app.progress.Progress``): the overall fraction in [0, 1], the
    #: stage running, its units done of all, the best objective so far, a line for people.
    progress: Mapped[float] = mapped_column(Float, default=0.0)
    stage: Mapped[str] = mapped_column(String(32), default="")
    done: Mapped[int] = mapped_column(Integer, default=0)
    of: Mapped[int] = mapped_column(Integer, default=1)
    best: Mapped[float | None] = mapped_column(Float)
    message: Mapped[str] = mapped_column(Text, default="")
    error: Mapped[str | None] = mapped_column(Text)
    #: the request, with the CLI's field names.
    params: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    #: the user's short name for the job's result ("UR5 slow, heavy"), None when not given.
    label: Mapped[str | None] = mapped_column(String(200))
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    created_at: Mapped[datetime] = mapped_column(default=utcnow, index=True)
    started_at: Mapped[datetime | None] = mapped_column()
    finished_at: Mapped[datetime | None] = mapped_column()
    updated_at: Mapped[datetime] = mapped_column(default=utcnow)


class _ResultMixin:
    """Result row of a job: same id as the job (deleted with it), JSON result in the CLI's
    shape."""

    id: Mapped[int] = mapped_column(
        ForeignKey("jobs.id", ondelete="CASCADE"), primary_key=True, sort_order=-1
    )
    result: Mapped[dict[str, Any] | None] = mapped_column(JSON)

    @declared_attr
    def job(cls) -> Mapped[JobRecord]:
        return relationship()


class Analysis(_ResultMixin, Base):
    __tablename__ = "analyses"

    recording_id: Mapped[int | None] = mapped_column(
        ForeignKey("recording_sessions.id", ondelete="SET NULL"), index=True
    )
    template: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    #: The plot overlays (``app.analysis.AnalysisOverlays.to_arrays``) as ``.npz`` bytes.
    arrays: Mapped[bytes | None] = mapped_column(LargeBinary, deferred=True)


class PoseExtraction(_ResultMixin, Base):
    """A pose-extraction job of one uploaded video (its landmarks become a file of the
    recording, its skeleton frames ``SkeletonFrame`` rows, when it succeeds)."""

    __tablename__ = "pose_extractions"

    recording_id: Mapped[int | None] = mapped_column(
        ForeignKey("recording_sessions.id", ondelete="SET NULL"), index=True
    )
    video_file_id: Mapped[int | None] = mapped_column(
        ForeignKey("recording_files.id", ondelete="SET NULL"), index=True
    )


class Plan(_ResultMixin, Base):
    __tablename__ = "plans"

    robot: Mapped[str] = mapped_column(String(100), index=True)
    arrays: Mapped[bytes | None] = mapped_column(LargeBinary, deferred=True)


class Simulation(_ResultMixin, Base):
    __tablename__ = "simulations"

    robot: Mapped[str] = mapped_column(String(100), index=True)
    arrays: Mapped[bytes | None] = mapped_column(LargeBinary, deferred=True)


class Sweep(_ResultMixin, Base):
    __tablename__ = "sweeps"

    robot: Mapped[str] = mapped_column(String(100), index=True)


class Profiles(_ResultMixin, Base):
    """Classical profiles (and the planning methods) on one task (``bioplan profiles``)."""

    __tablename__ = "profiles"

    robot: Mapped[str] = mapped_column(String(100), index=True)


class Cohort(_ResultMixin, Base):
    """Groups of stored recordings compared (``bioplan cohort``); the recordings are named in
    the job's params (a recording deleted later leaves the stored result as it was)."""

    __tablename__ = "cohorts"


class IdentificationRecord(_ResultMixin, Base):
    """Inertias and friction identified from robot logs (``bioplan identify``); on success the
    robot ``version`` (the nominal robot with the identified sidecar) is stored beside it."""

    __tablename__ = "identifications"

    robot: Mapped[str] = mapped_column(String(100), index=True)
    #: the name the identified robot is stored under.
    version: Mapped[str] = mapped_column(String(100))


class FrontRecord(_ResultMixin, Base):
    """A Pareto front between two metrics (``bioplan front``) with its reference methods;
    ``arrays`` holds every point's and reference's trajectory (``<id>_t``, ``<id>_q``, ...) as
    ``.npz`` bytes, so a point can be plotted, viewed and exported."""

    __tablename__ = "fronts"

    robot: Mapped[str] = mapped_column(String(100), index=True)
    arrays: Mapped[bytes | None] = mapped_column(LargeBinary, deferred=True)


class ResultBlob(Base):
    """A job result too large for its row, kept in the file store: the row's ``result`` holds
    ``{RESULT_BLOB_KEY: sha256, "bytes": n}`` and this row keeps the blob referenced (read back
    transparently: ``app.db.crud``)."""

    __tablename__ = "result_blobs"

    job_id: Mapped[int] = mapped_column(ForeignKey("jobs.id", ondelete="CASCADE"), primary_key=True)
    sha256: Mapped[str] = mapped_column(String(64), index=True)
    size: Mapped[int] = mapped_column(BigInteger)


#: The key of a result row's reference to its result in the file store.
RESULT_BLOB_KEY = "$result_blob"


#: A result table: one per job kind, whose primary key is the job's id.
ResultModel = (
    Analysis
    | PoseExtraction
    | Plan
    | Simulation
    | Sweep
    | Profiles
    | Cohort
    | IdentificationRecord
    | FrontRecord
)
#: The storage part of the job-kind registry (``app.kinds``): kind -> its result table.
RESULT_MODELS: dict[str, type[ResultModel]] = {
    "analysis": Analysis,
    "pose": PoseExtraction,
    "plan": Plan,
    "simulation": Simulation,
    "sweep": Sweep,
    "profiles": Profiles,
    "cohort": Cohort,
    "identify": IdentificationRecord,
    "front": FrontRecord,
}
