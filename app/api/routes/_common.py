"""Helpers shared by the result routers (analyses, plans, simulations, sweeps)."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import PurePosixPath
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from fastapi import Path, Query, Response
from pydantic import BeforeValidator, Field
from sqlalchemy import func, select
from sqlalchemy.orm import Session, undefer

from app.api.errors import ApiError
from app.api.schemas import Problem
from app.db import crud
from app.db.arrays import decode_arrays
from app.db.models import RESULT_MODELS, JobRecord
from app.errors import BioPlanError, without_paths
from app.names import METHODS
from app.planning.export import public_result
from app.planning.jsonsafe import json_safe
from app.services import RobotCatalog, job_to_dict

#: Ids in paths: positive and within a 32-bit integer, so no database overflows.
IdPath = Annotated[int, Path(ge=1, le=2**31 - 1)]
#: The most samples per series a read returns: enough for min/max decimation on any screen
#: (two per pixel of a 4K plot); 100 000 let 16 clients push other requests' p99 to 11 s.
MAX_POINTS = 10_000

#: The error answers every route documents, with the problem's schema.
PROBLEM_RESPONSES: dict[int | str, dict[str, Any]] = {
    code: {
        "description": desc,
        "content": {"application/problem+json": {"schema": Problem.model_json_schema()}},
    }
    for code, desc in (
        (400, "the body cannot be parsed as its Content-Type says"),
        (401, "API token missing or wrong"),
        (404, "not found"),
        (409, "conflict"),
        (413, "request body too large"),
        (422, "invalid request"),
        (429, "too many requests: waiting jobs or open event streams at their cap (Retry-After)"),
    )
}


def get_result_row(session: Session, kind: str, result_id: int, *, arrays: bool = False) -> Any:
    model: Any = RESULT_MODELS[kind]
    stmt = select(model).where(model.id == result_id)
    if arrays:
        stmt = stmt.options(undefer(model.arrays))
    row = session.scalars(stmt).first()
    if row is None:
        raise ApiError(404, f"{kind} {result_id} does not exist")
    return row


def job_of(session: Session, result_id: int) -> dict[str, Any]:
    job = session.get(JobRecord, result_id, populate_existing=True)
    if job is None:  # pragma: no cover - rows cascade with their job
        raise ApiError(404, f"job {result_id} does not exist")
    return job_to_dict(job)


def result_out(session: Session, kind: str, result_id: int) -> dict[str, Any]:
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
    get_result_row(session, kind, result_id)  # 404 when there is none
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


def arrays_out(
    session: Session, kind: str, result_id: int, *, points: int, names: list[str] | None
) -> dict[str, Any]:
    """Stored arrays decimated to at most ``points`` samples along the time axis."""
    row = get_result_row(session, kind, result_id, arrays=True)
    if row.arrays is None:
        state = job_of(session, result_id)["state"]
        raise ApiError(409, f"{kind} {result_id} has no arrays (job state {state})")
    arrays = decode_arrays(row.arrays)
    if names:
        unknown = sorted(set(names) - set(arrays))
        if unknown:  # as a recording's missing channels: not in this result
            raise ApiError(
                404,
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


#: Media type of each export format (``app.planning.export.FORMATS``).
EXPORT_MEDIA_TYPES: dict[str, str] = {
    "csv": "text/csv",
    "json": "application/json",
    "yaml": "application/yaml",
    "mcap": "application/octet-stream",
    "script": "text/plain",
    "mot": "text/plain",
}
#: The trajectory routes' documented answers: a file of one of the export media types.
EXPORT_RESPONSES: dict[int | str, dict[str, Any]] = {
    200: {
        "description": "the export file",
        "content": {media: {} for media in sorted(set(EXPORT_MEDIA_TYPES.values()))},
    }
}
#: Names of stored arrays (``t``, ``standard_q``, ``bound_energy``...).
ArrayNames = Annotated[
    list[Annotated[str, Field(pattern=r"^[a-z][a-z0-9_]*$", max_length=64)]] | None,
    Query(description="array names (default: all); one this result lacks is a 404"),
]
#: Highest export rate [Hz] (``app.planning.export.MAX_RATE_HZ``).
MAX_EXPORT_RATE_HZ = 20_000.0

if TYPE_CHECKING:
    ExportFormatName = str
    ExportMethod = str
else:
    ExportFormatName = Literal[tuple(EXPORT_MEDIA_TYPES)]
    ExportMethod = Literal[tuple(METHODS)]

FormatQuery = Annotated[ExportFormatName, Query(description="export format")]
RateQuery = Annotated[
    float | None,
    Query(gt=0, le=MAX_EXPORT_RATE_HZ, description="sample rate [Hz] (default: the format's)"),
]
MethodQuery = Annotated[
    ExportMethod | None, Query(description="method to export (default: the optimised one)")
]
SamplesQuery = Annotated[
    int | None,
    Query(
        ge=2,
        description="samples over the motion instead of a rate (rate = (samples - 1) / "
        "duration); the schema's maximum is this server's BIOPLAN_MAX_EXPORT_SAMPLES, which "
        "also caps what a rate may ask for (fewer for robots of more than six joints)",
    ),
]


def _export_field(message: str) -> str | None:
    """The request field an ``ExportError`` is about (its message names it)."""
    for needle, name in (("method", "method"), ("rate", "rate"), ("format", "format")):
        if needle in message:
            return name
    return None


def trajectory_out(
    session: Session,
    robots: RobotCatalog,
    kind: str,
    result_id: int,
    *,
    fmt: str,
    rate: float | None,
    method: str | None,
    samples: int | None = None,
    max_samples: int | None = None,
) -> Response:
    """A stored plan's or simulation's export file, streamed (``export_stream``'s chunks).

    ``samples`` (instead of ``rate``) asks for that many samples over the motion; the file
    holds at most ``max_samples`` (``Settings.max_export_samples``), else a 422 naming
    ``samples`` or ``rate``, before anything is sampled."""
    from fastapi.responses import StreamingResponse

    from app.jobs.tasks import robot_from_spec
    from app.planning.export import (
        check_export_size,
        export_sample_limit,
        export_stream,
        motion_of_result,
    )

    row = get_result_row(session, kind, result_id)
    if row.result is None:
        state = job_of(session, result_id)["state"]
        raise ApiError(409, f"{kind} {result_id} has no result (job state {state})")
    if "motion" not in row.result:
        raise ApiError(
            409, f"{kind} {result_id} was stored without its motion block: plan it again"
        )
    planned = row.result["motion"].get("methods") or {}
    if method is not None and method not in planned:  # not in this result, as a missing array
        raise ApiError(
            404,
            f"method '{method}' is not in {kind} {result_id}: expected one of {', '.join(planned)}",
            field="method",
        )
    try:
        motion = motion_of_result(row.result)
        if samples is not None:
            if rate is not None:
                raise ApiError(422, "give rate or samples, not both", field="samples")
            joints = len(motion.joint_names)
            limit = None if max_samples is None else export_sample_limit(joints, max_samples)
            if limit is not None and samples > limit:
                raise ApiError(
                    422,
                    f"samples {samples} exceeds the limit {limit} for {joints} joints "
                    "(BIOPLAN_MAX_EXPORT_SAMPLES)",
                    field="samples",
                )
            rate = (samples - 1) / motion.duration
        check_export_size(motion, fmt, rate, max_samples)
    except BioPlanError as exc:
        field = "samples" if samples is not None else _export_field(str(exc))
        raise ApiError(422, str(exc), field=field) from None
    spec = robots.spec(session, row.robot)
    payload = motion.conditions.get("payload")
    try:
        with robot_from_spec(spec, None if payload is None else float(payload)) as robot:
            chunks = export_stream(
                motion, fmt, method=method, rate=rate, robot=robot, max_samples=max_samples
            )
    except BioPlanError as exc:  # a robot file gone or changed: its name, not its folder
        text = without_paths(exc)
        raise ApiError(422, text, field=_export_field(text)) from None
    chosen = method or row.result["motion"]["default_method"]
    filename = f"{kind}-{result_id}-{chosen}.{fmt}"  # each format's extension is its name
    return StreamingResponse(
        chunks,
        media_type=EXPORT_MEDIA_TYPES[fmt],
        headers={"Content-Disposition": f'attachment; filename="{filename}"'},
    )


def _iso_only(value: Any) -> Any:
    """Refuse a bare number as a date (pydantic would read ``0.5`` as a Unix time)."""
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return value
        raise ValueError(f"{value!r} is a number: expected an ISO 8601 date, e.g. 2026-11-26")
    return value


#: A date and time in a query, ISO 8601 only ("2026-11-26" or "2026-11-26T08:00:00Z").
IsoDateTimeQuery = Annotated[
    datetime | None,
    BeforeValidator(_iso_only),
    Query(description="ISO 8601 date or date and time (UTC when no zone is given)"),
]


def utc(value: datetime | None, field: str) -> datetime | None:
    """A query datetime in UTC (naive values are taken as UTC)."""
    if value is None:
        return None
    try:
        return value.astimezone(UTC) if value.tzinfo else value.replace(tzinfo=UTC)
    except (OverflowError, ValueError):
        raise ApiError(422, f"{field} is out of range: {value!r}", field=field) from None


def upload_name(name: str | None, fallback: str, *, field: str) -> str:
    """An uploaded file's base name, kept as metadata only (storage is by content hash).

    Raises:
        ApiError: 422 when the name holds control characters (a NUL byte was stored and its
            download then dropped the connection).
    """
    raw = name or ""
    if any(ord(ch) < 32 or ord(ch) == 127 for ch in raw):
        shown = raw.encode("unicode_escape").decode("ascii")
        raise ApiError(
            422,
            f"file name {shown!r} contains control characters: rename the file",
            field=field,
            file=shown,
        )
    base = PurePosixPath(raw.replace("\\", "/")).name.strip()
    return base[:255] or fallback
