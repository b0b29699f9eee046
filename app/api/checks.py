"""Checks of a plan's or simulation's request before its job is queued: what the planner
would refuse, answered at once (404 unknown robot or analysis, 409 analysis without a template
yet, 422 naming the field)."""

from __future__ import annotations

import math
from typing import Any

from sqlalchemy.orm import Session

from app.api.errors import ApiError
from app.api.schemas import PlanRequest, SimulationRequest
from app.errors import BioPlanError
from app.services import ServiceError, Services


def _limit(value: float | None, default: float) -> float:
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
    _check_shape(body, session, services)


def _check_shape(
    body: PlanRequest | SimulationRequest, session: Session, services: Services
) -> None:
    """422 for ``human_constraint: "shape"`` on a template without recorded lifts' profiles."""
    from app.planning.human_constraints import speed_band
    from app.planning.human_template import HumanTemplate

    methods = getattr(body, "methods", ())
    if getattr(body, "human_constraint", None) != "shape" or "human_optimal" not in methods:
        return
    data = body.template
    if data is None and body.template_analysis_id is not None:
        data = services.jobs.analysis_template(session, body.template_analysis_id)
    try:
        speed_band(HumanTemplate() if data is None else HumanTemplate.from_dict(data))
    except BioPlanError as exc:
        raise ApiError(422, str(exc), field="human_constraint") from None
