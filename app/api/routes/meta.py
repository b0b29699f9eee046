"""Health, version and the viewer's address."""

from __future__ import annotations

import functools
import platform
import time
from typing import Any

from fastapi import APIRouter
from sqlalchemy import text

from app import __version__
from app.api.deps import ServicesDep
from app.api.schemas import Health, Version, ViewerInfo
from app.db.session import current_revision

router = APIRouter(prefix="/api", tags=["service"])


@functools.cache
def _entry_points() -> dict[str, bool]:
    from app.jobs.tasks import entry_points

    return entry_points()


@router.get("/health", response_model=Health)
def health(services: ServicesDep) -> dict[str, Any]:
    """Liveness and readiness: database reachable, job executor and its workers."""
    try:
        with services.engine.connect() as conn:
            conn.execute(text("SELECT 1"))
        database = "ok"
    except Exception as exc:  # report, do not fail: this endpoint must answer
        database = f"unreachable: {type(exc).__name__}"
    info = services.jobs.runner.info()
    return {
        "status": "ok" if database == "ok" else "degraded",
        "database": database,
        "executor": info["executor"],
        "workers": info.get("workers"),
        "running": info.get("running"),
        "queued": info.get("queued"),
        "entry_points": _entry_points(),
        "uptime_seconds": time.monotonic() - services.started,
    }


@router.get("/version", response_model=Version)
def version(services: ServicesDep) -> dict[str, Any]:
    return {
        "version": __version__,
        "database_revision": current_revision(services.engine),
        "python": platform.python_version(),
    }


@router.get("/viewer", response_model=ViewerInfo)
def viewer(services: ServicesDep) -> dict[str, Any]:
    """The 3-D viewer's URL and port; ``enabled`` is false until a viewer runs."""
    v = services.viewer
    return {
        "enabled": bool(v.get("port")),
        "url": v.get("url"),
        "host": v.get("host"),
        "port": v.get("port"),
    }
