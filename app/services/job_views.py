"""A job's JSON forms: the full one (``app.api.schemas.Job``) and the job drawer's summary.

Kept apart from the job service so that the services that create or list jobs (recordings,
cohorts, results) read them without importing the job service, which builds payloads from them.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy.orm import Session

from app.db.models import JobRecord
from app.errors import without_paths
from app.kinds import result_url
from app.services.errors import ConflictError


def _aware(value: datetime | None) -> datetime | None:
    # SQLite drops the time zone; every time stored here is UTC.
    if value is None or value.tzinfo is not None:
        return value
    return value.replace(tzinfo=UTC)


def _seconds(job: JobRecord) -> tuple[float | None, float | None]:
    """(queue time, run time so far or in all) [s] of a job."""
    created, started = _aware(job.created_at), _aware(job.started_at)
    finished = _aware(job.finished_at)
    queue_s = None if started is None or created is None else (started - created).total_seconds()
    run_s = None
    if started is not None:
        run_s = max(((finished or datetime.now(UTC)) - started).total_seconds(), 0.0)
    return (None if queue_s is None else max(queue_s, 0.0)), run_s


def job_to_dict(job: JobRecord) -> dict[str, object]:
    """The JSON form of a job (``app.api.schemas.Job``)."""
    queue_s, run_s = _seconds(job)
    return {
        "id": job.id,
        "kind": job.kind,
        "state": job.state,
        "progress": job.progress,
        "stage": job.stage or "",
        "done": job.done or 0,
        "of": job.of or 1,
        "best": job.best,
        "message": without_paths(job.message) if job.message else job.message,
        "error": without_paths(job.error) if job.error else job.error,
        "attempts": job.attempts,
        "params": job.params,
        "label": job.label,
        "created_at": _aware(job.created_at),
        "started_at": _aware(job.started_at),
        "finished_at": _aware(job.finished_at),
        "queue_seconds": queue_s,
        "run_seconds": run_s,
        "result_url": result_url(job.kind, job.id),
        "events_url": f"/api/jobs/{job.id}/events",
    }


def not_finished(
    session: Session,
    job_id: int,
    what: str,
    *,
    lacks: str = "no result",
    expected: str | None = None,
    field: str | None = None,
) -> ConflictError:
    """The 409 for ``what`` (``"plan 3"``) whose job has not stored ``lacks`` (yet): says
    the job's state, and ``expected`` when given (``"... (job state running): expected a
    finished plan"``)."""
    job = session.get(JobRecord, job_id)
    state = "unknown" if job is None else job.state
    tail = f": {expected}" if expected else ""
    return ConflictError(f"{what} has {lacks} (job state {state}){tail}", field=field)


def _about(kind: str, params: dict[str, Any]) -> str:
    """One line saying what a job works on ("curtain_wall_6dof, 4 kg, 1 s, abs_work")."""
    if kind in ("analysis", "pose"):
        return f"recording #{params.get('recording_id')}"
    if kind == "cohort":
        groups = params.get("groups") or {}
        n = sum(len(ids) for ids in groups.values())
        return f"{len(groups)} groups ({', '.join(groups)}), {n} recordings"
    if kind == "identify":
        logs = len(params.get("log_ids") or ())
        return f"{params.get('robot', '')}, {logs} log(s) -> {params.get('version', '')}"
    parts = [str(params.get("robot", ""))]
    if kind == "front":
        if params.get("payload_mass") is not None:
            parts.append(f"{params['payload_mass']:g} kg")
        parts.append(" vs ".join(params.get("objectives") or ()))
        parts.append(f"{params.get('points')} points")
    elif kind == "sweep":
        cells = len(params.get("durations") or ()) * len(params.get("payloads") or ())
        parts.append(f"{cells} cells" if cells else "")
        parts.append(", ".join(params.get("objectives") or ()))
    else:
        if params.get("payload") is not None:
            parts.append(f"{params['payload']:g} kg")
        if isinstance(params.get("duration"), int | float):
            parts.append(f"{params['duration']:g} s")
        parts.append(str(params.get("objective") or ""))
    return ", ".join(p for p in parts if p)


def job_summary(job: dict[str, Any]) -> dict[str, Any]:
    """A job's drawer form (``app.api.schemas.JobSummary``) from its JSON form: no request
    (it can be large: a template), but one line on what it works on and, for analysis and
    pose jobs, the recording they read."""
    params = job["params"]
    summary = {k: v for k, v in job.items() if k != "params"}
    summary["about"] = _about(job["kind"], params)
    rid = params.get("recording_id")
    summary["recording_id"] = rid if isinstance(rid, int) else None
    return summary
