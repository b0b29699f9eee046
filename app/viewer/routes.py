"""Dashboard routes under ``/api/viewer/...``: assets, comparison curves, exports, the analysis
series of a recording, and the viewer's tabs.

The service's own routes (``app.api``) stay as they are; these only read. ``GET /api/viewer``
(the viewer's address) belongs to the service and reports what the dashboard filled in.
"""

from __future__ import annotations

import functools
import hashlib
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

from fastapi import APIRouter, Query, Request, Response
from fastapi import Path as PathParam
from fastapi.responses import FileResponse

from app.api.errors import ApiError

if TYPE_CHECKING:
    from app.viewer.dashboard import DashboardState

_PROBLEMS: dict[int | str, dict[str, Any]] = {
    code: {"description": desc, "content": {"application/problem+json": {}}}
    for code, desc in (
        (404, "not found"),
        (409, "not finished"),
        (422, "invalid request"),
        (503, "dashboard not running"),
    )
}
router = APIRouter(prefix="/api/viewer", tags=["viewer"], responses=_PROBLEMS)

ComparisonKind = Literal["plan", "simulation"]
#: Ids in paths, as the service's routes take them (positive 32-bit integers).
IdPath = Annotated[int, PathParam(ge=1, le=2**31 - 1)]


def _state(request: Request) -> DashboardState:
    state: DashboardState | None = getattr(request.app.state, "dashboard", None)
    if state is None or state.prepared is None:
        raise ApiError(503, "the dashboard is not running (the app's lifespan has not started)")
    return state


@functools.cache
def plotly_js_path() -> Path:
    """plotly.min.js as shipped inside the installed ``plotly`` Python package."""
    import plotly

    path = Path(plotly.__file__).resolve().parent / "package_data" / "plotly.min.js"
    if not path.is_file():
        raise FileNotFoundError(f"plotly.min.js is missing from the plotly package at {path}")
    return path


@functools.cache
def _etag(path: Path) -> str:
    stat = path.stat()
    return hashlib.sha256(f"{path}:{stat.st_size}:{stat.st_mtime_ns}".encode()).hexdigest()[:20]


@router.get(
    "/assets/plotly.min.js",
    response_class=FileResponse,
    responses={200: {"content": {"text/javascript": {}}, "description": "Plotly.js"}},
)
def plotly_js(request: Request) -> Response:
    """Plotly.js from the installed ``plotly`` package (no CDN: the dashboard works offline)."""
    path = plotly_js_path()
    etag = f'"{_etag(path)}"'
    headers = {"Cache-Control": "public, max-age=86400", "ETag": etag}
    if request.headers.get("if-none-match") == etag:
        return Response(status_code=304, headers=headers)
    return FileResponse(path, media_type="text/javascript", headers=headers)


def _comparison_error(kind: str, result_id: int, exc: LookupError) -> ApiError:
    text = str(exc.args[0]) if exc.args else str(exc)
    status = 404 if "does not exist" in text or "unknown" in text else 409
    return ApiError(status, text)


@router.get("/comparisons/{kind}/{result_id}", response_model=dict[str, Any])
def comparison(
    request: Request,
    kind: ComparisonKind,
    result_id: IdPath,
    points: Annotated[int, Query(ge=2, le=20000, description="samples per curve")] = 400,
) -> dict[str, Any]:
    """A finished plan's or simulation's curves per joint (SI units), phases, metrics, floors,
    and where the 3-D viewer shows it."""
    state = _state(request)
    assert state.prepared is not None
    try:
        prepared = state.prepared(kind, result_id)
    except LookupError as exc:
        raise _comparison_error(kind, result_id, exc) from None
    c = prepared.comparison
    out = c.summary()
    out["curves"] = c.curves(points=points)
    out["result"] = c.result
    viewer = state.viewer
    out["viewer"] = (
        {
            "enabled": True,
            "port": viewer.port,
            "host": viewer.host,
            "path": f"/bioplan/{kind}/{result_id}",
            "url": viewer.client_url(kind, result_id),
        }
        if viewer is not None and viewer.running
        else {"enabled": False}
    )
    out["exports"] = {
        fmt: f"/api/viewer/comparisons/{kind}/{result_id}/export?format={fmt}"
        for fmt in ("scene", "report")
    }
    return out


@router.get(
    "/comparisons/{kind}/{result_id}/export",
    response_class=Response,
    responses={200: {"content": {"text/html": {}}, "description": "a self-contained HTML file"}},
)
def export(
    request: Request,
    kind: ComparisonKind,
    result_id: IdPath,
    format: Annotated[
        Literal["scene", "report"],
        Query(description="scene: 3-D animation (viser); report: curves and metrics (Plotly)"),
    ] = "scene",
    layout: Literal["ghost", "side_by_side"] = "ghost",
) -> Response:
    """A file that opens without the server: the recorded 3-D comparison, or the report."""
    from app.viewer.export import report_html, scene_html

    state = _state(request)
    assert state.prepared is not None
    try:
        prepared = state.prepared(kind, result_id)
    except LookupError as exc:
        raise _comparison_error(kind, result_id, exc) from None
    if format == "scene":
        page = scene_html(prepared, layout=layout)
    else:
        page = report_html(prepared.comparison)
    name = f"bioplan-{kind}-{result_id}-{format}.html"
    return Response(
        page,
        media_type="text/html; charset=utf-8",
        headers={"Content-Disposition": f'attachment; filename="{name}"'},
    )


@router.get("/recordings/{recording_id}/analysis", response_model=dict[str, Any])
def recording_analysis(
    request: Request,
    recording_id: IdPath,
    points: Annotated[int, Query(ge=2, le=100000, description="samples per series")] = 2000,
    t0: Annotated[float | None, Query(description="window start [s]")] = None,
    t1: Annotated[float | None, Query(description="window end [s]")] = None,
) -> dict[str, Any]:
    """The plot overlays of the newest finished analysis of a recording: envelopes with onsets,
    shoulder/elbow angles and velocities [deg, deg/s], lifts with their A/B/C phases and the
    human template, downsampled to ``points`` samples per series within the window [t0, t1].

    409 while the recording has no finished analysis; the problem's ``job`` is the analysis job
    to follow (queued or running), the one that failed, or null when none was submitted.
    """
    from app.viewer.signals import AnalysisPending, SignalsError

    state = _state(request)
    for name, value in (("t0", t0), ("t1", t1)):
        if value is not None and not math.isfinite(value):
            raise ApiError(422, f"{name} must be a finite time in seconds", field=name)
    if t0 is not None and t1 is not None and t1 <= t0:
        raise ApiError(422, f"t1 ({t1}) must be after t0 ({t0})", field="t1")
    try:
        analysis_id, overlays = state.signals.get(state.services(), recording_id)
    except SignalsError as exc:
        raise ApiError(404, str(exc)) from None
    except AnalysisPending as exc:
        raise ApiError(409, str(exc), title="No analysis yet", extra={"job": exc.job}) from None
    return {
        "recording_id": recording_id,
        "analysis_id": analysis_id,
        **overlays.window(points=points, t0=t0, t1=t1),
    }


@router.get("/sessions", response_model=list[dict[str, Any]])
def sessions(request: Request) -> list[dict[str, Any]]:
    """The viewer's open tabs: which comparison, playing or not, redraws per second."""
    state = _state(request)
    return [] if state.viewer is None else state.viewer.sessions()
