"""Plans: submit (202 + job), list, fetch results and arrays, compare two plans."""

from __future__ import annotations

import math
from typing import Annotated, Any

from fastapi import APIRouter, Query, Response
from sqlalchemy.orm import Session

from app.api.deps import RobotsDep, ServicesDep, SessionDep, SettingsDep, WriteAccess
from app.api.errors import ApiError
from app.api.routes._common import (
    EXPORT_RESPONSES,
    MAX_POINTS,
    PROBLEM_RESPONSES,
    ArrayNames,
    FormatQuery,
    IdPath,
    MethodQuery,
    RateQuery,
    SamplesQuery,
    arrays_out,
    get_result_row,
    job_of,
    list_results,
    relabel,
    result_out,
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
    SimulationRequest,
    left_out,
)
from app.errors import BioPlanError
from app.services import ServiceError, Services

router = APIRouter(prefix="/api/plans", tags=["plans"], responses=PROBLEM_RESPONSES)


def _limit(value: Any, default: float) -> float:
    return default if value is None else float(value)


def _check_angles(body: PlanRequest | SimulationRequest, robot: dict[str, Any]) -> None:
    """422 for start/goal angles outside the joint limits, or a task that does not move."""
    names = robot["joint_names"]
    for field in ("start_deg", "goal_deg"):
        angles = getattr(body, field) or robot[f"default_{field}"]
        for j, name in enumerate(names):
            lo = math.degrees(_limit(robot["q_min"][j], -math.inf))
            hi = math.degrees(_limit(robot["q_max"][j], math.inf))
            if not lo - 1e-9 <= angles[j] <= hi + 1e-9:
                raise ApiError(
                    422,
                    f"{field}: joint {name} at {angles[j]:g} deg is outside its limits "
                    f"[{lo:.1f}, {hi:.1f}] deg",
                    field=field,
                )


def check_feasible(body: PlanRequest | SimulationRequest, robot: dict[str, Any]) -> None:
    """422 for what is cheap to refuse before a job is queued (``validate_task``'s checks).

    Angles outside the joint limits, a task that does not move (or not the elbow), and a
    duration too short for a joint's speed limit: no rest-to-rest motion has a lower peak speed
    than its mean speed, so the smallest feasible duration is ``max |goal - start| / qd_max``.
    Robots described before the default task was recorded skip the checks (the job still
    refuses them with the planner's line).
    """
    if robot.get("default_start_deg") is None or robot.get("elbow_joint") is None:
        return
    _check_angles(body, robot)
    start = body.start_deg or robot["default_start_deg"]
    goal = body.goal_deg or robot["default_goal_deg"]
    names = robot["joint_names"]
    if all(abs(a - b) < 1e-9 for a, b in zip(start, goal, strict=True)):
        raise ApiError(422, "goal_deg equals start_deg: nothing to plan", field="goal_deg")
    elbow = names.index(robot["elbow_joint"])
    if abs(goal[elbow] - start[elbow]) < 1e-7:
        raise ApiError(
            422,
            f"goal_deg: the task does not move the elbow joint ({robot['elbow_joint']}), which "
            "the human template shapes",
            field="goal_deg",
        )
    shortest, joint = 0.0, ""
    for j, name in enumerate(names):
        qd_max = _limit(robot["qd_max"][j], math.inf)
        need = math.radians(abs(goal[j] - start[j])) / qd_max
        if need > shortest:
            shortest, joint = need, name
    if body.duration < shortest:
        raise ApiError(
            422,
            f"duration {body.duration:g} s is too short for the speed limit of joint {joint}: "
            f"expected a duration of at least {shortest:.3f} s",
            field="duration",
        )


def check_task(body: PlanRequest | SimulationRequest, session: Session, services: Services) -> None:
    """Refuse what the planner would: an unknown robot or analysis (404), an analysis without
    a template yet (409), angles, limits or a template the robot cannot take (422)."""
    from app.planning.human_template import HumanTemplate

    joints = services.robots.joints(session, body.robot)
    for name in ("start_deg", "goal_deg"):
        angles = getattr(body, name)
        if angles is not None and len(angles) != len(joints):
            raise ApiError(
                422,
                f"{name} needs {len(joints)} angles for {body.robot} ({', '.join(joints)}), "
                f"got {len(angles)}",
                field=name,
            )
    check_feasible(body, services.robots.describe(session, body.robot))
    if body.template is not None and body.template_analysis_id is not None:
        raise ApiError(422, "give template or template_analysis_id, not both", field="template")
    if body.template is not None:
        try:
            HumanTemplate.from_dict(body.template)
        except BioPlanError as exc:  # names the template's field at fault
            raise ApiError(422, f"not a HumanTemplate: {exc}", field="template") from None
    if body.template_analysis_id is not None:
        try:
            services.jobs.analysis_template(session, body.template_analysis_id)
        except ServiceError as exc:
            # Missing (404) or without a template yet (409), as for the analysis itself; the
            # answer names the body's field that points at it.
            exc.field = "template_analysis_id"
            raise


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
    return arrays_out(session, "plan", plan_id, points=points, names=name)


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
) -> Response:
    """One method's trajectory as a file (``bioplan export``): csv, json, yaml (ROS 2
    JointTrajectory), mcap (rosbag2), script (URScript) or mot (OpenSim); ``docs/export.md``."""
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
    )
