"""The job service: the API process's side of background jobs.

It creates job rows, builds each job's plain-data payload (by its kind's record in
``app.services.kinds``), hands it to a ``JobRunner``, and is the only writer of job state:
runner events go through one queue to one writer thread, which updates the rows (progress at
most every ``progress_interval`` seconds, state changes at once) and publishes each update to
the SSE broker.

Progress is stored and served structured (``app.progress.Progress``): the overall fraction, the
stage, its units done of all, the best objective so far and a line for people.

Restart semantics (``recover``, run at start-up before requests are served): a job found
``queued`` is submitted again; a job found ``running`` (the server stopped or crashed under it)
is run again while it has attempts left (``max_attempts`` starts in all), otherwise marked
``failed`` with the reason. A graceful shutdown kills running jobs and puts them back to
``queued`` without spending an attempt, so they run at the next start. No job stays ``running``.

Bounds: at most ``max_queued`` jobs wait at once; a submission beyond it is refused
(:class:`QueueFullError`, 429 with ``Retry-After``) before anything is stored. A result whose
JSON is larger than ``inline_result_bytes`` is kept in the file store (``crud.store_result``).

Logs: a job's log (the science packages' records at INFO and above, as the runner hands them
over with its final event, bounded by ``app.logs.LogTail``) is a text file per job in
``log_dir``, written before the job's end is, and served by :meth:`JobService.log`. No schema
change: a new job removes a file its id may have left, and the start removes the files of
jobs that no longer exist.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections.abc import Collection, Iterable, Mapping
from pathlib import Path
from typing import Any, TypedDict

from sqlalchemy.orm import Session, sessionmaker

from app.db import crud
from app.db.blobs import BlobStore
from app.db.models import JobRecord, utcnow
from app.errors import BioPlanError, storage_problem, without_paths
from app.jobs.runner import JobEvent, JobRunner
from app.kinds import KIND_PATHS
from app.names import MAX_VIDEO_SECONDS, TERMINAL_JOB_STATES
from app.services import recordings
from app.services.broker import JobBroker
from app.services.errors import ConflictError, ServiceError, found
from app.services.job_views import job_summary, job_to_dict
from app.services.kinds import KINDS, KindContext, analysis_template
from app.services.limits import JobLimits
from app.services.robots import RobotCatalog

__all__ = [
    "KIND_PATHS",
    "NO_PROGRESS",
    "JobService",
    "QueueFullError",
    "job_summary",
    "job_to_dict",
]

logger = logging.getLogger(__name__)


class ProgressColumns(TypedDict):
    """A job row's structured progress (``JobRecord`` columns of the same names)."""

    progress: float
    stage: str
    done: int
    of: int
    best: float | None


#: Structured progress of a job that has not reported any yet.
NO_PROGRESS: ProgressColumns = {"progress": 0.0, "stage": "", "done": 0, "of": 1, "best": None}


def _progress_columns(ev: JobEvent) -> dict[str, object]:
    """Job columns from a ``progress`` event's structured detail."""
    detail = ev.detail
    if not detail:
        return {**NO_PROGRESS, "progress": float(ev.progress or 0.0), "message": ev.message}
    return {
        "progress": detail["fraction"],
        "stage": detail["stage"][:32],
        "done": detail["done"],
        "of": detail["of"],
        "best": detail["best"],
        "message": ev.message,
    }


_STOP = object()

#: Seconds a client refused for a full queue is told to wait.
QUEUE_RETRY_AFTER = 30


class QueueFullError(ServiceError):
    """Too many jobs wait already: the submission is refused, nothing is stored (429)."""

    status = 429
    title = "Too Many Requests"

    def __init__(self, limit: int) -> None:
        super().__init__(
            f"the job queue is full: {limit} jobs are waiting, the limit "
            f"(BIOPLAN_MAX_QUEUED={limit}); nothing was stored: retry in a while"
        )
        self.headers = {"Retry-After": str(QUEUE_RETRY_AFTER)}


