"""Security finding 10 against a real ``bioplan serve``: a job past ``BIOPLAN_JOB_MEMORY_MB``
fails with "ran out of memory" while the server goes on; at most ``BIOPLAN_MAX_QUEUED`` jobs
wait (then 429 with ``Retry-After``, nothing stored); a result larger than
``BIOPLAN_RESULT_INLINE_KB`` is kept in the file store and read back as if it were in its row,
also after a restart (the start-up clean-up keeps its file)."""

from __future__ import annotations

import math
import sqlite3
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.utils.server import Server

TINY = {
    "robot": "human_arm_2dof",
    "particles": 8,
    "iterations": 5,
    "methods": ["quintic", "paper"],
}
#: A plan that runs long enough to stay running while others queue.
LONG = {**TINY, "robot": "curtain_wall_6dof", "particles": 400, "iterations": 2000}
#: A plan whose optimal control needs far more than 16 MB (CasADi, IPOPT, 2000 samples).
HEAVY = {
    "robot": "curtain_wall_6dof",
    "particles": 8,
    "iterations": 5,
    "n_samples": 2000,
    "methods": ["quintic", "paper", "bound"],
}
MAX_QUEUED = 2


def _wait(server: Server, job_id: int, states: set[str], deadline_s: float = 300.0) -> Any:
    deadline = time.monotonic() + deadline_s
    while True:
        job = server.get(f"/api/jobs/{job_id}")
        if job["state"] in states:
            return job
        assert time.monotonic() < deadline, f"job {job_id} is still {job['state']}"
        time.sleep(0.3)


def _stored(data_dir: Path, sql: str, *args: Any) -> list[tuple[Any, ...]]:
    with sqlite3.connect(data_dir / "bioplan.db") as db:
        return list(db.execute(sql, args))


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    s = Server(
        tmp_path_factory.mktemp("bounds") / "data",
        BIOPLAN_MAX_WORKERS="1",
        BIOPLAN_MAX_QUEUED=str(MAX_QUEUED),
        BIOPLAN_RESULT_INLINE_KB="1",
        BIOPLAN_JOB_MEMORY_MB="16",
    )
    s.start()
    try:
        yield s
    finally:
        s.cleanup()


def test_a_job_past_its_memory_limit_fails_and_the_server_goes_on(server: Server) -> None:
    response = server.post("/api/plans", json=HEAVY)
    assert response.status_code == 202, response.text
    job = _wait(server, response.json()["id"], {"succeeded", "failed"})
    assert job["state"] == "failed"
    assert "ran out of memory" in job["error"]
    assert "BIOPLAN_JOB_MEMORY_MB=16" in job["error"]
    assert httpx.get(server.url + "/api/health", timeout=60).status_code == 200
    assert server.proc is not None and server.proc.poll() is None


def test_a_large_result_round_trips_through_the_file_store(server: Server) -> None:
    response = server.post("/api/plans", json=TINY)
    assert response.status_code == 202, response.text
    job_id = response.json()["id"]
    assert _wait(server, job_id, {"succeeded", "failed"})["state"] == "succeeded"
    served = server.get(f"/api/plans/{job_id}")
    assert served["result"]["motion"]["methods"], served  # the whole result, as before
    # Stored as a reference to a file, not in the row.
    [(row,)] = _stored(server.data_dir, "SELECT result FROM plans WHERE id = ?", job_id)
    assert "$result_blob" in row and len(row) < 300
    [(sha, size)] = _stored(
        server.data_dir, "SELECT sha256, size FROM result_blobs WHERE job_id = ?", job_id
    )
    blob = server.data_dir / "blobs" / sha[:2] / sha
    assert blob.is_file() and blob.stat().st_size == size > 1024
    print(f"plan result: {size} bytes in the file store, {len(row)} bytes in its row")


