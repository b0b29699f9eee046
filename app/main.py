"""FastAPI application factory.

``create_app(settings)`` builds the whole server: the API routes, the dashboard's pages (from the
package, or ``Settings.frontend_dir``), the error handlers and middleware. Its lifespan starts
the services before the first request is served (``app.services.start_services``: migrate the
database, remove files a crash left unreferenced, start the job runner, recover the jobs a
previous server left queued or running) and then the 3-D viewer, and stops them in reverse.
Run it with one uvicorn worker (``bioplan serve``): the job runner and the viewer live in this
process.
"""

from __future__ import annotations

import gc
import logging
import threading
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI
from starlette.concurrency import run_in_threadpool
from starlette.staticfiles import StaticFiles

from app import __version__
from app.api.errors import install_error_handlers
from app.api.main import api_router
from app.api.middleware import install_middleware
from app.api.offline_docs import install_offline_docs
from app.config import Settings
from app.jobs.runner import JobRunner
from app.services import Services, start_services, stop_services
from app.services.limits import REQUEST_FIELDS, JobLimits, state_export_limit

logger = logging.getLogger(__name__)


def _warm_viewer_imports() -> None:
    # yourdfpy pulls in trimesh (about a second): import it before the first tab needs it.
    import yourdfpy  # type: ignore[import-untyped]  # noqa: F401


def _start(settings: Settings, runner: JobRunner | None) -> Services:
    services = start_services(settings, runner=runner)
    if settings.viewer:
        try:
            services.start_viewer()
        except BaseException:
            stop_services(services)
            raise
        threading.Thread(target=_warm_viewer_imports, name="bioplan-viewer-warmup").start()
    return services


def _pages(settings: Settings) -> StaticFiles:
    folder = settings.pages_dir
    if not (folder / "index.html").is_file():
        raise FileNotFoundError(
            f"the dashboard's pages are missing: no index.html in {folder} "
            "(BIOPLAN_FRONTEND_DIR, or reinstall the package)"
        )
    return StaticFiles(directory=folder, html=True)


def _document_server(app: FastAPI, settings: Settings) -> None:
    """The OpenAPI document says what this server does: without ``BIOPLAN_API_TOKEN`` a write
    needs no token (each bearer requirement gets an empty alternative), and a job's
    ``particles``, ``iterations``, ``n_samples`` and ``workers`` go no higher than this
    server's caps (``BIOPLAN_MAX_*``), so a client learns them before it is refused."""
    build = app.openapi
    limits = JobLimits.from_settings(settings)

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = build()
            if settings.token is None:
                _writes_need_no_token(schema)
            _state_job_limits(schema, limits)
            state_export_limit(schema, settings.max_export_samples)
            _forms_have_no_null(schema)
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]


def _writes_need_no_token(schema: dict[str, Any]) -> None:
    for path in schema.get("paths", {}).values():
        for operation in path.values():
            if isinstance(operation, dict) and operation.get("security"):
                operation["security"] = [*operation["security"], {}]


def _forms_have_no_null(schema: dict[str, Any]) -> None:
    """A form field is sent or left out; it cannot be ``null`` (the text "null" is no file and
    no number), so an optional form field's schema is its one non-null type."""
    components = schema.get("components", {}).get("schemas", {})
    for path in schema.get("paths", {}).values():
        for operation in path.values():
            content = (operation.get("requestBody") or {}).get("content", {})
            ref = content.get("multipart/form-data", {}).get("schema", {}).get("$ref", "")
            body = components.get(ref.rpartition("/")[2], {})
            for name, prop in body.get("properties", {}).items():
                kept = [b for b in prop.get("anyOf", []) if b.get("type") != "null"]
                if len(kept) == 1:
                    del prop["anyOf"]
                    body["properties"][name] = {**kept[0], **prop}


def _state_job_limits(schema: dict[str, Any], limits: JobLimits) -> None:
    """Lower each request field's ``maximum`` (and a higher default) to the configured cap
    of the same name (``JobLimits.fit`` lowers a left-out field the same way)."""
    for name, body in schema.get("components", {}).get("schemas", {}).items():
        if not name.endswith("Request"):
            continue
        for field, prop in body.get("properties", {}).items():
            cap = getattr(limits, field) if field in REQUEST_FIELDS else None
            if cap is None:
                continue
            for branch in prop.get("anyOf", [prop]):
                if branch.get("type") == "integer":
                    branch["maximum"] = min(branch.get("maximum", cap), cap)
            if isinstance(prop.get("default"), int) and prop["default"] > cap:
                prop["default"] = cap  # what a request that leaves it out gets here


def create_app(settings: Settings | None = None, *, runner: JobRunner | None = None) -> FastAPI:
    """The BioPlan server: API, dashboard pages, and (in its lifespan) jobs and viewer.

    Args:
        settings: configuration (default: from ``BIOPLAN_*`` environment variables).
        runner: job runner to use instead of the one ``settings.executor`` names (tests).

    Raises:
        FileNotFoundError: the dashboard's pages are missing.
    """
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        services = await run_in_threadpool(_start, settings, runner)
        app.state.services = services
        # Everything loaded so far lives as long as the server: keep it out of the cyclic
        # garbage collector's scans, which otherwise show up as latency spikes.
        gc.collect()
        gc.freeze()
        try:
            yield
        finally:
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
        docs_url=None,  # /docs and /redoc with their scripts served from the package
        redoc_url=None,
    )
    install_offline_docs(app)
    install_error_handlers(app)
    install_middleware(app, settings)
    app.include_router(api_router)
    _document_server(app, settings)
    # After every API route, so /api/... never falls through to a page.
    app.mount("/", _pages(settings), name="dashboard")
    return app
