"""Health, version, the shared names and the viewer's address."""

from __future__ import annotations

import platform
import shutil
import time
from typing import Any

from fastapi import APIRouter, Request
from sqlalchemy import text

from app import __version__, names
from app.api.deps import ServicesDep
from app.api.result_models import MetaOut
from app.api.schemas import Health, Version, ViewerInfo
from app.config import Settings
from app.services.robots import data_usage

router = APIRouter(prefix="/api", tags=["service"])


@router.get("/health", response_model=Health)
def health(services: ServicesDep) -> dict[str, Any]:
    """Liveness and readiness: database reachable, free disk, job executor and its workers."""
    try:
        with services.engine.connect() as conn:
            conn.execute(text("SELECT 1"))
        database = "ok"
    except Exception as exc:  # report, do not fail: this endpoint must answer
        database = f"unreachable: {type(exc).__name__}"
    info = services.jobs.runner.info()
    disk = _disk(services.settings)
    healthy = database == "ok" and disk is not None and disk["ok"]
    return {
        "status": "ok" if healthy else "degraded",
        "database": database,
        "disk": disk,
        "executor": info["executor"],
        "workers": info.get("workers"),
        "running": info.get("running"),
        "queued": info.get("queued"),
        "uptime_seconds": time.monotonic() - services.started,
    }


#: Seconds a measure of the data directory's size is reused (health is polled).
USAGE_MAX_AGE_S = 10.0


def _disk(settings: Settings) -> dict[str, Any] | None:
    try:
        usage = shutil.disk_usage(settings.data_dir)
    except OSError:
        return None
    free_mb, total_mb = usage.free / 1e6, usage.total / 1e6
    used_mb = data_usage(settings.data_dir, max_age_s=USAGE_MAX_AGE_S) / (1024 * 1024)
    quota_mb = settings.data_quota_mb
    return {
        "free_mb": free_mb,
        "total_mb": total_mb,
        "used_mb": used_mb,
        "quota_mb": quota_mb,
        "ok": free_mb >= settings.min_free_mb and used_mb < quota_mb,
    }


@router.get("/version", response_model=Version)
def version(services: ServicesDep) -> dict[str, Any]:
    return {
        "version": __version__,
        "database_revision": services.database_revision(),
        "python": platform.python_version(),
    }


@router.get("/meta", response_model=MetaOut)
def meta() -> dict[str, Any]:
    """The names every page shares (``app.names``): metrics with units and formulas, the A/B/C
    phases with bounds and colours, planning methods, muscle colours, PSO defaults, job states,
    the axes a front trades with their words, and the physical floors' formulas (the pages
    print them, never write them).
    """
    return names.as_json()


#: The request bodies whose fields the pages fill, by the pages' name for them.
_FORMS = {
    "plan": "PlanRequest",
    "simulation": "SimulationRequest",
    "sweep": "SweepRequest",
    "front": "FrontRequest",
    "analysis": "AnalysisRequest",
    "recording_patch": "RecordingPatch",
    "upload": "Body_upload_recording_api_recordings_post",
}
_BOUNDS = ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum")


@router.get("/caps", response_model=dict[str, dict[str, dict[str, float]]])
def caps(request: Request) -> dict[str, dict[str, dict[str, float]]]:
    """The numeric bounds of the fields the pages fill, as this server enforces them
    (``BIOPLAN_MAX_*`` included): form -> field -> ``minimum``/``maximum``/``exclusive...``.
    The pages show each cap beside its field, so a value is not refused unannounced."""
    schemas = request.app.openapi().get("components", {}).get("schemas", {})
    out: dict[str, dict[str, dict[str, float]]] = {}
    for form, schema in _FORMS.items():
        fields = {}
        for name, prop in schemas.get(schema, {}).get("properties", {}).items():
            options = [prop, *prop.get("anyOf", [])]
            bounds = {b: float(o[b]) for o in options for b in _BOUNDS if b in o}
            if bounds:
                fields[name] = bounds
        out[form] = fields
    return out


@router.get("/viewer", response_model=ViewerInfo)
def viewer(services: ServicesDep) -> dict[str, Any]:
    """The 3-D viewer's URL and port; ``enabled`` is false until a viewer runs."""
    return services.viewer_info()
