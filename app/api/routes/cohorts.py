"""Cohorts: submit (202 + job), list, fetch, delete, the per-recording table as CSV, and the
options a comparison takes (from ``CohortOptions``)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Response
from sqlalchemy.orm import Session

from app.api.deps import SessionDep
from app.api.result_models import CohortResultOut
from app.api.routes._common import PROBLEM_RESPONSES, IdPath, file_answer
from app.api.routes._results import ResultRoutes, add_result_routes
from app.api.schemas import CohortOptionInfo, CohortRequest
from app.services import Services
from app.services.cohorts import cohort_csv, cohort_option_info, cohort_params
from app.services.job_views import not_finished
from app.services.results import get_result_row

router = APIRouter(prefix="/api/cohorts", tags=["cohorts"], responses=PROBLEM_RESPONSES)


@router.get("/options", response_model=list[CohortOptionInfo])
def cohort_options() -> list[dict[str, object]]:
    """Every option of a comparison with its default, help, unit, choices and range."""
    return cohort_option_info()


def _out(session: Session, item: dict[str, Any]) -> dict[str, Any]:
    return {**item, "groups": item["job"]["params"].get("groups") or {}}


def _submit(body: CohortRequest, session: Session, services: Services) -> dict[str, object]:
    params = cohort_params(session, body.model_dump(mode="json", exclude={"label"}))
    return services.jobs.submit(kind="cohort", params=params, resource={}, label=body.label)


@router.get("/{cohort_id:int}/csv", **file_answer("text/csv", "one row per recording"))
def get_cohort_csv(session: SessionDep, cohort_id: IdPath) -> Response:
    """One row per measured recording: recording id, group, file, subject, every measure."""
    row = get_result_row(session, "cohort", cohort_id)
    if row.result is None:
        raise not_finished(session, row.id, f"cohort {cohort_id}")
    return Response(
        cohort_csv(row.result),
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="cohort-{cohort_id}.csv"'},
    )


_SUBMIT_DOC = """Queue a comparison of groups of stored recordings (``bioplan cohort``): explicit
``groups`` of recording ids, or the recordings grouped by their condition. Progress is
reported per recording file. A missing recording is a 404 naming the field; a recording
in two groups a 422; a recording without a condition or anything to measure, or fewer
than two conditions, a 409. Nothing is stored for a refused request."""
_LIST_DOC = "Cohort comparisons, newest first."
_DELETE_DOC = """Delete a comparison (its job and result); one still queued or running is cancelled
first."""


_DOCS = {"submit": _SUBMIT_DOC, "list": _LIST_DOC, "delete": _DELETE_DOC}
add_result_routes(
    router,
    ResultRoutes(
        "cohort", response_model=CohortResultOut, shape=_out, submit=_submit, request=CohortRequest,
        delete=True, docs=_DOCS,
    ),
)  # fmt: skip
