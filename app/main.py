"""FastAPI application factory.

``create_app(settings)`` builds the app; its lifespan migrates the database (``alembic upgrade
head``), removes files a crash left unreferenced, starts the job runner and recovers the jobs a
previous server left queued or running, all before the first request is served. Run it with one
uvicorn worker (``bioplan serve``): the job runner and the viewer live in this process.
"""

from __future__ import annotations

import gc
import logging
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI
from starlette.concurrency import run_in_threadpool

from app import __version__
from app.api.deps import Services
from app.api.errors import install_error_handlers
from app.api.main import api_router
from app.config import Settings
from app.jobs.runner import JobRunner

logger = logging.getLogger(__name__)

#: Called with the services once they run; the dashboard uses it to start the viewer and fill
#: ``services.viewer``. Returns a callable run at shutdown (or None).
StartupHook = Callable[[Services], Callable[[], None] | None]


def start_services(settings: Settings, *, runner: JobRunner | None = None) -> Services:
    """Migrate, open the database and the file store, start and recover jobs."""
    from app.db import crud
    from app.db.blobs import BlobStore
    from app.db.session import make_engine, make_sessionmaker, upgrade
    from app.jobs.broker import JobBroker
    from app.jobs.runner import make_runner
    from app.jobs.service import JobService

    settings.data_dir.mkdir(parents=True, exist_ok=True)
    upgrade(settings.db_url)
    engine = make_engine(settings.db_url)
    sessions = make_sessionmaker(engine)
    blobs = BlobStore(settings.blob_dir)
    with sessions() as session:
        removed = crud.collect_garbage(session=session, blobs=blobs)
    if removed:
        logger.warning("removed %d stored files no row referred to (interrupted writes)", removed)
    broker = JobBroker()
    if runner is None:
        runner = make_runner(settings.executor, max_workers=settings.max_workers)
    jobs = JobService(
        sessions=sessions,
        blobs=blobs,
        runner=runner,
        broker=broker,
        max_attempts=settings.job_max_attempts,
    )
    jobs.start()
    viewer: dict[str, Any] = {}
    if settings.viewer_port:
        viewer = {
            "host": settings.viewer_host,
            "port": settings.viewer_port,
            "url": f"http://{settings.viewer_host}:{settings.viewer_port}",
        }
    return Services(
        settings=settings,
        engine=engine,
        sessions=sessions,
        blobs=blobs,
        broker=broker,
        jobs=jobs,
        viewer=viewer,
    )


def stop_services(services: Services) -> None:
    services.jobs.close()
    services.engine.dispose()


def create_app(
    settings: Settings | None = None,
    *,
    runner: JobRunner | None = None,
    hooks: tuple[StartupHook, ...] = (),
) -> FastAPI:
    """The BioPlan API.

    Args:
        settings: configuration (default: from ``BIOPLAN_*`` environment variables).
        runner: job runner to use instead of the one ``settings.executor`` names (tests).
        hooks: called after start-up with the services (e.g. to start the viewer).
    """
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        services = await run_in_threadpool(start_services, settings, runner=runner)
        app.state.services = services
        stops = [stop for hook in hooks if (stop := hook(services)) is not None]
        # Everything loaded so far lives as long as the server: keep it out of the cyclic
        # garbage collector's scans, which otherwise show up as latency spikes.
        gc.collect()
        gc.freeze()
        try:
            yield
        finally:
            for stop in reversed(stops):
                stop()
            await run_in_threadpool(stop_services, services)

    app = FastAPI(
        title="BioPlan API",
        version=__version__,
        description=(
            "Recordings of human lifts in, energy-efficient robot trajectories out. "
            "Writes need `Authorization: Bearer <token>` when the server has one. "
            "Errors are `application/problem+json`."
        ),
        lifespan=lifespan,
    )
    # The upload limit is enforced while the body streams in, not after it is buffered.
    install_error_handlers(app, max_body_bytes=settings.max_upload_bytes)
    if settings.cors_origins:
        from fastapi.middleware.cors import CORSMiddleware

        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.cors_origins,
            allow_methods=["GET", "POST", "DELETE"],
            allow_headers=["Authorization", "Content-Type"],
        )
    app.include_router(api_router)
    return app
