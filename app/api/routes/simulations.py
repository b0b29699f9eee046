"""Simulations: submit (202 + job), list, fetch results and arrays."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Response

from app.api.checks import check_task
from app.api.deps import RobotsDep, ServicesDep, SessionDep, SettingsDep, WriteAccess
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
    ResultOut,
    SimulationRequest,
    left_out,
)
from app.services.results import list_results, relabel, result_arrays, result_out

router = APIRouter(prefix="/api/simulations", tags=["simulations"], responses=PROBLEM_RESPONSES)


@router.post("", status_code=202, response_model=Job, dependencies=[WriteAccess])
def submit_simulation(
    body: SimulationRequest, session: SessionDep, services: ServicesDep, response: Response
) -> dict[str, Any]:
    """Queue a simulation (``bioplan simulate``); the result is the CLI's ``--json`` output."""
    check_task(body, session, services)
    job = services.jobs.submit(
        kind="simulation",
        params=body.model_dump(mode="json", exclude={"label"}),
        resource={"robot": body.robot},
        label=body.label,
        left_out=left_out(body),
    )
    response.headers["Location"] = job["result_url"]
    return job


@router.get("", response_model=Page[ResultOut])
def list_simulations(
    session: SessionDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
    state: JobState | None = None,
    robot: Annotated[str | None, Query(max_length=100)] = None,
) -> dict[str, Any]:
    items, total = list_results(
        session, "simulation", limit=limit, offset=offset, state=state, robot=robot
    )
    return {"items": items, "total": total, "limit": limit, "offset": offset}


@router.get("/{simulation_id:int}", response_model=ResultOut)
def get_simulation(session: SessionDep, simulation_id: IdPath) -> dict[str, Any]:
    return result_out(session, "simulation", simulation_id)


@router.patch("/{simulation_id:int}", response_model=ResultOut, dependencies=[WriteAccess])
def relabel_simulation(
    session: SessionDep, simulation_id: IdPath, body: LabelPatch
) -> dict[str, Any]:
    """Give the simulation a short name (shown in every list), or remove it with ``null``."""
    return relabel(session, "simulation", simulation_id, body.label)


@router.get("/{simulation_id:int}/arrays", response_model=ArraysOut)
def get_simulation_arrays(
    session: SessionDep,
    simulation_id: IdPath,
    points: Annotated[int, Query(ge=2, le=MAX_POINTS)] = 500,
    name: ArrayNames = None,
) -> dict[str, Any]:
    return result_arrays(session, "simulation", simulation_id, points=points, names=name)


@router.get(
    "/{simulation_id:int}/trajectory",
    response_class=Response,
    responses=EXPORT_RESPONSES,
)
def get_simulation_trajectory(
    session: SessionDep,
    robots: RobotsDep,
    simulation_id: IdPath,
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
        "simulation",
        simulation_id,
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
