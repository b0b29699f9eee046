"""API test fixtures: the real app on a temporary data folder, database upgraded by Alembic."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.utils.api import TestClient, make_client
from tests.utils.db import DB_KINDS

#: The database-parametrised fixtures.
_STORAGE_FIXTURES = ("client", "shared_client")


def pytest_runtest_setup(item: pytest.Item) -> None:
    """A module or test marked ``api_contract`` checks what the routes declare and serve, or
    that options reach the science, which the database does not change: its PostgreSQL run is
    skipped before any fixture is built (tests/db and the other API tests run on PostgreSQL
    too; CI's time is bounded)."""
    callspec = getattr(item, "callspec", None)
    if callspec is None or item.get_closest_marker("api_contract") is None:
        return
    if any(callspec.params.get(name) == "postgresql" for name in _STORAGE_FIXTURES):
        pytest.skip("api_contract: what the routes declare and pass on, checked on SQLite only")


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
