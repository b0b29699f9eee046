"""Profiles: classical point-to-point profiles, minimum torque change and the planning methods on
one task (``bioplan profiles``): submit (202 + job), list, fetch."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Response

from app.api.deps import ServicesDep, SessionDep, WriteAccess
from app.api.errors import ApiError
from app.api.routes._common import PROBLEM_RESPONSES, IdPath
from app.api.schemas import Job, JobState, Page, ProfilesRequest, ResultOut, left_out
from app.services.results import list_results, result_out

router = APIRouter(prefix="/api/profiles", tags=["profiles"], responses=PROBLEM_RESPONSES)


@router.post("", status_code=202, response_model=Job, dependencies=[WriteAccess])
def submit_profiles(
    body: ProfilesRequest, session: SessionDep, services: ServicesDep, response: Response
) -> dict[str, Any]:
    """Queue a profiles comparison; the result is ``bioplan profiles --json``."""
    joints = services.robots.joints(session, body.robot)  # UnknownRobotError: 404 naming the field
    for name in ("start_deg", "goal_deg"):
        angles = getattr(body, name)
        if angles is not None and len(angles) != len(joints):
            raise ApiError(
                422, f"{name} needs {len(joints)} angles for {body.robot}, got {len(angles)}",
                field=name,
            )  # fmt: skip
    job = services.jobs.submit(
        kind="profiles",
        params=body.model_dump(mode="json"),
        resource={"robot": body.robot},
        left_out=left_out(body),
    )
    response.headers["Location"] = job["result_url"]
    return job


@router.get("", response_model=Page[ResultOut])
def list_profiles(
    session: SessionDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
    state: JobState | None = None,
    robot: Annotated[str | None, Query(max_length=100)] = None,
) -> dict[str, Any]:
    items, total = list_results(
        session, "profiles", limit=limit, offset=offset, state=state, robot=robot
    )
    return {"items": items, "total": total, "limit": limit, "offset": offset}


@router.get("/{profiles_id:int}", response_model=ResultOut)
def get_profiles(session: SessionDep, profiles_id: IdPath) -> dict[str, Any]:
    return result_out(session, "profiles", profiles_id)
