"""JobService: job rows follow the runner's events; restarts leave no job running."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from app.db import crud
from app.db.arrays import decode_arrays
from app.db.blobs import BlobStore
from app.db.models import JobRecord, Plan
from app.db.session import make_engine, make_sessionmaker, upgrade
from app.jobs.broker import JobBroker
from app.jobs.runner import EventSink, JobRunner, LocalRunner
from app.jobs.service import JobService
from tests.jobs.targets import service_target


class RecordingRunner(JobRunner):
    """A runner that only records what it is asked to do (for restart tests)."""

    executor = "record"

    def __init__(self) -> None:
        self.submitted: list[tuple[int, str]] = []
        self.cancelled: list[int] = []

    def start(self, sink: EventSink) -> None:
        self.sink = sink

    def submit(self, job_id: int, kind: str, payload: dict[str, Any]) -> None:
        self.submitted.append((job_id, kind))

    def cancel(self, job_id: int) -> bool:
        self.cancelled.append(job_id)
        return True

    def shutdown(self) -> None:
        pass

    def info(self) -> dict[str, Any]:
        return {"executor": self.executor, "workers": 0, "running": 0, "queued": 0}


@pytest.fixture
def sessions(tmp_path: Path) -> Iterator[sessionmaker[Session]]:
    url = f"sqlite:///{tmp_path / 'jobs.db'}"
    upgrade(url)
    engine = make_engine(url)
    yield make_sessionmaker(engine)
    engine.dispose()


def _service(
    sessions: sessionmaker[Session], runner: JobRunner, tmp_path: Path, **kw: Any
) -> JobService:
    svc = JobService(
        sessions=sessions,
        blobs=BlobStore(tmp_path / "blobs"),
        runner=runner,
        broker=JobBroker(),
        progress_interval=0.05,
        **kw,
    )
    svc.__dict__["builtin_robots"] = ["arm"]  # no planning package needed here
    return svc


def _job(sessions: sessionmaker[Session], state: str, attempts: int) -> int:
    with sessions() as s:
        job = crud.create_job(
            session=s, kind="plan", params={"robot": "arm"}, resource={"robot": "arm"}
        )
        crud.update_job(session=s, job_id=job.id, state=state, attempts=attempts)
        return job.id


def _state(sessions: sessionmaker[Session], job_id: int) -> JobRecord:
    with sessions() as s:
        job = crud.get_job(session=s, job_id=job_id)
        assert job is not None
        return job


def _wait(
    sessions: sessionmaker[Session], job_id: int, states: set[str], timeout: float = 20
) -> JobRecord:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job = _state(sessions, job_id)
        if job.state in states:
            return job
        time.sleep(0.05)
    raise AssertionError(f"job {job_id} stayed {_state(sessions, job_id).state}")


def test_restart_requeues_or_fails_every_unfinished_job(
    sessions: sessionmaker[Session], tmp_path: Path
) -> None:
    queued = _job(sessions, "queued", 0)
    interrupted = _job(sessions, "running", 1)
    exhausted = _job(sessions, "running", 2)
    finished = _job(sessions, "succeeded", 1)
    runner = RecordingRunner()
    svc = _service(sessions, runner, tmp_path, max_attempts=2)
    counts = svc.start()
    assert counts == {"requeued": 2, "failed": 1}
    assert sorted(runner.submitted) == [(queued, "plan"), (interrupted, "plan")]
    assert _state(sessions, interrupted).state == "queued"
    assert "attempt 2 of 2" in _state(sessions, interrupted).message
    failed = _state(sessions, exhausted)
    assert failed.state == "failed"
    assert failed.error is not None and "server stopped" in failed.error
    assert _state(sessions, finished).state == "succeeded"
    with sessions() as s:
        assert all(j.state != "running" for j in s.scalars(select(JobRecord)))
    svc.close()


def test_graceful_shutdown_requeues_running_jobs_without_spending_an_attempt(
    sessions: sessionmaker[Session], tmp_path: Path
) -> None:
    svc = _service(sessions, RecordingRunner(), tmp_path)
    svc.start()
    job_id = _job(sessions, "running", 1)
    svc.close()
    job = _state(sessions, job_id)
    assert (job.state, job.attempts) == ("queued", 0)


def test_events_update_rows_and_the_result_is_stored(
    sessions: sessionmaker[Session], tmp_path: Path
) -> None:
    runner = LocalRunner(1, target=service_target, preload=())
    svc = _service(sessions, runner, tmp_path)
    svc.start()
    try:
        job = svc.submit(
            kind="plan",
            params={"robot": "arm", "behave": "count", "n": 20, "dt": 0.05},
            resource={"robot": "arm"},
        )
        seen = set()
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            row = _state(sessions, job["id"])
            seen.add((row.state, round(row.progress, 1)))
            if row.state == "succeeded":
                break
            time.sleep(0.02)
        # Progress was written while it ran, not only at the end.
        assert any(state == "running" and 0 < p < 1 for state, p in seen)
        row = _state(sessions, job["id"])
        assert (row.state, row.progress, row.attempts) == ("succeeded", 1.0, 1)
        assert row.started_at is not None and row.finished_at is not None
        with sessions() as s:
            plan = s.get(Plan, job["id"])
            assert plan is not None and plan.result == {"steps": 20}
            assert plan.arrays is not None
            np.testing.assert_array_equal(decode_arrays(plan.arrays)["t"], np.linspace(0, 1, 20))
    finally:
        svc.close()


def test_cancel_marks_cancelled_and_failures_keep_their_message(
    sessions: sessionmaker[Session], tmp_path: Path
) -> None:
    runner = LocalRunner(2, target=service_target, preload=())
    svc = _service(sessions, runner, tmp_path)
    svc.start()
    try:
        slow = svc.submit(
            kind="plan", params={"robot": "arm", "behave": "sleep", "seconds": 60},
            resource={"robot": "arm"},
        )  # fmt: skip
        bad = svc.submit(
            kind="plan", params={"robot": "arm", "behave": "fail", "why": "payload < 0"},
            resource={"robot": "arm"},
        )  # fmt: skip
        gone = svc.submit(kind="plan", params={"robot": "nope"}, resource={"robot": "nope"})
        _wait(sessions, slow["id"], {"running"})
        out = svc.cancel(slow["id"])
        assert out is not None and out["state"] == "cancelled"
        assert _wait(sessions, slow["id"], {"cancelled"}).finished_at is not None
        failed = _wait(sessions, bad["id"], {"failed"})
        assert failed.error == "bad input: payload < 0"
        unknown = _wait(sessions, gone["id"], {"failed"})
        assert unknown.error is not None and "unknown robot 'nope'" in unknown.error
        assert runner.info()["running"] == 0
    finally:
        svc.close()
