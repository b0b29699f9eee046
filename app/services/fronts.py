"""Pareto fronts as the API serves them: submission checks, the stored front without its
internal blocks, its CSV, one point's export file, and the viewer address that plays a point
beside the quintic (job kind ``front``: ``app.jobs.tasks.fronts``).

Plain JSON-ready dicts and service errors (``NotFoundError`` 404, ``ConflictError`` 409, any
other ``ServiceError`` 422 naming the field); nothing here knows HTTP.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Collection, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from sqlalchemy.orm import Session

from app.errors import BioPlanError
from app.names import FRONT_AXES
from app.services.errors import ConflictError, NotFoundError, ServiceError
from app.services.job_views import not_finished
from app.services.results import (
    ExportFile,
    TrajectorySource,
    export_trajectory,
    get_result_row,
)

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from app.planning.robots import Robot
    from app.services.core import Services

#: Blocks of a stored front the job keeps for the server's own use (the exports' exact
#: motions): never served.
INTERNAL_KEYS = ("motions",)


def public_front(result: object) -> object:
    """A stored front's result as the API serves it (without :data:`INTERNAL_KEYS`)."""
    if not isinstance(result, dict):
        return result
    return {k: v for k, v in result.items() if k not in INTERNAL_KEYS}


def submit_front(
    services: Services, session: Session, params: dict[str, Any], *, label: str | None,
    left_out: Collection[str] = (),
) -> dict[str, object]:  # fmt: skip
    """Check a front's request against the robot and queue its job.

    Raises:
        UnknownRobotError: no such robot (404 naming ``robot``).
        ServiceError: start/goal angles of the wrong count, a template that does not read, or
            both a template and an analysis (422 naming the field).
        NotFoundError, ConflictError: ``template_analysis_id`` names no analysis, or one
            without a template yet.
    """
    joints = services.robots.joints(session, params["robot"])
    for name in ("start_deg", "goal_deg"):
        angles = params.get(name)
        if angles is not None and len(angles) != len(joints):
            raise ServiceError(
                f"{name} needs {len(joints)} angles for {params['robot']} "
                f"({', '.join(joints)}), got {len(angles)}",
                field=name,
            )
    if params.get("template") is not None and params.get("template_analysis_id") is not None:
        raise ServiceError("give template or template_analysis_id, not both", field="template")
    if params.get("template") is not None:
        from app.planning.human_template import HumanTemplate

        try:
            HumanTemplate.from_dict(params["template"])
        except BioPlanError as exc:
            raise ServiceError(f"not a HumanTemplate: {exc}", field="template") from None
    if params.get("template_analysis_id") is not None:
        try:
            services.jobs.analysis_template(session, params["template_analysis_id"])
        except ServiceError as exc:
            exc.field = "template_analysis_id"
            raise
    return services.jobs.submit(
        kind="front",
        params=params,
        resource={"robot": params["robot"]},
        label=label,
        left_out=left_out,
    )


def finished_front(session: Session, front_id: int) -> dict[str, object]:
    """The stored result of a front that succeeded (NotFoundError, else ConflictError)."""
    row = get_result_row(session, "front", front_id)
    if row.result is None:
        raise not_finished(session, front_id, f"front {front_id}")
    result: dict[str, object] = row.result
    return result


def front_csv(result: Mapping[str, Any]) -> str:
    """The front as CSV: ``id, A, B, every other axis, human_likeness, knee, end``, one row per
    point in front order (SI units; an empty cell where a value is missing)."""
    a, b = result["objectives"]
    columns = ["id", a, b, *(m for m in FRONT_AXES if m not in (a, b)), "human_likeness"]
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow([*columns, "knee", "end"])
    for point in result["points"]:
        row = ["" if point.get(c) is None else _cell(point[c]) for c in columns]
        writer.writerow([*row, "true" if point.get("knee") else "false", point.get("end") or ""])
    return buffer.getvalue()


def _cell(value: object) -> str:
    # repr gives the shortest text that reads back as the same float.
    return repr(float(value)) if isinstance(value, float) else str(value)


def front_point(result: Mapping[str, Any], pid: str) -> dict[str, object]:
    """Point ``pid`` of a front (``p0``, ...) or its quintic reference (``quintic``).

    Raises:
        NotFoundError: no such id in this front (field ``pid``).
    """
    for point in result.get("points") or ():
        if point["id"] == pid:
            return dict(point)
    if pid == "quintic" and pid in (result.get("methods") or ()):
        return {"id": "quintic", **(result.get("references") or {}).get("quintic", {})}
    raise NotFoundError(
        f"pid '{pid}' is not a point of this front: expected one of "
        f"{', '.join(result.get('methods') or ())}",
        field="pid",
    )


