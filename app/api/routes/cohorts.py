"""Cohorts: submit (202 + job), list, fetch, delete, the per-recording table as CSV, and the
options a comparison takes (from ``CohortOptions``)."""

from __future__ import annotations

import contextlib
from typing import Annotated, Any

from fastapi import APIRouter, Query, Response

from app.api.deps import ServicesDep, SessionDep, WriteAccess
from app.api.errors import ApiError
from app.api.routes._common import PROBLEM_RESPONSES, IdPath
from app.api.schemas import CohortOptionInfo, CohortOut, CohortRequest, Job, JobState, Page
from app.services.cohorts import cohort_csv, cohort_option_info, cohort_params
from app.services.errors import ConflictError
from app.services.results import delete_job, get_result_row, job_of, list_results

router = APIRouter(prefix="/api/cohorts", tags=["cohorts"], responses=PROBLEM_RESPONSES)


@router.post("", status_code=202, response_model=Job, dependencies=[WriteAccess])
def submit_cohort(
    body: CohortRequest, session: SessionDep, services: ServicesDep, response: Response
) -> dict[str, Any]:
    """Queue a comparison of groups of stored recordings (``bioplan cohort``): explicit
    ``groups`` of recording ids, or the recordings grouped by their condition. Progress is
    reported per recording file. A missing recording is a 404 naming the field; a recording
    in two groups a 422; a recording without a condition or anything to measure, or fewer
    than two conditions, a 409. Nothing is stored for a refused request."""
    params = cohort_params(session, body.model_dump(mode="json", exclude={"label"}))
    job = services.jobs.submit(kind="cohort", params=params, resource={}, label=body.label)
    response.headers["Location"] = job["result_url"]
    return job


@router.get("/options", response_model=list[CohortOptionInfo])
def cohort_options() -> list[dict[str, Any]]:
    """Every option of a comparison with its default, help, unit, choices and range."""
    return cohort_option_info()


def _out(item: dict[str, Any]) -> dict[str, Any]:
    return {**item, "groups": item["job"]["params"].get("groups") or {}}


@router.get("", response_model=Page[CohortOut])
def list_cohorts(
    session: SessionDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
    state: JobState | None = None,
) -> dict[str, Any]:
    """Cohort comparisons, newest first."""
    items, total = list_results(session, "cohort", limit=limit, offset=offset, state=state)
    return {"items": [_out(i) for i in items], "total": total, "limit": limit, "offset": offset}


@router.get("/{cohort_id:int}", response_model=CohortOut)
def get_cohort(session: SessionDep, cohort_id: IdPath) -> dict[str, Any]:
    row = get_result_row(session, "cohort", cohort_id)
    job = job_of(session, row.id)
    return _out({"id": row.id, "label": job["label"], "job": job, "result": row.result})


@router.get(
    "/{cohort_id:int}/csv",
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}, "description": "one row per recording"}},
)
def get_cohort_csv(session: SessionDep, cohort_id: IdPath) -> Response:
    """One row per measured recording: recording id, group, file, subject, every measure."""
    row = get_result_row(session, "cohort", cohort_id)
    if row.result is None:
        state = job_of(session, row.id)["state"]
        raise ApiError(409, f"cohort {cohort_id} has no result (job state {state})")
    return Response(
        cohort_csv(row.result),
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="cohort-{cohort_id}.csv"'},
    )


@router.delete("/{cohort_id:int}", status_code=204, dependencies=[WriteAccess])
def delete_cohort(services: ServicesDep, session: SessionDep, cohort_id: IdPath) -> Response:
    """Delete a comparison (its job and result); one still queued or running is cancelled
    first."""
    get_result_row(session, "cohort", cohort_id)  # 404 when there is none
    if job_of(session, cohort_id)["state"] in ("queued", "running"):
        with contextlib.suppress(ConflictError):  # it ended meanwhile
            services.jobs.cancel(cohort_id)
    if not delete_job(session, services.blobs, cohort_id):
        raise ApiError(404, f"cohort {cohort_id} does not exist")
    return Response(status_code=204)
