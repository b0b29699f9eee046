"""Security finding 10 (iv): a second server on another data directory but the same
``BIOPLAN_DATABASE_URL`` started, re-ran the first's running job and marked it failed while it
was still computing. One server per database: the second refuses to start (exit code 2, one
line naming the holder), and the first's running job runs on untouched. With SQLite (a lock
beside the database file) and, when ``BIOPLAN_TEST_POSTGRES_URL`` is set, PostgreSQL (an
advisory lock held by the server's session)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from tests.utils.db import POSTGRES_URL, fresh_postgres_database
from tests.utils.server import Server, free_port

#: A plan that runs long enough to be running while the second server tries to start.
LONG = {
    "robot": "curtain_wall_6dof",
    "particles": 400,
    "iterations": 2000,
    "methods": ["quintic", "paper"],
}


def _database_url(tmp_path: Path, backend: str) -> str:
    if backend == "sqlite":
        return f"sqlite:///{tmp_path / 'shared' / 'bioplan.db'}"
    if POSTGRES_URL is None:
        pytest.skip("no PostgreSQL: set BIOPLAN_TEST_POSTGRES_URL (scripts/ci_postgres.sh)")
    return fresh_postgres_database("bioplan_claim")


def _serve(data_dir: Path, url: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "BIOPLAN_DATABASE_URL": url, "BIOPLAN_VIEWER": "0"}
    env.pop("BIOPLAN_API_TOKEN", None)
    args = [sys.executable, "-m", "app.cli", "serve", "--port", str(free_port())]
    args += ["--data-dir", str(data_dir)]
    return subprocess.run(
        args, env=env, cwd=data_dir.parent, capture_output=True, text=True, timeout=300
    )


def _job(server: Server, job_id: int) -> Any:
    return server.get(f"/api/jobs/{job_id}")


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_a_second_server_on_the_same_database_refuses_to_start(
    tmp_path: Path, backend: str
) -> None:
    url = _database_url(tmp_path, backend)
    first = Server(tmp_path / "first" / "data", BIOPLAN_DATABASE_URL=url, BIOPLAN_MAX_WORKERS="1")
    first.start()
    try:
        job_id = first.post("/api/plans", json=LONG).json()["id"]
        deadline = time.monotonic() + 300
        while _job(first, job_id)["state"] != "running":
            assert time.monotonic() < deadline, "the plan did not start"
            time.sleep(0.3)
        before = _job(first, job_id)

        second = tmp_path / "second" / "data"
        second.parent.mkdir()
        done = _serve(second, url)
        assert done.returncode == 2, done.stderr
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1, done.stderr
        assert "in use by" in lines[0] and "one server per database" in lines[0]
        assert str(first.pid) in lines[0]  # it names the holder
        assert "Traceback" not in done.stderr and done.stdout == ""
        print(lines[0])

        # The first server's job runs on (or has finished meanwhile on a fast machine): not
        # re-queued, not failed, not started again.
        after = _job(first, job_id)
        assert after["state"] in ("running", "succeeded"), after
        assert after["attempts"] == before["attempts"] == 1
        assert after["started_at"] == before["started_at"]
        first.post(f"/api/jobs/{job_id}/cancel")
    finally:
        first.stop()
    # Once the first has stopped, the database is free for another server.
    again = Server(tmp_path / "second" / "data", BIOPLAN_DATABASE_URL=url)
    again.start()
    again.stop()
