"""In-process API clients (the real app, lifespan run) and what tests check on answers."""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from starlette.exceptions import StarletteDeprecationWarning

from app.config import Settings
from app.jobs.runner import JobRunner
from app.main import create_app
from app.names import TERMINAL_JOB_STATES
from tests.utils.db import database_url

with warnings.catch_warnings():
    # Starlette 1.x suggests httpx2 for its test client; httpx is what is installed.
    warnings.simplefilter("ignore", StarletteDeprecationWarning)
    from fastapi.testclient import TestClient

__all__ = ["TestClient", "assert_problem", "make_client", "read_sse", "wait_job"]


@contextmanager
def make_client(
    tmp_path: Path,
    *,
    runner: JobRunner | None = None,
    db_kind: str = "sqlite",
    **overrides: Any,
) -> Iterator[TestClient]:
    """A client of a fresh app (lifespan run: migrations, runner, recovery; no 3-D viewer
    unless ``viewer=True``)."""
    overrides.setdefault("viewer", False)
    settings = Settings(
        data_dir=tmp_path / "data",
        database_url=database_url(db_kind, tmp_path),
        max_workers=2,
        **overrides,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StarletteDeprecationWarning)
        # A loopback name in Host, as a browser on this machine sends (the server refuses others).
        client = TestClient(create_app(settings, runner=runner), base_url="http://127.0.0.1")
    with client:
        yield client


def wait_job(client: TestClient, job_id: int, timeout: float = 120.0) -> dict[str, Any]:
    """Poll a job until it ends (a generous deadline: the machine may be busy)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job: dict[str, Any] = client.get(f"/api/jobs/{job_id}").json()
        if job["state"] in TERMINAL_JOB_STATES:
            return job
        time.sleep(0.1)
    raise AssertionError(f"job {job_id} did not finish within {timeout} s: {job}")


def assert_problem(response: Any, status: int, **fields: Any) -> dict[str, Any]:
    """The response is an ``application/problem+json`` with this status (and fields)."""
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    body: dict[str, Any] = response.json()
    assert body["status"] == status and body["title"] and body["detail"]
    for key, value in fields.items():
        assert body.get(key) == value, (key, body)
    return body


def read_sse(client: TestClient, url: str) -> list[tuple[str, dict[str, Any]]]:
    """Every (event, data) of a Server-Sent Events stream, until the server ends it."""
    events = []
    with client.stream("GET", url) as r:
        assert r.status_code == 200
        assert r.headers["content-type"].startswith("text/event-stream")
        name = None
        for line in r.iter_lines():
            if line.startswith("event: "):
                name = line.removeprefix("event: ")
            elif line.startswith("data: ") and name is not None:
                events.append((name, json.loads(line.removeprefix("data: "))))
    return events
