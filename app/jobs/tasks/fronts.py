"""The ``front`` job: a Pareto front (``bioplan front``) with its reference methods, as plain
data.

Besides ``Front.to_dict()`` the result holds the quintic's, the paper's and the jerk-limited
points on the same task (``references``), the ids a page can view or export (``methods``), the
task (``conditions``), the collision check of every viewable trajectory (``safety``) and each
one's exact motion (``motions``: id -> a ``PlanMotion`` block with that one method, so a point
exports like a plan's method). The arrays hold every point's and reference's trajectory on its
own time grid: ``<id>_t`` (T,) [s], ``<id>_q``/``_qd``/``_qdd``/``_tau`` (T, n) [SI],
``<id>_power`` (T,) [W] and ``<id>_energy`` (T,) [J], and ``t``, the references' grid.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from app.errors import BioPlanError, one_line
from app.jobs.tasks.planning import task_from_degrees, template_of
from app.jobs.tasks.robots import robot_from_spec
from app.jobs.tasks.types import FrontPayload, JobResult
from app.jsonsafe import json_safe
from app.names import DEFAULT_OBJECTIVE, OBJECTIVES
from app.progress import ProgressFn, no_progress, report, within

if TYPE_CHECKING:
    from app.planning.evaluation import EvaluatedTrajectory
    from app.planning.front import Front
    from app.planning.human_template import HumanTemplate
    from app.planning.planner import PlanTask
    from app.planning.profiles import Trajectory
    from app.planning.robots import Robot

#: The methods drawn beside a front, each planned at the front's duration.
REFERENCES = ("quintic", "paper", "jerk_limited")
#: Share of the job's progress the front itself takes (the references and checks follow).
FRONT_SHARE = 0.85
#: The reference duration of a front with duration as an axis and no knee [s].
DEFAULT_REFERENCE_DURATION = 1.0


def front(payload: FrontPayload, progress: ProgressFn = no_progress) -> JobResult:
    """The Pareto front of a task with its reference methods (``POST /api/fronts``).

    Payload: ``robot`` (spec), ``payload_mass`` [kg] or None, ``objectives`` [A, B],
    ``duration`` [s] or None, ``method``, ``points``, ``intervals``, ``tolerance``,
    ``allow_reversal``, ``max_duration`` [s] or None, ``start_deg``, ``goal_deg`` (None: the
    robot's curl), ``template`` (HumanTemplate dict or None).

    Progress: stage ``front``, one unit per point (``pareto_front``'s), then ``references``.

    Returns:
        ``{"result": Front.to_dict() + references, methods, conditions, safety, motions,
        "arrays": the trajectories}`` (module docstring).
    """
    from app.planning.planner import PlanTask

    with robot_from_spec(payload["robot"], payload.get("payload_mass")) as robot:
        task = task_from_degrees(robot, payload.get("start_deg"), payload.get("goal_deg"))
        task = task or PlanTask.default(robot)
        template = template_of(payload)
        found = _pareto_front(robot, task, template, payload, progress)
        out, arrays = _with_references(robot, task, template, found, progress)
    report(progress, "done", 1, 1, message="front done")
    return {"result": json_safe(out), "arrays": arrays}


def _pareto_front(
    robot: Robot,
    task: PlanTask,
    template: HumanTemplate | None,
    payload: FrontPayload,
    progress: ProgressFn,
) -> Front:
    """``pareto_front`` with the payload's options (progress: its first ``FRONT_SHARE``)."""
    from app.planning.front import pareto_front

    # The request's names -> the library's; a field left out keeps the library's default (the
    # defaults live there once, not here again).
    names = {"intervals": "n_intervals"} | {
        k: k for k in ("method", "points", "max_duration", "tolerance", "duration")
    }
    fields: Mapping[str, object] = payload
    # keyword arguments of pareto_front by name (its signature types them)
    options: dict[str, Any] = {
        arg: fields[key] for key, arg in names.items() if fields.get(key) is not None
    }
    if "allow_reversal" in payload:
        options["no_reversal"] = not bool(payload["allow_reversal"])
    return pareto_front(
        robot,
        task,
        objectives=list(payload["objectives"]),
        template=template,
        **options,
        progress=within(progress, 0.0, FRONT_SHARE),
    )


def _with_references(
    robot: Robot, task: PlanTask, template: HumanTemplate | None, found: Front, progress: ProgressFn
) -> tuple[dict[str, object], dict[str, np.ndarray]]:
    """The front's JSON with its references, viewable ids, conditions, collision check and
    motions (module docstring), and every trajectory's arrays."""
    out: dict[str, object] = found.to_dict()
    at = reference_duration(out)
    report(progress, "references", 0, 1, fraction=FRONT_SHARE,
           message=f"references at {at:.4g} s")  # fmt: skip
    evaluated, errors, likeness = _references(robot, task, at, found.a, template)
    out["references"] = {
        name: (
            {"error": errors[name]}
            if name in errors
            else {**_values(robot, evaluated[name]), "human_likeness": likeness.get(name)}
        )
        for name in REFERENCES
    }
    shown = {p.id: p.evaluated for p in found.points}
    if "quintic" in evaluated:
        shown = {"quintic": evaluated["quintic"], **shown}
    out["methods"] = list(shown)
    conditions = _conditions(robot, task, found, at)
    out["conditions"] = conditions
    report(progress, "safety", 0, 1, fraction=0.95, message="collision check")
    out["safety"] = _safety(robot, {k: ev.trajectory for k, ev in shown.items()})
    out["motions"] = {
        name: _motion(robot, task, name, ev, conditions) for name, ev in shown.items()
    }
    every = {**evaluated, **shown}
    arrays = {k: v for name, ev in every.items() for k, v in trajectory_arrays(name, ev).items()}
    if "quintic" in evaluated:
        arrays["t"] = np.asarray(evaluated["quintic"].trajectory.t, dtype=np.float64)
    return out, arrays


def reference_duration(front: Mapping[str, object]) -> float:
    """The duration [s] the references are planned at: the front's, or with duration as an
    axis the knee point's (1 s without a knee)."""
    duration = front.get("duration")
    if isinstance(duration, int | float):
        return float(duration)
    knee = front.get("knee")
    points = front.get("points")
    for point in points if isinstance(points, list) else ():
        if point["id"] == knee:
            return float(point["duration"])
    return DEFAULT_REFERENCE_DURATION


def _values(robot: Robot, ev: EvaluatedTrajectory) -> dict[str, object]:
    """Every front axis of one trajectory and its peak torques [Nm], as a point has them."""
    from app.planning.front import FRONT_AXES as axes
    from app.planning.front import jerk_integral
    from app.planning.methods import objective_value

    values: dict[str, object] = {}
    for name in axes:
        if name == "duration":
            values[name] = ev.trajectory.duration
        elif name == "jerk":
            values[name] = jerk_integral(ev.trajectory)
        else:
            values[name] = objective_value(robot, ev, name)
    peaks = np.abs(np.asarray(ev.tau)).max(axis=0)
    values["peak_torques"] = {n: float(v) for n, v in zip(robot.joint_names, peaks, strict=True)}
    values["violations"] = list(ev.violations)
    return values


def _references(
    robot: Robot, task: PlanTask, duration: float, a: str, template: HumanTemplate | None
) -> tuple[dict[str, EvaluatedTrajectory], dict[str, str], dict[str, float]]:
    """The reference methods planned at ``duration`` (the paper's PSO minimising A when A is
    a planner objective, else ``abs_work``): evaluated trajectories, errors, human-likeness."""
    from app.planning.planner import plan as run_plan

    try:
        planned = run_plan(
            robot,
            task=task,
            duration=duration,
            objective=a if a in OBJECTIVES else DEFAULT_OBJECTIVE,
            template=template,
            methods=list(REFERENCES),
            safety=False,  # checked below with the points
        )
    except BioPlanError as exc:  # the task itself fails at this duration: every method says so
        return {}, {name: one_line(str(exc)) for name in REFERENCES}, {}
    evaluated = {name: m.evaluated for name, m in planned.methods.items()}
    errors = {name: f.error for name, f in planned.method_errors.items()}
    for name in REFERENCES:
        if name not in evaluated and name not in errors:
            errors[name] = "not planned"
    return evaluated, errors, dict(planned.human_likeness)


def _conditions(robot: Robot, task: PlanTask, found: Front, at: float) -> dict[str, object]:
    """The task and what the front was made of, as a plan's ``conditions`` (the viewer reads
    the task and the title from them)."""
    return {
        "robot": robot.name,
        "objective": f"{found.a} vs {found.b} front",
        "objectives": [found.a, found.b],
        "method": found.method,
        "duration": at,
        "payload": float(robot.payload.mass),
        "start_deg": np.degrees(np.asarray(task.start, float)).tolist(),
        "goal_deg": np.degrees(np.asarray(task.goal, float)).tolist(),
    }


def _safety(robot: Robot, trajectories: Mapping[str, Trajectory]) -> dict[str, object]:
    """The collision check of every viewable trajectory (findings name the point's id)."""
    from app.planning.safety import check_safety, not_checked

    try:
        report_: dict[str, object] = check_safety(robot, trajectories).to_dict()
    except BioPlanError as exc:
        report_ = not_checked(f"not checked: {exc}").to_dict()
    return report_


def trajectory_arrays(name: str, ev: EvaluatedTrajectory) -> dict[str, np.ndarray]:
    """One trajectory's arrays under ``<name>_``: ``t``, ``q``, ``qd``, ``qdd``, ``tau``,
    ``power`` (Σ|τ·q̇| [W]) and ``energy`` (its running integral [J]), as a plan stores them."""
    from app.planning.energy import cumulative_energy as energy
    from app.planning.energy import power_curve

    tr = ev.trajectory
    power = np.asarray(power_curve(tr.qd, ev.tau), dtype=np.float64)
    out = {
        "t": tr.t,
        "q": tr.q,
        "qd": tr.qd,
        "qdd": tr.qdd,
        "tau": ev.tau,
        "power": power,
        "energy": energy(tr.t, power),
    }
    return {f"{name}_{k}": np.asarray(v, dtype=np.float64) for k, v in out.items()}


def _motion(
    robot: Robot,
    task: PlanTask,
    name: str,
    ev: EvaluatedTrajectory,
    conditions: Mapping[str, object],
) -> dict[str, object]:
    """A ``PlanMotion`` block holding one trajectory as method ``name``: its exact knots (an
    optimum's constant-jerk mesh, a quintic's polynomial) or else its samples."""
    from app.planning.export import PlanMotion, method_motion

    method = method_motion(name, ev, robot)
    motion = PlanMotion(
        robot=robot.name,
        robot_spec=dict(robot.spec),
        joint_names=tuple(robot.joint_names),
        locks=dict(robot.locks),
        all_joint_names=tuple(robot.all_joint_names),
        start=np.asarray(task.start, dtype=np.float64),
        goal=np.asarray(task.goal, dtype=np.float64),
        duration=float(method.duration),
        methods={name: method},
        default_method=name,
        conditions={k: conditions[k] for k in ("objective", "payload", "method")},
    )
    out: dict[str, object] = motion.to_dict()
    return out
