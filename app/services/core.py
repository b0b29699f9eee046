"""The running services of one server process, built once by ``app.main.create_app``.

``start_services`` migrates the database, opens it and the file store, removes files a crash
left unreferenced, starts the job runner and recovers the jobs a previous server left queued or
running. ``Services.start_viewer`` starts the 3-D viewer on them. ``stop_services`` undoes it all.
"""

from __future__ import annotations

import functools
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TypeVar

from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker

from app.config import Settings
from app.db import crud
from app.db.blobs import BlobStore
from app.db.lock import DatabaseLock, DataDirLock, lock_data_dir, lock_database
from app.db.session import current_revision, make_engine, make_sessionmaker, upgrade
from app.jobs.runner import JobRunner, make_runner
from app.services import sandbox
from app.services.broker import JobBroker, StreamLimits
from app.services.cache import ResponseCache
from app.services.comparisons import ComparisonLoader
from app.services.errors import ParseLimitError
from app.services.human_replay import HumanReplayLoader
from app.services.jobs import JobService
from app.services.limits import JobLimits
from app.services.overlays import RecordingOverlays
from app.services.robots import RobotCatalog, mesh_limits
from app.services.sandbox import ParseSandbox
from app.viewer.access import ViewerAccess
from app.viewer.kinematics import use_mesh_limits
from app.viewer.scene import PreparedCache
from app.viewer.server import ViewerServer

if TYPE_CHECKING:
    from app.planning.robots import MeshLimits

T = TypeVar("T")

logger = logging.getLogger(__name__)

#: Viewer playback updates per second.
VIEWER_FPS = 60.0


@dataclass
class Services:
    """Everything the routes use.

    Attributes:
        settings: the configuration the services run with.
        engine, sessions: the database.
        blobs: the file store.
        broker: job updates to SSE subscribers.
        jobs: submits, tracks and cancels jobs (the only writer of job rows).
        robots: built-in and uploaded robots.
        overlays: the recording detail page's analysis overlays.
        comparisons: finished plans and simulations prepared for the viewer and the Compare
            page (kept in memory, most recently used first).
        viewer: the 3-D viewer, once started.
        data_lock: this server's hold on its data directory (one server per folder).
        db_lock: this server's claim on its database (one server per database, whatever
            its data directory).
        streams: the caps on open event streams (``BIOPLAN_MAX_STREAMS*``, idle timeout).
        recordings_cache: cached ``GET /api/recordings`` pages.
        parse_slots: uploads parsed at once (``BIOPLAN_MAX_PARALLEL_PARSES``); the others wait
            their turn, so a burst of large uploads cannot take every worker thread from reads.
        started: ``time.monotonic()`` at start.
        parse_sandbox: where uploads are read (a child process with limits), None until started.
    """

    settings: Settings
    engine: Engine
    sessions: sessionmaker[Session]
    blobs: BlobStore
    broker: JobBroker
    jobs: JobService
    robots: RobotCatalog
    overlays: RecordingOverlays
    comparisons: PreparedCache
    viewer: ViewerServer | None = None
    data_lock: DataDirLock | None = None
    db_lock: DatabaseLock | None = None
    streams: StreamLimits = field(default_factory=StreamLimits)
    recordings_cache: ResponseCache = field(default_factory=ResponseCache)
    parse_slots: threading.BoundedSemaphore = field(
        default_factory=lambda: threading.BoundedSemaphore(2)
    )
    started: float = field(default_factory=time.monotonic)
    parse_sandbox: ParseSandbox | None = None

    def start_viewer(self) -> ViewerServer:
        """Start the viser viewer on ``settings.viewer_host``/``viewer_port``.

        viser takes the next free port when the one asked for is busy; ``viewer.port`` is the
        real one.
        """
        if self.viewer is None:
            settings = self.settings
            access = ViewerAccess(
                ttl_s=settings.viewer_token_ttl_s,
                max_connections=settings.viewer_max_connections,
                max_per_token=settings.viewer_max_per_token,
            )
            viewer = ViewerServer(
                self.comparisons,
                host=settings.viewer_host,
                port=settings.viewer_port,
                fps=VIEWER_FPS,
                access=access,
                origin_hosts=settings.allowed_hosts,
            )
            viewer.start()
            self.viewer = viewer
            logger.info("3-D viewer at %s", viewer.url)
        return self.viewer

    def database_revision(self) -> str | None:
        """The migration the database is at (None: not migrated)."""
        return current_revision(self.engine)

    def viewer_info(self) -> dict[str, object]:
        """Where the viewer listens (``GET /api/viewer``); ``enabled`` is false without one."""
        v = self.viewer
        if v is None or not v.running:
            return {"enabled": False, "url": None, "host": None, "port": None}
        return {"enabled": True, "url": v.url, "host": v.host, "port": v.port}