def test_the_queue_is_bounded(server: Server) -> None:
    before = server.get("/api/jobs?limit=1")["total"]
    running = server.post("/api/plans", json=LONG).json()["id"]
    _wait(server, running, {"running"})
    queued = [server.post("/api/plans", json=TINY) for _ in range(MAX_QUEUED)]
    assert [r.status_code for r in queued] == [202] * MAX_QUEUED
    refused = server.post("/api/plans", json=TINY)
    assert refused.status_code == 429
    assert int(refused.headers["retry-after"]) >= 1
    assert refused.headers["content-type"].startswith("application/problem+json")
    assert f"BIOPLAN_MAX_QUEUED={MAX_QUEUED}" in refused.json()["detail"]
    # Nothing stored for the refused one.
    assert server.get("/api/jobs?limit=1")["total"] == before + 1 + MAX_QUEUED
    for job_id in [running] + [r.json()["id"] for r in queued]:
        server.post(f"/api/jobs/{job_id}/cancel")
    # Room again once the queue drains.
    again = server.post("/api/plans", json=TINY)
    assert again.status_code == 202, again.text
    _wait(server, again.json()["id"], {"succeeded", "failed"})


def test_a_stored_result_survives_a_restart(server: Server) -> None:
    # its own result (the module's earlier jobs may have been cancelled on a busy machine)
    job_id = server.post("/api/plans", json=TINY).json()["id"]
    assert _wait(server, job_id, {"succeeded", "failed"})["state"] == "succeeded"
    stored = _stored(server.data_dir, "SELECT job_id FROM result_blobs")
    assert (job_id,) in stored
    before = _plan_result(server, job_id)
    server.stop()
    server.start()  # the start-up clean-up removes unreferenced files: this one is referenced
    assert _plan_result(server, job_id) == before


def _plan_result(server: Server, job_id: int) -> object:
    """The stored plan's result (a failed read says what the server answered)."""
    response = httpx.get(f"{server.url}/api/plans/{job_id}", timeout=60)
    assert response.status_code == 200, response.text
    body = response.json()
    assert "result" in body, body
    return body["result"]


def test_a_change_that_would_queue_past_the_bound_is_refused_whole(tmp_path: Path) -> None:
    """A PATCH that stores a change and then queues its analysis asks for room first: with the
    queue full it is a 429 and the recording keeps what it had (it was stored, then refused)."""
    from tests.utils.api import make_client
    from tests.utils.jobs import RecordingRunner

    rows = "\n".join(f"{i / 1000:.3f},{math.sin(i / 7):.4f}" for i in range(2000))
    emg = ("emg.csv", f"time,biceps\n{rows}\n".encode(), "text/csv")
    with make_client(tmp_path, runner=RecordingRunner(), max_queued=1) as client:
        up = client.post("/api/recordings", files={"files": emg}, data={"subject": "before"})
        assert up.status_code == 201, up.text  # no video: no job
        rec_id = up.json()["id"]
        first = client.patch(f"/api/recordings/{rec_id}", json={"notes": "one"})
        assert first.status_code == 200 and first.json()["analysis_job"]["state"] == "queued"
        refused = client.patch(f"/api/recordings/{rec_id}", json={"subject": "after"})
        assert refused.status_code == 429, refused.text
        assert "BIOPLAN_MAX_QUEUED=1" in refused.json()["detail"]
        shown = client.get(f"/api/recordings/{rec_id}").json()
        assert (shown["subject"], shown["notes"]) == ("before", "one")
        assert client.get("/api/jobs?limit=1").json()["total"] == 1
        # Without an analysis the change needs no room and is stored.
        quiet = client.patch(
            f"/api/recordings/{rec_id}", json={"subject": "after", "analyse": False}
        )
        assert quiet.status_code == 200 and quiet.json()["subject"] == "after"


def test_a_recording_past_the_data_quota_is_refused_and_nothing_stored(tmp_path: Path) -> None:
    """Issue 23 item 8: the quota holds for every upload, recordings as well as robots."""
    from tests.utils.api import make_client

    rows = "\n".join(f"{i / 1000:.4f},{math.sin(i / 7):.6f}" for i in range(90000))
    emg = ("big.csv", f"time,biceps\n{rows}\n".encode(), "text/csv")  # about 1.6 MB
    with make_client(tmp_path, data_quota_mb=1.0) as client:
        r = client.post("/api/recordings", files={"files": emg})
        assert r.status_code == 413, r.text
        problem = r.json()
        assert problem["file"] == "big.csv" and "BIOPLAN_DATA_QUOTA_MB" in problem["detail"]
        assert client.get("/api/recordings").json()["total"] == 0
        assert not any(p.is_file() for p in (tmp_path / "data" / "blobs").rglob("*"))
        small = ("small.csv", b"time,biceps\n" + rows[:2000].encode() + b"\n", "text/csv")
        assert client.post("/api/recordings", files={"files": small}).status_code == 201
