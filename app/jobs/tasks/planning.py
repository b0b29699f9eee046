"""Planning jobs: plan, simulate, sweep and compare profiles (``bioplan plan``, ``simulate``,
``sweep``, ``profiles``) on a job's robot.

A payload's options are the dict of the operation's options object (``PlanOptions``,
``SimulationOptions``, ``SweepGrid``), read back with its ``from_payload``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, TypeVar

import numpy as np
from numpy.typing import NDArray

from app.errors import BioPlanError
from app.jobs.tasks.robots import robot_from_spec
from app.jobs.tasks.types import (
    FrontPayload,
    JobResult,
    PlanPayload,
    ProfilesPayload,
    SimulationPayload,
    SweepPayload,
)
from app.jsonsafe import json_safe
from app.options import Options
from app.progress import ProgressFn, no_progress, report, within

if TYPE_CHECKING:
    from app.planning.human_template import HumanTemplate
    from app.planning.planner import PlanResult, PlanTask
    from app.planning.robots import Robot
    from app.simulation.comparison import SimulationResult

#: What ``plan`` or ``simulate`` returns (:func:`_with_motion`'s ``run``).
R = TypeVar("R", "PlanResult", "SimulationResult")


def task_from_degrees(
    robot: Robot, start_deg: list[float] | None, goal_deg: list[float] | None
) -> PlanTask | None:
    """A PlanTask from start/goal angles [deg] ((n,) each), each defaulting to the robot's
    curl task; None when neither is given (the planner's default task)."""
    if start_deg is None and goal_deg is None:
        return None
    from app.planning.planner import PlanTask

    default = PlanTask.default(robot)
    start, goal = np.array(default.start, float), np.array(default.goal, float)
    n = len(robot.joint_names)
    for name, values, target in (("start_deg", start_deg, start), ("goal_deg", goal_deg, goal)):
        if values is None:
            continue
        if len(values) != n:
            raise BioPlanError(f"{name} needs {n} angles for {robot.name}, got {len(values)}")
        target[:] = np.radians(np.asarray(values, float))
    return PlanTask(start, goal)


def template_of(
    payload: PlanPayload | SimulationPayload | ProfilesPayload | FrontPayload,
) -> HumanTemplate | None:
    """The payload's human template (a ``HumanTemplate`` dict), or None."""
    from app.planning.human_template import HumanTemplate

    template = payload.get("template")
    return None if template is None else HumanTemplate.from_dict(template)


def _arrays_of(result: object) -> dict[str, NDArray[np.float64]] | None:
    """A result's named arrays as float64 (its ``arrays()``), or None when it has none."""
    arrays = getattr(result, "arrays", None)
    if not callable(arrays):
        return None
    return {k: np.asarray(v, dtype=np.float64) for k, v in arrays().items()}


def plan(payload: PlanPayload, progress: ProgressFn = no_progress) -> JobResult:
    """Plan standard and bio-inspired trajectories (``bioplan plan``).

    Payload: ``robot`` (spec), ``payload`` [kg] or None, ``start_deg``/``goal_deg`` [deg],
    ``template`` (HumanTemplate dict or None), and the fields of
    :class:`app.planning.options.PlanOptions` (absent or None: its default).

    Returns:
        ``{"result": PlanResult.to_dict() + "motion", "arrays": PlanResult.arrays()}``; the
        ``motion`` block (``plan_motion(result, robot).to_dict()``) holds every method's exact
        knots, so the stored result can be exported at any rate.
    """
    from app.planning.options import PlanOptions
    from app.planning.planner import plan as run_plan

    options = PlanOptions.from_payload(payload)
    return _with_motion(payload, run_plan, options, progress, plan_of=lambda result: result)


def simulate(payload: SimulationPayload, progress: ProgressFn = no_progress) -> JobResult:
    """Simulate standard and optimised trajectories (``bioplan simulate``).

    Payload: as for :func:`plan`, with the fields of
    :class:`app.simulation.options.SimulationOptions`.

    Returns:
        ``{"result": SimulationResult.to_dict() + "motion", "arrays":
        SimulationResult.arrays()}`` (the motion block of the simulated plan).
    """
    from app.simulation import simulate_comparison
    from app.simulation.options import SimulationOptions

    options = SimulationOptions.from_payload(payload)
    return _with_motion(
        payload, simulate_comparison, options, progress, plan_of=lambda result: result.plan
    )


def _with_motion(
    payload: PlanPayload | SimulationPayload,
    run: Callable[..., R],
    options: Options,
    progress: ProgressFn,
    *,
    plan_of: Callable[[R], PlanResult],
) -> JobResult:
    """``run(robot, options, task=, template=, progress=)`` on the payload's robot, task and
    template: its dict with the ``motion`` block of its plan (``plan_of(result)``) and its
    arrays."""
    from app.planning.export import plan_motion

    with robot_from_spec(payload["robot"], payload.get("payload")) as robot:
        result = run(
            robot,
            options,
            task=task_from_degrees(robot, payload.get("start_deg"), payload.get("goal_deg")),
            template=template_of(payload),
            progress=progress,
        )
        out = json_safe(result.to_dict())
        out["motion"] = plan_motion(plan_of(result), robot).to_dict()
    return {"result": out, "arrays": _arrays_of(result)}


def sweep(payload: SweepPayload, progress: ProgressFn = no_progress) -> JobResult:
    """Savings over a grid of durations, payloads and objectives (``bioplan sweep``).

    Payload: ``robot`` (spec), the fields of :class:`app.simulation.options.SweepGrid`,
    ``workers`` (processes for the cells), and ``cell_executor``: set by the runner to
    ``"dask"`` when the job runs on a Dask worker, so that every cell becomes a task of its own
    on the cluster (submitted from this task through ``worker_client``); otherwise the cells
    run in a local pool of ``workers`` processes. Progress is reported per cell.
    """
    from app.simulation import run_sweep
    from app.simulation.options import SweepGrid

    grid = SweepGrid.from_payload(payload)
    with robot_from_spec(payload["robot"]) as robot, _cell_executor(payload) as executor:
        result = run_sweep(
            robot=robot, grid=grid, workers=payload.get("workers"), executor=executor,
            progress=progress,
        )  # fmt: skip
    return {"result": json_safe(result.to_dict())}


@contextmanager
def _cell_executor(payload: SweepPayload) -> Iterator[object]:
    """Where a sweep job's cells run: ``"local"``, or (on a Dask worker) a client that submits
    them to the same cluster while this task steps out of the worker's thread pool."""
    if payload.get("cell_executor") != "dask":
        yield "local"
        return
    from distributed import worker_client

    with worker_client() as client:
        yield client


def profiles(payload: ProfilesPayload, progress: ProgressFn = no_progress) -> JobResult:
    """Classical profiles and the minimum-torque-change baseline on one task, with the planning
    methods beside them (``bioplan profiles --json``).

    Payload: ``robot`` (spec), ``payload`` [kg], ``duration`` [s], ``start_deg``, ``goal_deg``,
    ``min_torque_change``, ``mtc_intervals``, ``methods`` ([] = none), ``objective``, ``seed``,
    ``particles``, ``iterations``.
    """
    from app.planning.comparison import compare_profiles
    from app.planning.options import PlanOptions
    from app.planning.planner import plan as run_plan

    with robot_from_spec(payload["robot"], payload.get("payload")) as robot:
        task = task_from_degrees(robot, payload.get("start_deg"), payload.get("goal_deg"))
        duration = float(payload["duration"])
        report(progress, "profiles", 0, 1, fraction=0.0, message="classical profiles")
        result = compare_profiles(
            robot,
            task=task,
            duration=duration,
            include_min_torque_change=bool(payload.get("min_torque_change", True)),
            mtc_intervals=int(payload.get("mtc_intervals", 100)),
        )
        out: dict[str, object] = json_safe(result.to_dict())
        methods = payload.get("methods")
        if methods is None or methods:
            planned = run_plan(
                robot,
                PlanOptions.from_payload(payload),
                task=task,
                progress=within(progress, 0.3, 1.0),
            ).to_dict()
            out["objective"] = planned["conditions"]["objective"]
            out["methods"] = planned["methods"]
            out["share_of_achievable_pct"] = planned["share_of_achievable_pct"]
    report(progress, "done", 1, 1, message="profiles compared")
    return {"result": json_safe(out)}