def read_meshes(limits: MeshLimits | None, fn: Callable[..., list[T]], *args: object) -> list[T]:
    """A robot's meshes parsed in the upload sandbox (memory and time limited), each mesh
    checked against ``limits`` (the server's mesh caps) first; a mesh set past the sandbox's
    limits is drawn without meshes (a warning in the log), never parsed in this process."""
    try:
        return sandbox.read_untrusted(_meshes_within, limits, fn, args, what="the robot's meshes")
    except ParseLimitError as exc:
        logger.warning("robot drawn without meshes: %s", exc)
        return []


def _meshes_within(
    limits: MeshLimits | None, fn: Callable[..., list[T]], args: tuple[object, ...]
) -> list[T]:
    """``fn(*args)`` in the child, with the server's mesh caps (the child was forked before
    the server set them)."""
    use_mesh_limits(limits)
    return fn(*args)


def start_services(settings: Settings, *, runner: JobRunner | None = None) -> Services:
    """Migrate, open the database and the file store, start and recover jobs.

    Args:
        settings: the configuration.
        runner: job runner to use instead of the one ``settings.executor`` names (tests).
    """
    data_lock = lock_data_dir(settings.data_dir)  # before anything touches the folder
    try:
        # Before migrating or recovering: another server on this database owns its jobs.
        db_lock = lock_database(settings.db_url, data_dir=settings.data_dir)
    except BaseException:
        data_lock.release()
        raise
    try:
        services = _start(settings, runner, data_lock)
    except BaseException:
        db_lock.release()
        data_lock.release()
        raise
    services.db_lock = db_lock
    return services


def _start(settings: Settings, runner: JobRunner | None, data_lock: DataDirLock) -> Services:
    upgrade(settings.db_url)
    engine = make_engine(settings.db_url)
    sessions = make_sessionmaker(engine)
    blobs = BlobStore(settings.blob_dir)
    # Results kept in the file store are read back through the session (``crud``'s load hook).
    sessions.configure(info={crud.BLOBS_KEY: blobs})
    with sessions() as session:
        removed = crud.collect_garbage(session=session, blobs=blobs)
    if removed:
        logger.warning("removed %d stored files no row referred to (interrupted writes)", removed)
    broker = JobBroker()
    robots = RobotCatalog(blobs=blobs, files_dir=settings.data_dir / "robots")
    jobs = JobService(
        sessions=sessions,
        blobs=blobs,
        runner=runner
        or make_runner(
            settings.executor,
            max_workers=settings.max_workers,
            time_limit=settings.job_time_limit_s,
            memory_mb=settings.job_memory_mb,
        ),
        limits=JobLimits.from_settings(settings),
        broker=broker,
        robots=robots,
        max_attempts=settings.job_max_attempts,
        max_video_seconds=settings.max_video_seconds,
        scratch_dir=settings.data_dir / "scratch" if settings.executor == "local" else None,
        max_queued=settings.max_queued,
        inline_result_bytes=int(settings.result_inline_kb * 1024),
    )
    jobs.start()
    # Uploads are read in a child process with limits from now on (after the runner set the
    # fork server's preload, so the child starts with the readers imported).
    parse_sandbox = ParseSandbox(memory_mb=settings.parse_memory_mb, seconds=settings.parse_seconds)
    sandbox.use(parse_sandbox)
    use_mesh_limits(mesh_limits(settings))  # the viewer never parses a mesh past them
    return Services(
        settings=settings,
        engine=engine,
        sessions=sessions,
        blobs=blobs,
        broker=broker,
        jobs=jobs,
        robots=robots,
        overlays=RecordingOverlays(sessions),
        comparisons=PreparedCache(
            ComparisonLoader(sessions, robots),
            human=HumanReplayLoader(sessions),
            mesh_reader=functools.partial(read_meshes, mesh_limits(settings)),
        ),
        data_lock=data_lock,
        parse_slots=threading.BoundedSemaphore(settings.max_parallel_parses),
        parse_sandbox=parse_sandbox,
        streams=StreamLimits(
            total=settings.max_streams,
            per_client=settings.max_streams_per_client,
            idle_s=settings.stream_idle_s,
        ),
    )


def stop_services(services: Services) -> None:
    """End the event streams, stop the viewer and the jobs (running ones go back to the
    queue), close the database."""
    services.broker.close_all()
    if services.parse_sandbox is not None:
        sandbox.release(services.parse_sandbox)
    use_mesh_limits(None)  # the library's defaults again (services of one process come and go)
    if services.viewer is not None:
        services.viewer.stop()
        services.viewer = None
    services.jobs.close()
    services.engine.dispose()
    if services.db_lock is not None:
        services.db_lock.release()
        services.db_lock = None
    if services.data_lock is not None:
        services.data_lock.release()