class JobService:
    """Submits, tracks, cancels and recovers jobs.

    Args:
        sessions: session factory of the service database.
        blobs: the file store (raw recordings, robot models).
        runner: where jobs run.
        broker: SSE fan-out.
        robots: built-in and uploaded robots (jobs receive their specs).
        max_attempts: starts allowed per job (a restart under a running job spends one).
        progress_interval: shortest time between two progress writes of one job [s].
        max_video_seconds: longest video a pose job turns into landmarks [s].
        scratch_dir: folder for pose jobs' temporary copies of videos (None: the system's
            temporary folder; a local executor gets one in the data folder).
        max_queued: jobs waiting at once (None: no bound); more are refused.
        inline_result_bytes: largest result JSON kept in the database row; larger ones go to
            the file store (None: always in the row).
        log_dir: folder of the jobs' logs (None: ``job-logs`` beside the file store's folder,
            in the data directory).
    """

    def __init__(
        self,
        *,
        sessions: sessionmaker[Session],
        blobs: BlobStore,
        runner: JobRunner,
        broker: JobBroker,
        robots: RobotCatalog | None = None,
        max_attempts: int = 2,
        progress_interval: float = 0.25,
        max_video_seconds: float = MAX_VIDEO_SECONDS,
        scratch_dir: Path | None = None,
        limits: JobLimits | None = None,
        max_queued: int | None = None,
        inline_result_bytes: int | None = None,
        log_dir: Path | None = None,
    ) -> None:
        self.sessions = sessions
        self.log_dir = log_dir if log_dir is not None else blobs.root.parent / "job-logs"
        self.max_queued = max_queued
        self.inline_result_bytes = inline_result_bytes
        self._submitting = threading.Lock()
        self.limits = limits or JobLimits()
        self.blobs = blobs
        self.runner = runner
        self.broker = broker
        self.robots = robots or RobotCatalog(blobs=blobs)
        self.max_attempts = max_attempts
        self.progress_interval = progress_interval
        self.max_video_seconds = max_video_seconds
        self.scratch_dir = scratch_dir
        self._events: queue.Queue[object] = queue.Queue()  # JobEvents, then _STOP
        self._writer: threading.Thread | None = None
        self._closed = False

    # lifecycle -------------------------------------------------------------------------------

    def start(self) -> dict[str, int]:
        """Start the writer thread and the runner, then recover jobs left by a previous run."""
        self._writer = threading.Thread(target=self._write_loop, name="bioplan-job-writer")
        self._writer.daemon = True
        self._writer.start()
        self.runner.start(self._events.put)
        self._remove_stray_logs()
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
        self,
        *,
        kind: str,
        params: Mapping[str, object],
        resource: Mapping[str, object],
        label: str | None = None,
        left_out: Collection[str] = (),
        bounded: bool = True,
    ) -> dict[str, Any]:
        """Create a queued job (and its result row) and hand it to the runner; ``label`` is
        the user's name for its result; ``left_out`` names the fields the request did not give
        (their defaults are lowered to the server's caps, ``JobLimits.fit``); ``bounded``
        False skips the queue bound (a follow-up job the server starts itself).

        Raises:
            ServiceError: the request asks for more work than a configured limit allows.
            QueueFullError: ``max_queued`` jobs are waiting already (nothing stored).
        """
        params = self.limits.fit(params, left_out)
        # One submission at a time counts and inserts: the bound holds under a burst (and one
        # server owns its database: ``app.db.lock.lock_database``).
        with self._submitting, self.sessions() as session:
            limit = self.max_queued if bounded else None
            if limit is not None and crud.count_jobs(session=session, state="queued") >= limit:
                raise QueueFullError(limit)
            job = crud.create_job(
                session=session, kind=kind, params=params, resource=dict(resource), label=label
            )
            data = job_to_dict(job)
        with contextlib.suppress(OSError):  # a deleted job's, under a reused id
            self._log_path(job.id).unlink(missing_ok=True)
        self._publish(job.id)  # the job drawers see it queued
        self._dispatch(job.id)
        return data

    def check_room(self, jobs: int = 1) -> None:
        """Refuse at once (QueueFullError) when ``jobs`` more would pass the queue bound: a
        request that stores something and then queues its jobs asks first, then submits them
        with ``bounded=False``, so a full queue never leaves half of it done."""
        if self.max_queued is None or jobs <= 0:
            return
        with self.sessions() as session:
            if crud.count_jobs(session=session, state="queued") + jobs > self.max_queued:
                raise QueueFullError(self.max_queued)

    def cancel(self, job_id: int) -> dict[str, object]:
        """Cancel a queued or running job.

        Returns:
            The job as it is now.

        Raises:
            NotFoundError: no such job.
            ConflictError: the job already ended.
        """
        job = self.get(job_id)
        if job["state"] in TERMINAL_JOB_STATES:
            raise ConflictError(f"job {job_id} already ended ({job['state']})", job=job)
        self.runner.cancel(job_id)
        self._set_state(job_id, "cancelled", message="cancelled by request")
        return self.get(job_id)

    def find(self, job_id: int) -> dict[str, object] | None:
        """The job's JSON form, or None when there is no such job."""
        with self.sessions() as session:
            job = crud.get_job(session=session, job_id=job_id)
            return None if job is None else job_to_dict(job)

    def recent(self, limit: int, also: Iterable[int] = ()) -> list[dict[str, Any]]:
        """Drawer forms of the newest ``limit`` jobs, every active job and the jobs ``also``
        names (those a client shows as active), newest first."""
        with self.sessions() as session:
            newest, _ = crud.list_jobs(session=session, limit=limit)
            found = {j.id: j for j in newest + crud.active_jobs(session=session)}
            for job_id in set(also) - found.keys():
                job = crud.get_job(session=session, job_id=job_id)
                if job is not None:
                    found[job_id] = job
            return [job_summary(job_to_dict(found[i])) for i in sorted(found, reverse=True)]

    def get(self, job_id: int) -> dict[str, object]:
        """The job's JSON form.

        Raises:
            NotFoundError: no such job.
        """
        return found(self.find(job_id), f"job {job_id}")

    def log(self, job_id: int) -> dict[str, object]:
        """A job's log: ``lines`` (its records at INFO and above, oldest first, paths cut to
        their last part), ``complete`` (the job ended: the log is all there is; while it is
        queued or running its log is not here yet) and ``state``.

        Raises:
            NotFoundError: no such job.
        """
        job = self.get(job_id)
        try:
            text = self._log_path(job_id).read_text(encoding="utf-8", errors="replace")
        except FileNotFoundError:
            text = ""
        return {
            "job_id": job_id,
            "state": job["state"],
            "complete": job["state"] in TERMINAL_JOB_STATES,
            "lines": [without_paths(line) for line in text.splitlines()],
        }

    def _log_path(self, job_id: int) -> Path:
        return self.log_dir / f"{int(job_id)}.log"

    def _write_log(self, job_id: int, lines: list[str]) -> None:
        """Keep a job's log (a failure to write it is logged, never the job's failure)."""
        try:
            self.log_dir.mkdir(parents=True, exist_ok=True)
            path = self._log_path(job_id)
            tmp = path.with_suffix(".tmp")
            tmp.write_text("".join(f"{line}\n" for line in lines), encoding="utf-8")
            tmp.replace(path)
        except OSError as exc:
            logger.warning("the log of job %d could not be kept: %s", job_id, exc)

    def _remove_stray_logs(self) -> None:
        """Remove the logs of jobs that no longer exist (deleted with their results)."""
        if not self.log_dir.is_dir():
            return
        with self.sessions() as session:
            for path in self.log_dir.glob("*.log"):
                if (
                    path.stem.isdigit()
                    and crud.get_job(session=session, job_id=int(path.stem)) is None
                ):
                    with contextlib.suppress(OSError):  # read-only: left for the next start
                        path.unlink(missing_ok=True)

    def recover(self) -> dict[str, int]:
        """Resubmit or fail the jobs a previous server left queued or running."""
        counts = {"requeued": 0, "failed": 0}
        with self.sessions() as session:
            jobs = [(j.id, j.state, j.attempts) for j in crud.active_jobs(session=session)]
            for job_id, state, attempts in jobs:
                outcome = self._recover_one(session, job_id, state, attempts)
                counts[outcome] += 1
        for job_id, state, attempts in jobs:
            if not (state == "running" and attempts >= self.max_attempts):
                self._dispatch(job_id)
        if any(counts.values()):
            logger.warning("recovered jobs after restart: %s", counts)
        return counts

    def _recover_one(self, session: Session, job_id: int, state: str, attempts: int) -> str:
        """Fail or requeue one job found active at start-up; returns what was done."""
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
            return "failed"
        message = "queued"
        if state == "running":
            message = (
                "the server stopped while this job was running; queued again "
                f"(attempt {attempts + 1} of {self.max_attempts})"
            )
        crud.update_job(
            session=session, job_id=job_id, state="queued", message=message, **NO_PROGRESS
        )
        return "requeued"

    # payloads ---------------------------------------------------------------------------------

    @staticmethod
    def analysis_template(session: Session, analysis_id: int) -> dict[str, object]:
        """The human template of a finished analysis (``app.services.kinds``).

        Raises:
            NotFoundError: no such analysis.
            ConflictError: it has no template (yet).
        """
        return analysis_template(session, analysis_id)

    def context(self) -> KindContext:
        """What the kinds' payload builders and result stores use besides the session."""
        return KindContext(
            blobs=self.blobs,
            robots=self.robots,
            max_video_seconds=self.max_video_seconds,
            scratch_dir=self.scratch_dir,
            inline_result_bytes=self.inline_result_bytes,
        )

    def build_payload(self, session: Session, job: JobRecord) -> Mapping[str, object]:
        """The job function's input, from the request stored with the job (its kind's
        ``payload`` builder)."""
        return KINDS[job.kind].payload(session, self.context(), job.params)

    def _dispatch(self, job_id: int) -> None:
        try:
            with self.sessions() as session:
                job = crud.get_job(session=session, job_id=job_id)
                if job is None:
                    return
                kind = job.kind
                payload = self.build_payload(session, job)
        except Exception as exc:
            # Its inputs vanished (recording or robot deleted while it was queued): the job
            # fails with the reason instead of running; anything else is logged as the bug it is.
            if isinstance(exc, BioPlanError):
                logger.warning("job %d cannot start: %s", job_id, exc)
            else:
                logger.exception("job %d cannot start", job_id)
            self._set_state(job_id, "failed", error=f"cannot start: {exc}", message="failed")
            return
        self.runner.submit(job_id, kind, payload)

    # event writer ------------------------------------------------------------------------------

    def _set_state(self, job_id: int, state: str, **values: Any) -> None:
        with self.sessions() as session:
            if state in TERMINAL_JOB_STATES:
                values.setdefault("finished_at", utcnow())
            crud.update_job(session=session, job_id=job_id, state=state, **values)
        self._publish(job_id)

    def _publish(self, job_id: int) -> None:
        if self.broker.subscribers(job_id) == 0:
            return
        data = self.find(job_id)
        if data is not None:
            self.broker.publish(job_id, data)

    def _update(self, job_id: int, **values: Any) -> None:
        with self.sessions() as session:
            crud.update_job(session=session, job_id=job_id, **values)
        self._publish(job_id)

    def _apply(self, ev: JobEvent) -> None:
        if ev.log is not None:  # before the end it comes with: a client that sees it finds it
            self._write_log(ev.job_id, ev.log)
        if ev.type == "started":
            self._update(
                ev.job_id,
                state="running",
                started_at=utcnow(),
                message=ev.message or "running",
                attempts=JobRecord.attempts + 1,
                **NO_PROGRESS,
            )
        elif ev.type == "progress":
            self._update(ev.job_id, **_progress_columns(ev))
        elif ev.type == "succeeded":
            self._store(ev)
        elif ev.type == "failed":
            self._set_state(ev.job_id, "failed", error=ev.error or "failed", message="failed")
        elif ev.type == "cancelled":
            self._set_state(ev.job_id, "cancelled", message=ev.message or "cancelled")

    def _store(self, ev: JobEvent) -> None:
        """Keep a finished job's output (its kind's ``store``), then start what follows it."""
        try:
            with self.sessions() as session:
                job = crud.get_job(session=session, job_id=ev.job_id)
                if job is None:
                    return
                if ev.result is None:  # a succeeded event always carries the output
                    raise ValueError("the job returned no output")
                stored = KINDS[job.kind].store(session, self.context(), job, ev.result)
        except Exception as exc:
            logger.exception("cannot store the result of job %d", ev.job_id)
            self._set_state(ev.job_id, "failed", error=f"cannot store the result: {exc}")
            return
        if stored.error is not None:
            self._set_state(ev.job_id, "failed", error=stored.error)
            return
        self._publish(ev.job_id)
        self._analyse_after_pose(stored.analyse_recording)

    def _analyse_after_pose(self, recording_id: int | None) -> None:
        """Analyse a recording once its video became pose (with the options of its newest
        analysis); not while another of its videos is still being extracted."""
        if recording_id is None:
            return
        try:
            with self.sessions() as session:
                params = recordings.rerun_params(session, recording_id)
        except BioPlanError as exc:
            logger.info("recording %d not analysed after its pose job: %s", recording_id, exc)
            return
        self.submit(
            kind="analysis",
            params=params,
            resource={"recording_id": recording_id},
            bounded=False,
        )

    def _write_again(self, events: list[JobEvent]) -> list[JobEvent]:
        """Write the ends a full disk refused, in order; returns those still refused."""
        for i, ev in enumerate(events):
            try:
                self._apply(ev)
            except Exception as exc:
                if storage_problem(exc) is None:
                    logger.exception("job event could not be written: %r", ev)
                    continue
                return events[i:]
        return []

    def _write_loop(self) -> None:
        pending: dict[int, JobEvent] = {}
        unwritten: list[JobEvent] = []  # ends a full disk refused, written once there is room
        last_flush = time.monotonic()
        while True:
            try:
                ev = self._events.get(timeout=self.progress_interval)
            except queue.Empty:
                ev = None
            unwritten = self._write_again(unwritten)
            try:
                if ev is _STOP:
                    return
                if isinstance(ev, JobEvent):
                    if ev.type == "progress":
                        pending[ev.job_id] = ev  # only the latest progress is written
                    else:
                        last = pending.pop(ev.job_id, None)
                        if last is not None and ev.type == "succeeded":
                            self._apply(last)  # a job's last progress is shown, however fast
                        self._apply(ev)
                now = time.monotonic()
                if pending and now - last_flush >= self.progress_interval:
                    for p in list(pending.values()):
                        self._apply(p)
                    pending.clear()
                    last_flush = now
            except Exception as exc:  # keep writing whatever one bad event did
                if (
                    isinstance(ev, JobEvent)
                    and ev.type in TERMINAL_JOB_STATES
                    and storage_problem(exc) is not None
                ):
                    logger.error(
                        "storage full or read-only: job %d's end is kept until it can be written",
                        ev.job_id,
                    )
                    unwritten.append(ev)
                else:
                    logger.exception("job event could not be written: %r", ev)
