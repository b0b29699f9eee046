"""Stored results and jobs as the API shows them: one result with its job, a page of them,
their arrays decimated for plotting, a plan's or simulation's export file, pages of jobs and
pose extractions, a job's deletion.

Plain JSON-ready dicts and service errors (``NotFoundError`` 404, ``ConflictError`` 409, any
other ``ServiceError`` 422 naming the field); nothing here knows HTTP.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session, undefer

from app.db import crud
from app.db.arrays import decode_arrays
from app.db.blobs import BlobStore
from app.db.models import RESULT_MODELS, JobRecord
from app.errors import BioPlanError, without_paths
from app.jsonsafe import json_safe
from app.planning.export import public_result
from app.services.errors import ConflictError, NotFoundError, ServiceError, found
from app.services.jobs import job_to_dict
from app.services.robots import RobotCatalog


def get_result_row(session: Session, kind: str, result_id: int, *, arrays: bool = False) -> Any:
    """The stored row of result ``result_id`` of ``kind`` (``RESULT_MODELS``), with its arrays
    loaded when ``arrays``; NotFoundError when there is none."""
    model: Any = RESULT_MODELS[kind]
    stmt = select(model).where(model.id == result_id)
    if arrays:
        stmt = stmt.options(undefer(model.arrays))
    return found(session.scalars(stmt).first(), f"{kind} {result_id}")


def job_of(session: Session, result_id: int) -> dict[str, Any]:
    """The job (JSON form) that made result ``result_id`` (a result's id is its job's)."""
    job = session.get(JobRecord, result_id, populate_existing=True)
    if job is None:  # pragma: no cover - rows cascade with their job
        raise NotFoundError(f"job {result_id} does not exist")
    return job_to_dict(job)


def result_out(session: Session, kind: str, result_id: int) -> dict[str, Any]:
    """One result with its job and label, its result block as the public sees it."""
    row = get_result_row(session, kind, result_id)
    job = job_of(session, row.id)
    return {
        "id": row.id,
        "robot": getattr(row, "robot", ""),
        "label": job["label"],
        "job": job,
        "result": public_result(row.result),
    }


def relabel(session: Session, kind: str, result_id: int, label: str | None) -> dict[str, Any]:
    """Give a plan or simulation the user's short name (None: none); returns it as shown."""
    get_result_row(session, kind, result_id)  # NotFoundError when there is none
    crud.update_job(session=session, job_id=result_id, only_if_active=False, label=label)
    return result_out(session, kind, result_id)


def list_results(
    session: Session,
    kind: str,
    *,
    limit: int,
    offset: int,
    state: str | None = None,
    robot: str | None = None,
    recording_id: int | None = None,
) -> tuple[list[dict[str, Any]], int]:
    """A page of results of ``kind``, newest first, and how many match in all."""
    model: Any = RESULT_MODELS[kind]
    stmt = select(model, JobRecord).join(JobRecord, JobRecord.id == model.id)
    count = select(func.count(model.id)).join(JobRecord, JobRecord.id == model.id)
    if state is not None:
        stmt, count = stmt.where(JobRecord.state == state), count.where(JobRecord.state == state)
    if robot is not None and hasattr(model, "robot"):
        stmt, count = stmt.where(model.robot == robot), count.where(model.robot == robot)
    if recording_id is not None and hasattr(model, "recording_id"):
        mine = model.recording_id == recording_id
        stmt, count = stmt.where(mine), count.where(mine)
    rows = session.execute(stmt.order_by(model.id.desc()).limit(limit).offset(offset)).all()
    items = []
    for row, job in rows:
        items.append(
            {
                "id": row.id,
                "robot": getattr(row, "robot", ""),
                "recording_id": getattr(row, "recording_id", None),
                "template": getattr(row, "template", None),
                "label": job.label,
                "job": job_to_dict(job),
                "result": public_result(row.result),
            }
        )
    return items, int(session.scalar(count) or 0)


def result_arrays(
    session: Session, kind: str, result_id: int, *, points: int, names: list[str] | None
) -> dict[str, Any]:
    """Stored arrays decimated to at most ``points`` samples along the time axis.

    Returns ``{"id", "points", "arrays": {name: nested lists}}``; ConflictError when the job
    stored none (yet), NotFoundError (field ``name``) for a name this result lacks.
    """
    row = get_result_row(session, kind, result_id, arrays=True)
    if row.arrays is None:
        state = job_of(session, result_id)["state"]
        raise ConflictError(f"{kind} {result_id} has no arrays (job state {state})")
    arrays = decode_arrays(row.arrays)
    if names:
        unknown = sorted(set(names) - set(arrays))
        if unknown:  # as a recording's missing channels: not in this result
            raise NotFoundError(
                f"{kind} {result_id} has no arrays {unknown} (expected some of {sorted(arrays)})",
                field="name",
            )
        arrays = {k: arrays[k] for k in names}
    n = max((a.shape[0] for a in arrays.values() if a.ndim >= 1), default=0)
    # Trajectories are smooth: an even stride keeps their shape (no spikes to preserve).
    idx = np.unique(np.linspace(0, n - 1, min(points, n)).round().astype(int)) if n else None
    out: dict[str, list[Any]] = {}
    for key, arr in arrays.items():
        if idx is not None and arr.ndim >= 1 and arr.shape[0] == n:
            arr = arr[idx]
        out[key] = json_safe(np.atleast_1d(arr).tolist())
    return {"id": result_id, "points": 0 if idx is None else len(idx), "arrays": out}


