"""Pareto fronts: submit (202 + job), list, fetch, rename, delete, the front as CSV, one
point's trajectory as a file, and the viewer address that plays a point."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Response
from sqlalchemy.orm import Session

from app.api.deps import ServicesDep, SessionDep
from app.api.routes._common import (
    EXPORT_RESPONSES,
    PROBLEM_RESPONSES,
    ExportOptions,
    FormatQuery,
    IdPath,
    RateQuery,
    export_response,
    file_answer,
)
from app.api.routes._results import ResultRoutes, add_result_routes
from app.api.schemas import FrontRequest, left_out
from app.services import Services
from app.services.fronts import (
    export_point,
    finished_front,
    front_csv,
    point_view,
    public_front,
    submit_front,
)

router = APIRouter(prefix="/api/fronts", tags=["fronts"], responses=PROBLEM_RESPONSES)

#: A point's id in its front (``p0``, ``p1``, ...) or ``quintic`` (the reference).
PointPath = Annotated[
    str,
    Path(
        pattern=r"^[a-z][a-z0-9_]{0,31}$",
        description="a point's id (p0, p1, ...; the result's methods list them)",
    ),
]


def _submit(body: FrontRequest, session: Session, services: Services) -> dict[str, object]:
    return submit_front(
        services,
        session,
        body.model_dump(mode="json", exclude={"label"}),
        label=body.label,
        left_out=left_out(body),
    )


def _public(session: Session, item: dict[str, object]) -> dict[str, object]:
    return {**item, "result": public_front(item["result"])}


_SUBMIT_DOC = """Queue a Pareto front (``bioplan front``); progress is reported per point (stage
``front``), then the references (the quintic, the paper's and the jerk-limited method at
the front's duration)."""
_GET_DOC = """The front (``bioplan front --json``) with ``references`` (the quintic's, the paper's
and the jerk-limited method's metrics, or their ``error``) and ``methods`` (the ids a
point's view and export take)."""
_ARRAYS_DOC = """Every point's and reference's trajectory on its own time grid: ``<id>_t`` [s],
``<id>_q``, ``_qd``, ``_qdd``, ``_tau`` [SI], ``_power`` [W], ``_energy`` [J]."""


_DOCS = {"submit": _SUBMIT_DOC, "get": _GET_DOC, "arrays": _ARRAYS_DOC}
_NAMES = {"submit": "post_front", "list": "get_fronts", "relabel": "patch_front"}
add_result_routes(
    router,
    ResultRoutes(
        "front", shape=_public, submit=_submit, request=FrontRequest,
        label=True, arrays=True, delete=True, names=_NAMES, docs=_DOCS,
    ),
)  # fmt: skip


@router.get("/{front_id:int}/csv", **file_answer("text/csv", "one row per point"))
def get_front_csv(session: SessionDep, front_id: IdPath) -> Response:
    """The front as CSV: ``id, A, B, every other metric, human_likeness, knee, end``."""
    return Response(
        front_csv(finished_front(session, front_id)),
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="bioplan-front-{front_id}.csv"'},
    )


@router.get(
    "/{front_id:int}/points/{pid}/export",
    response_class=Response,
    responses=EXPORT_RESPONSES,
)
def export_front_point(
    services: ServicesDep,
    session: SessionDep,
    front_id: IdPath,
    pid: PointPath,
    format: FormatQuery,
    options: ExportOptions,
    rate: RateQuery = None,
) -> Response:
    """Point ``pid``'s trajectory as a file, as a plan's (``GET /api/plans/{id}/trajectory``):
    the same formats, options and limit and safety gates."""
    out = export_point(session, services, front_id, pid, fmt=format, rate=rate, **options)
    return export_response(out, format)


@router.get("/{front_id:int}/points/{pid}/view", response_model=dict[str, object])
def view_front_point(
    services: ServicesDep, session: SessionDep, front_id: IdPath, pid: PointPath
) -> dict[str, object]:
    """Point ``pid`` and where the 3-D viewer plays it (solid) beside the quintic at the same
    duration: ``{"point", "viewer": {"enabled", "url", "path", "host", "port"}}``."""
    return point_view(services, session, front_id, pid)
