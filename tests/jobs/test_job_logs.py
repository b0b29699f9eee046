"""A job's log: the runner collects the ``bioplan`` records of the job process (bounded), the
job service keeps them with the job, the API serves them."""

from __future__ import annotations

import contextlib
import queue
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy.orm import Session, sessionmaker

from app.db.blobs import BlobStore
from app.db.session import make_engine, make_sessionmaker, upgrade
from app.jobs.runner import JobEvent, LocalRunner
from app.logs import MAX_LINES
from app.services import JobBroker, JobService
from tests.utils.api import TestClient, make_client, wait_job
from tests.utils.jobs import Collector, RecordingRunner, log_target


@pytest.fixture(scope="module")
def runner() -> Iterator[tuple[LocalRunner, Collector]]:
    sink = Collector()
    r = LocalRunner(2, target=log_target, preload=())
    r.start(sink)
    yield r, sink
    r.shutdown()


def test_the_final_event_carries_the_last_lines(runner: tuple[LocalRunner, Collector]) -> None:
    r, sink = runner
    r.submit(1, "plan", {"n": MAX_LINES + 150})
    ev = sink.wait_for(1, {"succeeded"})
    assert ev.log is not None and len(ev.log) == MAX_LINES + 1
    assert "150 earlier line(s) left out" in ev.log[0]
    assert ev.log[1].endswith("INFO bioplan.planning: line 150 of 650")
    assert ev.log[-1].endswith("line 649 of 650")
    assert not any("detail" in line for line in ev.log)  # DEBUG is not kept


def test_a_failed_job_logs_its_error_last(runner: tuple[LocalRunner, Collector]) -> None:
    r, sink = runner
    r.submit(2, "plan", {"n": 3, "fail": "no trajectory in 0.1 s"})
    ev = sink.wait_for(2, {"failed"})
    assert ev.error == "no trajectory in 0.1 s"
    assert ev.log is not None and [line.split(" ", 1)[1] for line in ev.log] == [
        "INFO bioplan.planning: line 0 of 3",
        "INFO bioplan.planning: line 1 of 3",
        "INFO bioplan.planning: line 2 of 3",
        "ERROR bioplan: job failed: no trajectory in 0.1 s",
    ]


def test_a_cancelled_job_keeps_what_it_said_by_its_last_progress(
    runner: tuple[LocalRunner, Collector],
) -> None:
    r, sink = runner
    r.submit(3, "plan", {"n": 100, "every": 50, "sleep": 60})
    deadline = time.monotonic() + 60
    while not any(e.detail and e.detail["done"] == 100 for e in sink.of(3)):  # now it sleeps
        assert time.monotonic() < deadline, sink.of(3)
        with contextlib.suppress(queue.Empty):
            sink.seen.append(sink.events.get(timeout=0.1))
    assert r.cancel(3)
    ev = sink.wait_for(3, {"cancelled"})
    assert ev.log is not None and len(ev.log) == 100
    assert ev.log[-1].endswith("line 99 of 100")


# --------------------------------------------------------------------------------- the service


@pytest.fixture
def sessions(tmp_path: Path) -> Iterator[sessionmaker[Session]]:
    url = f"sqlite:///{tmp_path / 'jobs.db'}"
    upgrade(url)
    engine = make_engine(url)
    yield make_sessionmaker(engine)
    engine.dispose()


def _service(sessions: sessionmaker[Session], tmp_path: Path) -> tuple[JobService, RecordingRunner]:
    runner = RecordingRunner()
    svc = JobService(
        sessions=sessions,
        blobs=BlobStore(tmp_path / "blobs"),
        runner=runner,
        broker=JobBroker(),
        progress_interval=0.05,
    )
    svc.robots.__dict__["builtin"] = ["arm"]
    return svc, runner


def _wait_state(svc: JobService, job_id: int, state: str) -> dict[str, Any]:
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        job = svc.get(job_id)
        if job["state"] == state:
            return job
        time.sleep(0.02)
    raise AssertionError(f"job {job_id} stayed {svc.get(job_id)['state']}")


def test_the_service_keeps_a_log_per_job(sessions: sessionmaker[Session], tmp_path: Path) -> None:
    svc, runner = _service(sessions, tmp_path)
    svc.start()
    try:
        job = svc.submit(kind="plan", params={"robot": "arm"}, resource={"robot": "arm"})
        assert svc.log(job["id"]) == {
            "job_id": job["id"],
            "state": "queued",
            "complete": False,
            "lines": [],
        }
        lines = ["12:00:00 INFO bioplan.recordings: /srv/data/uploads/ab/arm.csv: read as csv"]
        runner.sink(JobEvent(job["id"], "failed", error="no", log=lines))
        _wait_state(svc, job["id"], "failed")
        log = svc.log(job["id"])
        assert log["complete"] is True
        # Folders are cut from paths, as in a job's error.
        assert log["lines"] == ["12:00:00 INFO bioplan.recordings: arm.csv: read as csv"]
        assert svc.log_dir == tmp_path / "job-logs"
        # A stray log (its job deleted) goes at the next start; a new job never shows a log
        # its id had before.
        (svc.log_dir / "999.log").write_text("old\n")
        (svc.log_dir / f"{job['id'] + 1}.log").write_text("a deleted job's\n")
        nxt = svc.submit(kind="plan", params={"robot": "arm"}, resource={"robot": "arm"})
        assert nxt["id"] == job["id"] + 1 and svc.log(nxt["id"])["lines"] == []
    finally:
        svc.close()
    svc2, _ = _service(sessions, tmp_path)
    svc2.start()
    try:
        assert not (svc2.log_dir / "999.log").exists()
        assert svc2.log(job["id"])["lines"] == log["lines"]
    finally:
        svc2.close()


# --------------------------------------------------------------------------------------- API


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with make_client(tmp_path_factory.mktemp("logs")) as c:
        yield c


def test_a_plan_jobs_log_says_what_the_planner_did(client: TestClient) -> None:
    body = {
        "robot": "human_arm_2dof",
        "duration": 1.0,
        "particles": 8,
        "iterations": 5,
        "methods": ["quintic", "paper", "jerk_limited"],
    }
    r = client.post("/api/plans", json=body)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"])
    assert job["state"] == "succeeded", job
    result = client.get(job["result_url"]).json()["result"]
    log = client.get(f"/api/jobs/{job['id']}/log")
    assert log.status_code == 200, log.text
    data = log.json()
    assert data["complete"] is True and data["state"] == "succeeded"
    text = "\n".join(data["lines"])
    assert "INFO bioplan.planning: plan of human_arm_2dof: quintic, paper, jerk_limited" in text
    assert "INFO bioplan.planning: paper: PSO of 8 particles x 5 iterations, seed 0" in text
    best = result["methods"]["paper"]["solver"]["best_cost"]
    assert f"paper: best abs_work = {best:.6g}" in text
    assert "INFO bioplan.planning: jerk_limited: ruckig profile over 1 s" in text
    assert "DEBUG" not in text


def test_the_log_of_an_unknown_job_is_a_404(client: TestClient) -> None:
    r = client.get("/api/jobs/987654/log")
    assert r.status_code == 404
    assert "987654" in r.json()["detail"]
