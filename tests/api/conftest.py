"""API test fixtures: the real app on a temporary data folder, database upgraded by Alembic."""

from __future__ import annotations

import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from starlette.exceptions import StarletteDeprecationWarning

from app.config import Settings
from app.jobs.runner import JobRunner
from app.main import create_app
from tests.db.conftest import DB_KINDS, database_url

with warnings.catch_warnings():
    # Starlette 1.x suggests httpx2 for its test client; httpx is what is installed.
    warnings.simplefilter("ignore", StarletteDeprecationWarning)
    from fastapi.testclient import TestClient

TERMINAL = {"succeeded", "failed", "cancelled"}


@contextmanager
def make_client(
    tmp_path: Path,
    *,
    runner: JobRunner | None = None,
    db_kind: str = "sqlite",
    **overrides: Any,
) -> Iterator[TestClient]:
    """A client of a fresh app (lifespan run: migrations, runner, recovery)."""
    settings = Settings(
        data_dir=tmp_path / "data",
        database_url=database_url(db_kind, tmp_path),
        max_workers=2,
        **overrides,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StarletteDeprecationWarning)
        client = TestClient(create_app(settings, runner=runner))
    with client:
        yield client


def wait_job(client: TestClient, job_id: int, timeout: float = 60.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job: dict[str, Any] = client.get(f"/api/jobs/{job_id}").json()
        if job["state"] in TERMINAL:
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


@pytest.fixture(params=DB_KINDS)
def client(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[TestClient]:
    """A fresh app on SQLite, and on PostgreSQL when ``BIOPLAN_TEST_POSTGRES_URL`` is set."""
    with make_client(tmp_path, db_kind=request.param) as c:
        yield c


@pytest.fixture(scope="module", params=DB_KINDS)
def shared_client(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[TestClient]:
    """One app for the read-mostly tests of a module (SQLite, and PostgreSQL when set)."""
    with make_client(tmp_path_factory.mktemp("api"), db_kind=request.param) as c:
        yield c
