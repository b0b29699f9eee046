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
from app.jobs.runner import JobRunner, LocalRunner
from app.services import ConflictError, JobBroker, JobService, NotFoundError
from tests.utils.jobs import RecordingRunner, service_target


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
    svc.robots.__dict__["builtin"] = ["arm"]  # no planning package needed here
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
    sessions: sessionmaker[Session], job_id: int, states: set[str], timeout: float = 60
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
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            row = _state(sessions, job["id"])
            seen.add((row.state, round(row.progress, 1), row.stage, row.done, row.of, row.best))
            if row.state == "succeeded":
                break
            time.sleep(0.02)
        # Progress was written while it ran, not only at the end, with its structure: the
        # target reports step i of 20 with best = 20 - i + 1 (tests.utils.jobs.target).
        running = [s for s in seen if s[0] == "running" and 0 < s[1] < 1]
        assert running
        for _, _, stage, done, of, best in running:
            assert (stage, of) == ("count", 20) and 1 <= done <= 20 and best == 20 - done + 1
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
        assert out["state"] == "cancelled"
        assert _wait(sessions, slow["id"], {"cancelled"}).finished_at is not None
        with pytest.raises(ConflictError, match="already ended"):
            svc.cancel(slow["id"])
        with pytest.raises(NotFoundError):
            svc.cancel(10**6)
        failed = _wait(sessions, bad["id"], {"failed"})
        assert failed.error == "bad input: payload < 0"
        unknown = _wait(sessions, gone["id"], {"failed"})
        assert unknown.error is not None and "unknown robot 'nope'" in unknown.error
        # the runner reaps a finished child on its own thread: wait for it, generously
        deadline = time.monotonic() + 60
        while runner.info()["running"] and time.monotonic() < deadline:
            time.sleep(0.05)
        assert runner.info()["running"] == 0
    finally:
        svc.close()


def test_a_job_end_refused_by_a_full_disk_is_written_once_there_is_room(
    sessions: sessionmaker[Session], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 14 item 10: on a full disk job events were lost (jobs stayed "running" for ever and
    ran again after a restart). The end is kept and written when the disk has room again."""
    import errno

    runner = LocalRunner(1, target=service_target, preload=())
    svc = _service(sessions, runner, tmp_path)
    real_store = svc._store
    refusals = {"left": 3}

    def full_disk_then_room(ev: Any) -> None:
        if refusals["left"] > 0:
            refusals["left"] -= 1
            raise OSError(errno.ENOSPC, "No space left on device")
        real_store(ev)

    monkeypatch.setattr(svc, "_store", full_disk_then_room)
    svc.start()
    try:
        job = svc.submit(
            kind="plan",
            params={"robot": "arm", "behave": "count", "n": 2, "dt": 0.01},
            resource={"robot": "arm"},
        )
        row = _wait(sessions, job["id"], {"succeeded", "failed"})
        assert row.state == "succeeded" and refusals["left"] == 0
    finally:
        svc.close()
