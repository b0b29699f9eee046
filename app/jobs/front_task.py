"""The ``front`` job: a Pareto front (``bioplan front``) with its reference methods, as plain
data (kept out of ``tasks.py``, which holds the other job functions).

Besides ``Front.to_dict()`` the result holds the quintic's, the paper's and the jerk-limited
points on the same task (``references``), the ids a page can view or export (``methods``), the
task (``conditions``), the collision check of every viewable trajectory (``safety``) and each
one's exact motion (``motions``: id -> a ``PlanMotion`` block with that one method, so a point
exports like a plan's method). The arrays hold every point's and reference's trajectory on its
own time grid: ``<id>_t`` (T,) [s], ``<id>_q``/``_qd``/``_qdd``/``_tau`` (T, n) [SI],
``<id>_power`` (T,) [W] and ``<id>_energy`` (T,) [J], and ``t``, the references' grid.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from app.errors import BioPlanError, one_line
from app.jsonsafe import json_safe
from app.names import PSO_DEFAULTS
from app.progress import ProgressFn, no_progress, report, within

#: The methods drawn beside a front, each planned at the front's duration.
REFERENCES = ("quintic", "paper", "jerk_limited")
#: Share of the job's progress the front itself takes (the references and checks follow).
FRONT_SHARE = 0.85
#: The reference duration of a front with duration as an axis and no knee [s].
DEFAULT_REFERENCE_DURATION = 1.0


def front(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
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
    # Here, not at the top: ``tasks`` imports this module for its table of job functions.
    from app.jobs.tasks import _task, _template, robot_from_spec

    with robot_from_spec(payload["robot"], payload.get("payload_mass")) as robot:
        task = _task(robot, payload.get("start_deg"), payload.get("goal_deg"))
        task = task or _entry("app.planning.planner", "PlanTask").default(robot)
        template = _template(payload)
        found = _pareto_front(robot, task, template, payload, progress)
        out, arrays = _with_references(robot, task, template, found, progress)
    report(progress, "done", 1, 1, message="front done")
    return {"result": json_safe(out), "arrays": arrays}


def _pareto_front(
    robot: Any, task: Any, template: Any, payload: dict[str, Any], progress: ProgressFn
) -> Any:
    """``pareto_front`` with the payload's options (progress: its first ``FRONT_SHARE``)."""
    pareto_front = _entry("app.planning.front", "pareto_front")
    # The request's names -> the library's; a field left out keeps the library's default (the
    # defaults live there once, not here again).
    names = {"intervals": "n_intervals"} | {
        k: k for k in ("method", "points", "max_duration", "tolerance", "duration")
    }
    options = {arg: payload[key] for key, arg in names.items() if payload.get(key) is not None}
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
    robot: Any, task: Any, template: Any, found: Any, progress: ProgressFn
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The front's JSON with its references, viewable ids, conditions, collision check and
    motions (module docstring), and every trajectory's arrays."""
    out: dict[str, Any] = found.to_dict()
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
    out["conditions"] = _conditions(robot, task, found, at)
    report(progress, "safety", 0, 1, fraction=0.95, message="collision check")
    out["safety"] = _safety(robot, {k: ev.trajectory for k, ev in shown.items()})
    out["motions"] = {
        name: _motion(robot, task, name, ev, out["conditions"]) for name, ev in shown.items()
    }
    every = {**evaluated, **shown}
    arrays = {k: v for name, ev in every.items() for k, v in trajectory_arrays(name, ev).items()}
    if "quintic" in evaluated:
        arrays["t"] = np.asarray(evaluated["quintic"].trajectory.t, dtype=np.float64)
    return out, arrays


def _entry(module: str, name: str) -> Any:
    import importlib

    return getattr(importlib.import_module(module), name)


def reference_duration(front: dict[str, Any]) -> float:
    """The duration [s] the references are planned at: the front's, or with duration as an
    axis the knee point's (1 s without a knee)."""
    if front.get("duration") is not None:
        return float(front["duration"])
    knee = front.get("knee")
    for point in front.get("points") or ():
        if point["id"] == knee:
            return float(point["duration"])
    return DEFAULT_REFERENCE_DURATION


def _values(robot: Any, ev: Any) -> dict[str, Any]:
    """Every front axis of one trajectory and its peak torques [Nm], as a point has them."""
    axes = _entry("app.planning.front", "FRONT_AXES")
    jerk_integral = _entry("app.planning.front", "jerk_integral")
    objective_value = _entry("app.planning.methods", "objective_value")
    values: dict[str, Any] = {}
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
    robot: Any, task: Any, duration: float, a: str, template: Any
) -> tuple[dict[str, Any], dict[str, str], dict[str, float]]:
    """The reference methods planned at ``duration`` (the paper's PSO minimising A when A is
    a planner objective, else ``abs_work``): evaluated trajectories, errors, human-likeness."""
    run_plan = _entry("app.planning", "plan")
    objectives = _entry("app.names", "OBJECTIVES")
    try:
        planned = run_plan(
            robot,
            task=task,
            duration=duration,
            objective=a if a in objectives else "abs_work",
            template=template,
            seed=PSO_DEFAULTS.seed,
            particles=PSO_DEFAULTS.particles,
            iterations=PSO_DEFAULTS.iterations,
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


def _conditions(robot: Any, task: Any, found: Any, at: float) -> dict[str, Any]:
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


def _safety(robot: Any, trajectories: dict[str, Any]) -> dict[str, Any]:
    """The collision check of every viewable trajectory (findings name the point's id)."""
    check_safety = _entry("app.planning.safety", "check_safety")
    not_checked = _entry("app.planning.safety", "not_checked")
    try:
        report_: dict[str, Any] = check_safety(robot, trajectories).to_dict()
    except BioPlanError as exc:
        report_ = not_checked(f"not checked: {exc}").to_dict()
    return report_


def trajectory_arrays(name: str, ev: Any) -> dict[str, np.ndarray]:
    """One trajectory's arrays under ``<name>_``: ``t``, ``q``, ``qd``, ``qdd``, ``tau``,
    ``power`` (Σ|τ·q̇| [W]) and ``energy`` (its running integral [J]), as a plan stores them."""
    energy = _entry("app.planning.energy", "cumulative_energy")
    power_curve = _entry("app.planning.energy", "power_curve")
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
    robot: Any, task: Any, name: str, ev: Any, conditions: dict[str, Any]
) -> dict[str, Any]:
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
    out: dict[str, Any] = motion.to_dict()
    return out
