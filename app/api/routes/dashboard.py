"""The dashboard's data under ``/api/viewer/...``: Plotly.js, comparison curves, exports, a
recording's analysis overlays, and the viewer's tabs. These only read.

``GET /api/viewer`` (the viewer's address) is in ``meta``; the pages themselves are mounted at
``/`` by ``app.main.create_app``.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import FileResponse

from app.api.deps import ServicesDep
from app.api.errors import ApiError
from app.api.result_models import ComparisonView
from app.api.routes._common import MAX_POINTS, PROBLEM_RESPONSES, IdPath, file_answer
from app.names import METHODS
from app.services.comparisons import comparison_data, comparison_file, prepare_comparison
from app.services.results import with_joint_power

router = APIRouter(prefix="/api/viewer", tags=["viewer"], responses=PROBLEM_RESPONSES)

ComparisonKind = Literal["plan", "simulation"]


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


@router.get("/assets/plotly.min.js", **file_answer("text/javascript", "Plotly.js", FileResponse))
def plotly_js(request: Request) -> Response:
    """Plotly.js from the installed ``plotly`` package (no CDN: the dashboard works offline);
    gzip-compressed once (4.8 MB -> about 1.4 MB) for browsers that accept it, cached by ETag."""
    path = plotly_js_path()
    etag = f'"{_etag(path)}"'
    headers = {"Cache-Control": "public, max-age=86400", "ETag": etag, "Vary": "Accept-Encoding"}
    if request.headers.get("if-none-match") == etag:
        return Response(status_code=304, headers=headers)
    if "gzip" in request.headers.get("accept-encoding", "").lower():
        return Response(
            _gzipped(path),
            media_type="text/javascript",
            headers={**headers, "Content-Encoding": "gzip"},
        )
    return FileResponse(path, media_type="text/javascript", headers=headers)


@functools.cache
def _gzipped(path: Path) -> bytes:
    import gzip

    return gzip.compress(path.read_bytes(), compresslevel=6, mtime=0)


#: Every ``a,b`` of two different methods: the schema lists them, so a client (or a fuzzer)
#: knows ``bound,bound`` and ``quintic,warp`` are no pair before asking.
METHOD_PAIRS = tuple(f"{a},{b}" for a, b in itertools.permutations(METHODS, 2))

if TYPE_CHECKING:
    MethodPair = str
else:
    MethodPair = Literal[METHOD_PAIRS]

MethodsQuery = Annotated[
    MethodPair | None,
    Query(
        description="two different planned methods shown as standard,optimized (default: "
        "quintic,paper, or the quintic and the first other planned method when the result "
        "has no paper's method); a method the result did not plan is a 404 naming this field",
        examples=["quintic,bound"],
    ),
]


def method_pair(methods: str | None) -> tuple[str, str] | None:
    """``"a,b"`` (one of ``METHOD_PAIRS``) as the two method names."""
    if methods is None:
        return None
    a, b = methods.split(",")
    return a, b


@router.get(
    "/comparisons/{kind}/{result_id:int}",
    response_model=ComparisonView,
    response_model_exclude_unset=True,
)
def comparison(
    services: ServicesDep,
    kind: ComparisonKind,
    result_id: IdPath,
    points: Annotated[int, Query(ge=2, le=MAX_POINTS, description="samples per curve")] = 400,
    methods: MethodsQuery = None,
) -> dict[str, object]:
    """A finished plan's or simulation's curves per joint (SI units), phases, metrics, floors,
    and where the 3-D viewer shows it. ``methods=a,b`` shows any two planned methods as
    ``standard`` (a) and ``optimized`` (b); ``summary.methods`` says which."""
    pair = method_pair(methods)
    prepared = prepare_comparison(services.comparisons, kind, result_id, pair)
    out = comparison_data(prepared, points)
    out["curves"] = with_joint_power(out["curves"], prepared.comparison, points)
    viewer = services.viewer
    out["viewer"] = (
        {
            "enabled": True,
            "port": viewer.port,
            "host": viewer.host,
            "path": f"/bioplan/{kind}/{result_id}",
            "url": viewer.client_url(kind, result_id, pair),
        }
        if viewer is not None and viewer.running
        else {"enabled": False}
    )
    suffix = "" if pair is None else f"&methods={pair[0]},{pair[1]}"
    out["exports"] = {
        fmt: f"/api/viewer/comparisons/{kind}/{result_id}/export?format={fmt}{suffix}"
        for fmt in ("scene", "report")
    }
    return out


@router.get(
    "/comparisons/{kind}/{result_id:int}/export",
    **file_answer("text/html", "a self-contained HTML file"),
)
def export(
    services: ServicesDep,
    kind: ComparisonKind,
    result_id: IdPath,
    format: Annotated[
        Literal["scene", "report"],
        Query(description="scene: 3-D animation (viser); report: curves and metrics (Plotly)"),
    ] = "scene",
    layout: Annotated[
        Literal["ghost", "side_by_side"],
        Query(description="scene: the robots side by side (as the live viewer) or overlaid"),
    ] = "side_by_side",
    methods: MethodsQuery = None,
) -> Response:
    """A file that opens without the server: the recorded 3-D comparison, or the report."""
    prepared = prepare_comparison(services.comparisons, kind, result_id, method_pair(methods))
    page = comparison_file(prepared, format, layout)
    name = f"bioplan-{kind}-{result_id}-{format}.html"
    return Response(
        page,
        media_type="text/html; charset=utf-8",
        headers={"Content-Disposition": f'attachment; filename="{name}"'},
    )


@router.get("/recordings/{recording_id:int}/analysis", response_model=dict[str, object])
def recording_analysis(
    services: ServicesDep,
    recording_id: IdPath,
    points: Annotated[int, Query(ge=2, le=MAX_POINTS, description="samples per series")] = 2000,
    t0: Annotated[float | None, Query(description="window start [s]")] = None,
    t1: Annotated[float | None, Query(description="window end [s]")] = None,
) -> dict[str, object]:
    """The plot overlays of the newest finished analysis of a recording: envelopes with onsets,
    shoulder/elbow angles and velocities [deg, deg/s], lifts with their A/B/C phases and the
    human template, downsampled to ``points`` samples per series within the window [t0, t1].

    409 while the recording has no finished analysis; the problem's ``job`` is the analysis job
    to follow (queued or running), the one that failed, or null when none was submitted.
    """
    for name, value in (("t0", t0), ("t1", t1)):
        if value is not None and not math.isfinite(value):
            raise ApiError(422, f"{name} must be a finite time in seconds", field=name)
    if t0 is not None and t1 is not None and t1 < t0:
        raise ApiError(422, f"t1 ({t1}) must not be before t0 ({t0})", field="t1")
    analysis_id, overlays = services.overlays.get(recording_id)
    return {
        "recording_id": recording_id,
        "analysis_id": analysis_id,
        **overlays.window(points=points, t0=t0, t1=t1),
    }


@router.get("/sessions", response_model=list[dict[str, object]])
def sessions(services: ServicesDep) -> list[dict[str, object]]:
    """The viewer's open tabs: which comparison, playing or not, redraws per second."""
    return [] if services.viewer is None else services.viewer.sessions()
