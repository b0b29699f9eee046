"""Sweeps: submit (202 + job), list, fetch results."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Response

from app.api.deps import ServicesDep, SessionDep, WriteAccess
from app.api.routes._common import PROBLEM_RESPONSES, IdPath
from app.api.schemas import Job, JobState, Page, ResultOut, SweepRequest
from app.services.results import list_results, result_out

router = APIRouter(prefix="/api/sweeps", tags=["sweeps"], responses=PROBLEM_RESPONSES)


@router.post("", status_code=202, response_model=Job, dependencies=[WriteAccess])
def submit_sweep(
    body: SweepRequest, session: SessionDep, services: ServicesDep, response: Response
) -> dict[str, Any]:
    """Queue a sweep (``bioplan sweep``); progress is reported per grid cell."""
    services.robots.joints(session, body.robot)  # UnknownRobotError: 404 naming the field
    job = services.jobs.submit(
        kind="sweep", params=body.model_dump(mode="json"), resource={"robot": body.robot}
    )
    response.headers["Location"] = job["result_url"]
    return job


@router.get("", response_model=Page[ResultOut])
def list_sweeps(
    session: SessionDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
    state: JobState | None = None,
) -> dict[str, Any]:
    items, total = list_results(session, "sweep", limit=limit, offset=offset, state=state)
    return {"items": items, "total": total, "limit": limit, "offset": offset}


@router.get("/{sweep_id:int}", response_model=ResultOut)
def get_sweep(session: SessionDep, sweep_id: IdPath) -> dict[str, Any]:
    return result_out(session, "sweep", sweep_id)
