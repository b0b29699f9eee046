"""Plans: submit (202 + job), list, fetch results and arrays, compare two plans."""

from __future__ import annotations

import math
from typing import Annotated, Any

from fastapi import APIRouter, Query, Response

from app.api.checks import check_task
from app.api.deps import RobotsDep, ServicesDep, SessionDep, SettingsDep, WriteAccess
from app.api.errors import ApiError
from app.api.routes._common import (
    EXPORT_RESPONSES,
    MAX_POINTS,
    PROBLEM_RESPONSES,
    AllowUnsafeQuery,
    ArrayNames,
    ForceQuery,
    FormatQuery,
    FromPositionQuery,
    GoalQuery,
    IdPath,
    MethodQuery,
    RateQuery,
    SamplesQuery,
    TopicQuery,
    trajectory_out,
)
from app.api.schemas import (
    ArraysOut,
    Job,
    JobState,
    LabelPatch,
    Page,
    PlanComparison,
    PlanRequest,
    ResultOut,
    left_out,
)
from app.services.results import (
    get_result_row,
    job_of,
    list_results,
    relabel,
    result_arrays,
    result_out,
)

router = APIRouter(prefix="/api/plans", tags=["plans"], responses=PROBLEM_RESPONSES)


@router.post("", status_code=202, response_model=Job, dependencies=[WriteAccess])
def submit_plan(
    body: PlanRequest, session: SessionDep, services: ServicesDep, response: Response
) -> dict[str, Any]:
    """Queue a plan (``bioplan plan``); the result is the CLI's ``--json`` output."""
    check_task(body, session, services)
    job = services.jobs.submit(
        kind="plan",
        params=body.model_dump(mode="json", exclude={"label"}),
        resource={"robot": body.robot},
        label=body.label,
        left_out=left_out(body),
    )
    response.headers["Location"] = job["result_url"]
    return job


@router.get("", response_model=Page[ResultOut])
def list_plans(
    session: SessionDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
    state: JobState | None = None,
    robot: Annotated[str | None, Query(max_length=100)] = None,
) -> dict[str, Any]:
    items, total = list_results(
        session, "plan", limit=limit, offset=offset, state=state, robot=robot
    )
    return {"items": items, "total": total, "limit": limit, "offset": offset}


def _diff(a: Any, b: Any) -> dict[str, Any] | None:
    def number(x: Any) -> bool:
        return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)

    def one(x: float, y: float) -> tuple[float, float | None]:
        return y - x, (100.0 * (y - x) / abs(x) if x != 0 else None)

    if number(a) and number(b):
        d, pct = one(a, b)
        return {"a": a, "b": b, "diff": d, "diff_pct": pct}
    if (
        isinstance(a, list)
        and isinstance(b, list)
        and len(a) == len(b)
        and all(number(x) for x in a + b)
    ):
        pairs = [one(x, y) for x, y in zip(a, b, strict=True)]
        return {"a": a, "b": b, "diff": [d for d, _ in pairs], "diff_pct": [p for _, p in pairs]}
    return None


def _compare_metrics(ma: dict[str, Any], mb: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for key in ma:
        if key in mb and (d := _diff(ma[key], mb[key])) is not None:
            out[key] = d
    return out


@router.get("/compare", response_model=PlanComparison)
def compare_plans(
    session: SessionDep,
    a: Annotated[int, Query(ge=1, le=2**31 - 1, description="first plan id")],
    b: Annotated[int, Query(ge=1, le=2**31 - 1, description="second plan id")],
) -> dict[str, Any]:
    """Metric by metric, ``b - a`` and ``100 (b - a) / |a|`` for both trajectories."""
    results = []
    for pid in (a, b):
        row = get_result_row(session, "plan", pid)
        if row.result is None:
            state = job_of(session, pid)["state"]
            raise ApiError(409, f"plan {pid} has no result (job state {state})")
        results.append(row.result)
    ra, rb = results
    return {
        "a": a,
        "b": b,
        "conditions": {"a": ra.get("conditions", {}), "b": rb.get("conditions", {})},
        "standard": _compare_metrics(ra.get("standard", {}), rb.get("standard", {})),
        "optimized": _compare_metrics(ra.get("optimized", {}), rb.get("optimized", {})),
        "improvement_pct": {"a": ra.get("improvement_pct", {}), "b": rb.get("improvement_pct", {})},
    }


@router.get("/{plan_id:int}", response_model=ResultOut)
def get_plan(session: SessionDep, plan_id: IdPath) -> dict[str, Any]:
    return result_out(session, "plan", plan_id)


@router.patch("/{plan_id:int}", response_model=ResultOut, dependencies=[WriteAccess])
def relabel_plan(session: SessionDep, plan_id: IdPath, body: LabelPatch) -> dict[str, Any]:
    """Give the plan a short name (shown in every list), or remove it with ``null``."""
    return relabel(session, "plan", plan_id, body.label)


@router.get("/{plan_id:int}/arrays", response_model=ArraysOut)
def get_plan_arrays(
    session: SessionDep,
    plan_id: IdPath,
    points: Annotated[int, Query(ge=2, le=MAX_POINTS)] = 500,
    name: ArrayNames = None,
) -> dict[str, Any]:
    """Time grid and, per trajectory, q, qd, qdd, tau [SI], power [W], energy [J]."""
    return result_arrays(session, "plan", plan_id, points=points, names=name)


@router.get(
    "/{plan_id:int}/trajectory",
    response_class=Response,
    responses=EXPORT_RESPONSES,
)
def get_plan_trajectory(
    session: SessionDep,
    robots: RobotsDep,
    plan_id: IdPath,
    format: FormatQuery,
    settings: SettingsDep,
    rate: RateQuery = None,
    method: MethodQuery = None,
    samples: SamplesQuery = None,
    force: ForceQuery = False,
    allow_unsafe: AllowUnsafeQuery = False,
    goal: GoalQuery = False,
    topic: TopicQuery = None,
    from_position: FromPositionQuery = None,
) -> Response:
    """One method's trajectory as a file (``bioplan export``): csv, json, yaml (ROS 2
    JointTrajectory), mcap (rosbag2), script (URScript) or mot (OpenSim); ``docs/export.md``.
    A file past the robot's limits or into a contact is refused (409) unless ``force`` /
    ``allow_unsafe``, which the file records."""
    return trajectory_out(
        session,
        robots,
        "plan",
        plan_id,
        fmt=format,
        rate=rate,
        method=method,
        samples=samples,
        max_samples=settings.max_export_samples,
        force=force,
        allow_unsafe=allow_unsafe,
        goal=goal,
        topic=topic,
        from_position=from_position,
    )