#: The request fields an ``ExportError`` may be about, in the order they are looked for.
_EXPORT_FIELDS = ("from_position", "topic", "goal", "method", "rate", "format")


def _export_field(message: str) -> str | None:
    """The request field an ``ExportError`` is about (its message names it by name)."""
    return next((name for name in _EXPORT_FIELDS if name in message), None)


@dataclass(frozen=True)
class ExportFile:
    """An export file ready to stream: its chunks (bytes or text) and its download name."""

    chunks: Iterator[Any]
    filename: str


@dataclass(frozen=True)
class TrajectorySource:
    """What an export reads: a stored result's motion and how to name it.

    Attributes:
        motion: the motion block (``app.planning.export.PlanMotion``) with its safety check.
        robot: the robot's name in the catalogue (rebuilt from its spec for the export).
        stem: the download name's start (``plan-7``, ``front-3-p2``).
    """

    motion: Any
    robot: str
    stem: str


def stored_source(
    session: Session, kind: str, result_id: int, method: str | None
) -> TrajectorySource:
    """The motion of a stored plan or simulation, with ``method`` checked against it.

    Raises:
        NotFoundError: no such result, or a method it did not plan (field ``method``).
        ConflictError: no result yet, or one stored without its motion block.
        ServiceError: a motion block that does not read back.
    """
    from app.planning.export import motion_of_result

    row = get_result_row(session, kind, result_id)
    if row.result is None:
        state = job_of(session, result_id)["state"]
        raise ConflictError(f"{kind} {result_id} has no result (job state {state})")
    if "motion" not in row.result:
        raise ConflictError(
            f"{kind} {result_id} was stored without its motion block: plan it again"
        )
    planned = row.result["motion"].get("methods") or {}
    if method is not None and method not in planned:  # not in this result, as a missing array
        raise NotFoundError(
            f"method '{method}' is not in {kind} {result_id}: expected one of {', '.join(planned)}",
            field="method",
        )
    try:
        motion = motion_of_result(row.result)
    except BioPlanError as exc:
        raise ServiceError(str(exc), field=_export_field(str(exc))) from None
    return TrajectorySource(motion=motion, robot=row.robot, stem=f"{kind}-{result_id}")


def export_file(
    session: Session,
    robots: RobotCatalog,
    kind: str,
    result_id: int,
    *,
    fmt: str,
    rate: float | None,
    method: str | None,
    **options: Any,
) -> ExportFile:
    """A stored plan's or simulation's export file (:func:`export_trajectory` of its
    :func:`stored_source`)."""
    return export_trajectory(
        session,
        robots,
        lambda: stored_source(session, kind, result_id, method),
        fmt=fmt,
        rate=rate,
        method=method,
        **options,
    )


def _ros_options(
    fmt: str, *, goal: bool, topic: str | None, from_position: str | None
) -> list[float] | None:
    """The ROS 2 options checked for the format ``fmt``; returns ``from_position`` (degrees,
    comma separated) as (n,) joint positions [rad], or None.

    Raises:
        ServiceError: a bad option, naming its field.
    """
    from app.planning.export import check_ros_options

    start_from = None
    if from_position is not None:
        try:
            start_from = [math.radians(float(v)) for v in from_position.split(",")]
        except ValueError:
            raise ServiceError(
                f"from_position '{from_position}': expected joint positions in degrees "
                "separated by commas",
                field="from_position",
            ) from None
    try:
        check_ros_options(fmt, goal=goal, topic=topic, from_position=start_from)
    except BioPlanError as exc:
        raise ServiceError(str(exc), field=_export_field(str(exc))) from None
    return start_from


def _export_rate(
    motion: Any, fmt: str, *, rate: float | None, samples: int | None, max_samples: int | None
) -> float | None:
    """The export's sample rate [Hz]: ``rate``, or ``samples`` samples over the motion; the
    file's size checked against ``max_samples`` before anything is sampled.

    Raises:
        ServiceError: both given, or the file too large (naming ``samples`` or ``rate``).
    """
    from app.planning.export import check_export_size, export_sample_limit

    try:
        if samples is not None:
            if rate is not None:
                raise ServiceError("give rate or samples, not both", field="samples")
            joints = len(motion.joint_names)
            limit = None if max_samples is None else export_sample_limit(joints, max_samples)
            if limit is not None and samples > limit:
                raise ServiceError(
                    f"samples {samples} exceeds the limit {limit} for {joints} joints "
                    "(BIOPLAN_MAX_EXPORT_SAMPLES)",
                    field="samples",
                )
            rate = (samples - 1) / motion.duration
        check_export_size(motion, fmt, rate, max_samples)
    except ServiceError:
        raise
    except BioPlanError as exc:
        field = "samples" if samples is not None else _export_field(str(exc))
        raise ServiceError(str(exc), field=field) from None
    return rate


