"""The job service: the API process's side of background jobs.

It creates job rows, builds each job's plain-data payload from the database and the file store,
hands it to a ``JobRunner``, and is the only writer of job state: runner events go through one
queue to one writer thread, which updates the rows (progress at most every ``progress_interval``
seconds, state changes at once) and publishes each update to the SSE broker.

Restart semantics (``recover``, run at start-up before requests are served): a job found
``queued`` is submitted again; a job found ``running`` (the server stopped or crashed under it)
is run again while it has attempts left (``max_attempts`` starts in all), otherwise marked
``failed`` with the reason. A graceful shutdown kills running jobs and puts them back to
``queued`` without spending an attempt, so they run at the next start. No job stays ``running``.
"""

from __future__ import annotations

import functools
import logging
import queue
import threading
import time
from datetime import UTC, datetime
from typing import Any

from sqlalchemy.orm import Session, sessionmaker

from app.db import crud
from app.db.blobs import BlobStore
from app.db.models import TERMINAL_STATES, Analysis, JobRecord, RecordingSession, utcnow
from app.jobs import tasks
from app.jobs.broker import JobBroker
from app.jobs.runner import JobEvent, JobRunner

logger = logging.getLogger(__name__)

KIND_PATHS = {
    "analysis": "analyses",
    "plan": "plans",
    "simulation": "simulations",
    "sweep": "sweeps",
}


class UnknownRobotError(LookupError):
    """A request names a robot that is neither built in nor uploaded."""


def _aware(value: datetime | None) -> datetime | None:
    # SQLite drops the time zone; every time stored here is UTC.
    if value is None or value.tzinfo is not None:
        return value
    return value.replace(tzinfo=UTC)


def job_to_dict(job: JobRecord) -> dict[str, Any]:
    """The JSON form of a job (``app.api.schemas.Job``)."""
    created, started = _aware(job.created_at), _aware(job.started_at)
    finished = _aware(job.finished_at)
    queue_s = None if started is None or created is None else (started - created).total_seconds()
    run_s = None
    if started is not None:
        end = finished or datetime.now(UTC)
        run_s = max((end - started).total_seconds(), 0.0)
    return {
        "id": job.id,
        "kind": job.kind,
        "state": job.state,
        "progress": job.progress,
        "message": job.message,
        "error": job.error,
        "attempts": job.attempts,
        "params": job.params,
        "created_at": created,
        "started_at": started,
        "finished_at": finished,
        "queue_seconds": None if queue_s is None else max(queue_s, 0.0),
        "run_seconds": run_s,
        "result_url": f"/api/{KIND_PATHS.get(job.kind, job.kind)}/{job.id}",
        "events_url": f"/api/jobs/{job.id}/events",
    }


_STOP = object()