def point_source(session: Session, front_id: int, pid: str) -> TrajectorySource:
    """The export source of point ``pid`` of front ``front_id`` (its exact motion, checked
    against the front's collision check)."""
    import dataclasses

    from app.planning.export import PlanMotion

    result = finished_front(session, front_id)
    front_point(result, pid)  # NotFoundError naming pid
    motions = result.get("motions")
    block = motions.get(pid) if isinstance(motions, dict) else None
    if block is None:
        raise ConflictError(f"front {front_id} was stored without the motion of {pid}")
    try:
        motion = PlanMotion.from_dict(block)
    except BioPlanError as exc:
        raise ServiceError(str(exc)) from None
    safety = result.get("safety")
    motion = dataclasses.replace(motion, safety=dict(safety) if isinstance(safety, dict) else None)
    row = get_result_row(session, "front", front_id)
    return TrajectorySource(motion=motion, robot=row.robot, stem=f"front-{front_id}")


def export_point(
    session: Session, services: Services, front_id: int, pid: str, **options: Any
) -> ExportFile:
    """Point ``pid``'s export file, as a plan's method's (``export_trajectory``'s formats,
    options and limit and safety gates)."""
    return export_trajectory(
        session,
        services.robots,
        lambda: point_source(session, front_id, pid),
        method=None,
        **options,
    )


def point_view(services: Services, session: Session, front_id: int, pid: str) -> dict[str, object]:
    """Point ``pid`` and the viewer address that plays it (solid) beside the quintic at its
    duration (ghost): ``{"point", "viewer": {"enabled", "url", "path", "host", "port"}}``;
    ``viewer`` is ``{"enabled": false}`` when the viewer does not run. ``pid`` ``quintic``
    plays the quintic reference (solid) beside the knee (else the first point)."""
    result = finished_front(session, front_id)
    point = front_point(result, pid)
    viewer = services.viewer
    if viewer is None or not viewer.running:
        return {"point": point, "viewer": {"enabled": False}}
    return {
        "point": point,
        "viewer": {
            "enabled": True,
            "port": viewer.port,
            "host": viewer.host,
            "path": f"/bioplan/front/{front_id}",
            "url": viewer.client_url("front", front_id, view_pair(result, pid)),
        },
    }


def view_pair(result: Mapping[str, Any], pid: str) -> tuple[str, str]:
    """The (solid, ghost) pair the viewer shows for ``pid``: the point and the quintic, or for
    ``quintic`` the quintic and the knee (else the first point)."""
    if pid != "quintic":
        return pid, "quintic"
    points = [p["id"] for p in result.get("points") or ()]
    return "quintic", result.get("knee") or points[0]


def viewed_point(methods: tuple[str, str] | None) -> str:
    """The point of a front's viewer pair (the member that is not the quintic).

    Raises:
        NotFoundError: not a pair of the quintic and one point (field ``pid``).
    """
    if methods is None or methods.count("quintic") != 1:
        raise NotFoundError(
            "a front's comparison shows one of its points beside the quintic: expected "
            "methods <point id>,quintic (or quintic,<point id>)",
            field="pid",
        )
    return methods[1] if methods[0] == "quintic" else methods[0]


def point_arrays(
    arrays: Mapping[str, Any], result: Mapping[str, Any], pid: str, robot: Robot
) -> dict[str, NDArray[np.generic]]:
    """The arrays of point ``pid`` and of the quintic at its duration, on the point's grid:
    ``t``, ``<pid>_*`` and ``quintic_*`` (the stored reference when its grid is the point's,
    else the quintic planned at the point's duration, as a front along the duration needs).

    Raises:
        NotFoundError: ``pid`` is not a point of the front (field ``pid``).
    """
    from app.jobs.tasks.fronts import trajectory_arrays
    from app.planning.evaluation import PlanTask, evaluate_trajectory
    from app.planning.profiles import quintic

    ids = [p["id"] for p in result.get("points") or ()]
    if pid not in ids:
        raise NotFoundError(
            f"pid '{pid}' is not a point of this front: expected one of {', '.join(ids)}",
            field="pid",
        )
    t = np.asarray(arrays[f"{pid}_t"], dtype=np.float64)
    out = {k: v for k, v in arrays.items() if k.startswith(f"{pid}_")}
    out["t"] = t
    stored = arrays.get("quintic_t")
    if stored is not None and np.shape(stored) == t.shape and np.allclose(stored, t, rtol=0):
        out.update({k: v for k, v in arrays.items() if k.startswith("quintic_")})
        return out
    conditions = result.get("conditions") or {}
    task = PlanTask(
        np.radians(np.asarray(conditions["start_deg"], float)),
        np.radians(np.asarray(conditions["goal_deg"], float)),
    )
    traj = quintic(task.start, task.goal, float(t[-1]), n_samples=t.size)
    out.update(trajectory_arrays("quintic", evaluate_trajectory(robot, traj, task)))
    return out