def export_trajectory(
    session: Session,
    robots: RobotCatalog,
    source: Callable[[], TrajectorySource],
    *,
    fmt: str,
    rate: float | None,
    method: str | None,
    samples: int | None = None,
    max_samples: int | None = None,
    force: bool = False,
    allow_unsafe: bool = False,
    goal: bool = False,
    topic: str | None = None,
    from_position: str | None = None,
) -> ExportFile:
    """The export file of a stored trajectory (``export_stream``'s chunks); ``source`` reads
    the motion once the request's own options are checked (a plan's method, a front's point).

    ``rate`` [Hz] or ``samples`` (that many samples over the motion); the file holds at most
    ``max_samples`` (``Settings.max_export_samples``), else a ServiceError naming ``samples``
    or ``rate``, before anything is sampled. A file past the robot's limits or into a contact
    of the result's safety check is a ConflictError unless ``force`` / ``allow_unsafe``;
    ``goal``, ``topic`` and ``from_position`` (degrees, comma separated) are the ROS 2 options
    (a ServiceError naming them)."""
    from app.jobs.tasks import robot_from_spec
    from app.planning.export import ExportRefused, export_stream

    start_from = _ros_options(fmt, goal=goal, topic=topic, from_position=from_position)
    found = source()
    motion = found.motion
    rate = _export_rate(motion, fmt, rate=rate, samples=samples, max_samples=max_samples)
    spec = robots.spec(session, found.robot)
    payload = motion.conditions.get("payload")
    try:
        with robot_from_spec(spec, None if payload is None else float(payload)) as robot:
            chunks = export_stream(
                motion,
                fmt,
                method=method,
                rate=rate,
                robot=robot,
                max_samples=max_samples,
                force=force,
                allow_unsafe=allow_unsafe,
                goal=goal,
                topic=topic,
                from_position=start_from,
            )
    except ExportRefused as exc:  # well-formed, but the plan is not fit to run as asked
        raise ConflictError(without_paths(exc)) from None
    except BioPlanError as exc:  # a robot file gone or changed: its name, not its folder
        text = without_paths(exc)
        raise ServiceError(text, field=_export_field(text)) from None
    chosen = method or motion.default_method
    # Each format's extension is its name.
    return ExportFile(chunks=chunks, filename=f"{found.stem}-{chosen}.{fmt}")


def job_page(
    session: Session, *, limit: int, offset: int, kind: str | None, state: str | None
) -> tuple[list[dict[str, Any]], int]:
    """A page of jobs (JSON form), newest first, and how many match in all."""
    rows, total = crud.list_jobs(
        session=session, limit=limit, offset=offset, kind=kind, state=state
    )
    return [job_to_dict(j) for j in rows], total


def pose_page(
    session: Session, *, limit: int, offset: int, state: str | None, recording_id: int | None
) -> tuple[list[tuple[Any, dict[str, Any]]], int]:
    """A page of pose extractions, newest first, each with its job (JSON form), and the total."""
    rows, total = crud.list_pose_extractions(
        session=session, limit=limit, offset=offset, state=state, recording_id=recording_id
    )
    return [(row, job_to_dict(job)) for row, job in rows], total


def delete_job(session: Session, blobs: BlobStore, job_id: int) -> bool:
    """Delete a job with its result (and the result's file when nothing else refers to it);
    False when there is no such job."""
    return crud.delete_job(session=session, blobs=blobs, job_id=job_id)


def with_joint_power(curves: dict[str, Any], comparison: Any, points: int) -> dict[str, Any]:
    """``curves`` (``Comparison.curves(points=points)``) with each trajectory's per-joint power
    ``joint_power`` [W] and cumulative energy ``joint_energy`` [J], (T, n) lists on the same
    samples: integrated on the comparison's full grid, then decimated as the curves are, so the
    page draws them and computes nothing."""
    from app.planning.curves import joint_power

    t = np.asarray(comparison.t, dtype=np.float64)
    n = len(t)
    idx = np.unique(np.linspace(0, n - 1, min(points, n)).round().astype(int))
    for label in ("standard", "optimized"):
        derived = joint_power(t, comparison.tau[label], comparison.qd[label])
        curves[label]["joint_power"] = json_safe(derived.power[idx].tolist())
        curves[label]["joint_energy"] = json_safe(derived.energy[idx].tolist())
    return curves