class JobService:
    """Submits, tracks, cancels and recovers jobs.

    Args:
        sessions: session factory of the service database.
        blobs: the file store (raw recordings, robot models).
        runner: where jobs run.
        broker: SSE fan-out.
        max_attempts: starts allowed per job (a restart under a running job spends one).
        progress_interval: shortest time between two progress writes of one job [s].
    """

    def __init__(
        self,
        *,
        sessions: sessionmaker[Session],
        blobs: BlobStore,
        runner: JobRunner,
        broker: JobBroker,
        max_attempts: int = 2,
        progress_interval: float = 0.25,
    ) -> None:
        self.sessions = sessions
        self.blobs = blobs
        self.runner = runner
        self.broker = broker
        self.max_attempts = max_attempts
        self.progress_interval = progress_interval
        self._events: queue.Queue[Any] = queue.Queue()
        self._writer: threading.Thread | None = None
        self._closed = False
        self._described: dict[str, dict[str, Any]] = {}

    # lifecycle -------------------------------------------------------------------------------

    def start(self) -> dict[str, int]:
        """Start the writer thread and the runner, then recover jobs left by a previous run."""
        self._writer = threading.Thread(target=self._write_loop, name="bioplan-job-writer")
        self._writer.daemon = True
        self._writer.start()
        self.runner.start(self._events.put)
        return self.recover()

    def close(self) -> None:
        """Stop the runner and put interrupted jobs back in the queue for the next start."""
        if self._closed:
            return
        self._closed = True
        self.runner.shutdown()
        self._events.put(_STOP)
        if self._writer is not None:
            self._writer.join(timeout=10)
        with self.sessions() as session:
            for job in crud.active_jobs(session=session):
                if job.state == "running":
                    crud.update_job(
                        session=session,
                        job_id=job.id,
                        state="queued",
                        attempts=max(job.attempts - 1, 0),
                        message="interrupted by a server shutdown; runs again at the next start",
                    )

    # API --------------------------------------------------------------------------------------

    def submit(
        self, *, kind: str, params: dict[str, Any], resource: dict[str, Any]
    ) -> dict[str, Any]:
        """Create a queued job (and its result row) and hand it to the runner."""
        with self.sessions() as session:
            job = crud.create_job(session=session, kind=kind, params=params, resource=resource)
            data = job_to_dict(job)
        self._dispatch(job.id)
        return data

    def cancel(self, job_id: int) -> dict[str, Any] | None:
        """Cancel a queued or running job; a finished job is returned unchanged.

        Returns:
            The job as it is now, or None when there is no such job.
        """
        with self.sessions() as session:
            job = crud.get_job(session=session, job_id=job_id)
            if job is None:
                return None
            if job.state in TERMINAL_STATES:
                return job_to_dict(job)
        self.runner.cancel(job_id)
        self._set_state(job_id, "cancelled", message="cancelled by request")
        return self.get(job_id)

    def get(self, job_id: int) -> dict[str, Any] | None:
        with self.sessions() as session:
            job = crud.get_job(session=session, job_id=job_id)
            return None if job is None else job_to_dict(job)

    def recover(self) -> dict[str, int]:
        """Resubmit or fail the jobs a previous server left queued or running."""
        counts = {"requeued": 0, "failed": 0}
        with self.sessions() as session:
            jobs = [(j.id, j.state, j.attempts) for j in crud.active_jobs(session=session)]
            for job_id, state, attempts in jobs:
                if state == "running" and attempts >= self.max_attempts:
                    crud.update_job(
                        session=session,
                        job_id=job_id,
                        state="failed",
                        finished_at=utcnow(),
                        error=(
                            "the server stopped while this job was running "
                            f"(attempt {attempts} of {self.max_attempts}); not run again"
                        ),
                        message="failed",
                    )
                    counts["failed"] += 1
                    continue
                message = "queued"
                if state == "running":
                    message = (
                        "the server stopped while this job was running; queued again "
                        f"(attempt {attempts + 1} of {self.max_attempts})"
                    )
                crud.update_job(
                    session=session, job_id=job_id, state="queued", progress=0.0, message=message
                )
                counts["requeued"] += 1
        for job_id, state, attempts in jobs:
            if not (state == "running" and attempts >= self.max_attempts):
                self._dispatch(job_id)
        if any(counts.values()):
            logger.warning("recovered jobs after restart: %s", counts)
        return counts

    # payloads ---------------------------------------------------------------------------------

    @functools.cached_property
    def builtin_robots(self) -> list[str]:
        try:
            return tasks.builtin_robots()
        except ImportError:  # planning package not installed: only uploaded robots
            logger.warning("app.planning.robots is missing: no built-in robots")
            return []

    def describe_builtin(self, name: str) -> dict[str, Any]:
        """Joints and limits of a built-in robot (loaded once, then cached)."""
        cached = self._described.get(name)
        if cached is None:
            cached = tasks.describe_robot({"name": name})
            cached["builtin"] = True
            self._described[name] = cached
        return dict(cached)

    def robot_joints(self, session: Session, name: str) -> list[str]:
        """Joint names of a built-in or uploaded robot.

        Raises:
            UnknownRobotError: no such robot.
        """
        if name in self.builtin_robots:
            return list(self.describe_builtin(name)["joint_names"])
        row = crud.get_robot(session=session, name=name)
        if row is None:
            self.robot_spec(session, name, files=False)  # raises with the list of names
        assert row is not None
        return list(row.description.get("joint_names", []))

    def robot_spec(self, session: Session, name: str, *, files: bool = True) -> dict[str, Any]:
        """The plain-data robot spec for a job: a built-in name, or the uploaded files.

        Raises:
            UnknownRobotError: no such robot.
        """
        if name in self.builtin_robots:
            return {"name": name}
        row = crud.get_robot(session=session, name=name)
        if row is None:
            uploaded = [r.name for r in crud.list_robots(session=session)]
            raise UnknownRobotError(
                f"unknown robot {name!r} (expected one of {sorted(self.builtin_robots + uploaded)})"
            )
        if not files:
            return {"name": row.name}
        return {
            "name": row.name,
            "urdf": self.blobs.get(row.urdf_sha256),
            "urdf_name": row.urdf_name,
            "mjcf": None if row.mjcf_sha256 is None else self.blobs.get(row.mjcf_sha256),
            "mjcf_name": row.mjcf_name,
            "payload": row.payload,
        }

    @staticmethod
    def analysis_template(session: Session, analysis_id: int) -> dict[str, Any]:
        """The human template of a finished analysis."""
        row = session.get(Analysis, analysis_id)
        if row is None:
            raise LookupError(f"analysis {analysis_id} does not exist")
        if row.template is None:
            job = session.get(JobRecord, analysis_id)
            state = "unknown" if job is None else job.state
            raise LookupError(f"analysis {analysis_id} has no template yet (job state {state})")
        return row.template

    def build_payload(self, session: Session, job: JobRecord) -> dict[str, Any]:
        """The job function's input, from the request stored with the job."""
        p = job.params
        if job.kind == "analysis":
            rec = session.get(RecordingSession, p["recording_id"])
            if rec is None:
                raise LookupError(f"recording {p['recording_id']} no longer exists")
            read_options = dict(rec.options)
            for key in ("emg_rate", "muscle_map"):
                if p.get(key) is not None:
                    read_options[key] = p[key]
            load = p.get("load_mass")
            options = {
                "emg_rate": p.get("emg_rate"),
                "muscle_map": read_options.get("muscle_map"),
                "phase_bounds_deg": p.get("phase_bounds_deg"),
                "body_mass": p.get("body_mass"),
                "body_height": p.get("body_height"),
                "load_mass": load if load is not None else rec.load_kg,
                "together": p.get("together") or None,
                "offset": p.get("offset"),
            }
            files = [{"name": f.original_name, "data": self.blobs.get(f.sha256)} for f in rec.files]
            return {"files": files, "read_options": read_options, "options": options}
        payload = dict(p)
        payload["robot"] = self.robot_spec(session, p["robot"])
        if job.kind in ("plan", "simulation") and p.get("template_analysis_id") is not None:
            payload["template"] = self.analysis_template(session, p["template_analysis_id"])
        payload.pop("template_analysis_id", None)
        return payload

    def _dispatch(self, job_id: int) -> None:
        try:
            with self.sessions() as session:
                job = crud.get_job(session=session, job_id=job_id)
                if job is None:
                    return
                kind = job.kind
                payload = self.build_payload(session, job)
        except Exception as exc:
            logger.warning("job %d cannot start: %s", job_id, exc)
            self._set_state(job_id, "failed", error=f"cannot start: {exc}", message="failed")
            return
        self.runner.submit(job_id, kind, payload)

    # event writer ------------------------------------------------------------------------------

    def _set_state(self, job_id: int, state: str, **values: Any) -> None:
        with self.sessions() as session:
            if state in TERMINAL_STATES:
                values.setdefault("finished_at", utcnow())
            crud.update_job(session=session, job_id=job_id, state=state, **values)
        self._publish(job_id)

    def _publish(self, job_id: int) -> None:
        if self.broker.subscribers(job_id) == 0:
            return
        data = self.get(job_id)
        if data is not None:
            self.broker.publish(job_id, data)

    def _apply(self, ev: JobEvent) -> None:
        if ev.type == "started":
            with self.sessions() as session:
                crud.update_job(
                    session=session,
                    job_id=ev.job_id,
                    state="running",
                    started_at=utcnow(),
                    progress=0.0,
                    message=ev.message or "running",
                    attempts=JobRecord.attempts + 1,
                )
            self._publish(ev.job_id)
        elif ev.type == "progress":
            with self.sessions() as session:
                crud.update_job(
                    session=session,
                    job_id=ev.job_id,
                    progress=float(ev.progress or 0.0),
                    message=ev.message,
                )
            self._publish(ev.job_id)
        elif ev.type == "succeeded":
            self._store(ev)
        elif ev.type == "failed":
            self._set_state(ev.job_id, "failed", error=ev.error or "failed", message="failed")
        elif ev.type == "cancelled":
            self._set_state(ev.job_id, "cancelled", message=ev.message or "cancelled")

    def _store(self, ev: JobEvent) -> None:
        out = ev.result or {}
        try:
            with self.sessions() as session:
                job = crud.get_job(session=session, job_id=ev.job_id)
                if job is None:
                    return
                crud.store_result(
                    session=session,
                    job_id=ev.job_id,
                    kind=job.kind,
                    result=out["result"],
                    arrays=out.get("arrays"),
                    template=out.get("template"),
                )
        except Exception as exc:
            logger.exception("cannot store the result of job %d", ev.job_id)
            self._set_state(ev.job_id, "failed", error=f"cannot store the result: {exc}")
            return
        self._publish(ev.job_id)

    def _write_loop(self) -> None:
        pending: dict[int, JobEvent] = {}
        last_flush = time.monotonic()
        while True:
            try:
                ev = self._events.get(timeout=self.progress_interval)
            except queue.Empty:
                ev = None
            try:
                if ev is _STOP:
                    return
                if isinstance(ev, JobEvent):
                    if ev.type == "progress":
                        pending[ev.job_id] = ev  # only the latest progress is written
                    else:
                        pending.pop(ev.job_id, None)
                        self._apply(ev)
                now = time.monotonic()
                if pending and now - last_flush >= self.progress_interval:
                    for p in list(pending.values()):
                        self._apply(p)
                    pending.clear()
                    last_flush = now
            except Exception:  # keep writing whatever one bad event did
                logger.exception("job event could not be written: %r", ev)
