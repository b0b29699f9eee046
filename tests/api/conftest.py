"""API test fixtures: the real app on a temporary data folder, database upgraded by Alembic."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.utils.api import TestClient, make_client
from tests.utils.db import DB_KINDS


def _storage_kind(request: pytest.FixtureRequest) -> str:
    """The parametrised database, but for a module marked ``api_contract``: it checks what the
    routes declare and serve, which the database does not change, so its PostgreSQL run is
    skipped (tests/db and the other API modules run on PostgreSQL too; CI's time is bounded)."""
    kind: str = request.param
    if kind == "postgresql" and request.node.get_closest_marker("api_contract"):
        pytest.skip("api_contract module: the routes' contract, checked on SQLite only")
    return kind


@pytest.fixture(params=DB_KINDS)
def client(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[TestClient]:
    """A fresh app on SQLite, and on PostgreSQL when ``BIOPLAN_TEST_POSTGRES_URL`` is set."""
    with make_client(tmp_path, db_kind=_storage_kind(request)) as c:
        yield c


@pytest.fixture(scope="module", params=DB_KINDS)
def shared_client(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[TestClient]:
    """One app for the read-mostly tests of a module (SQLite, and PostgreSQL when set)."""
    with make_client(tmp_path_factory.mktemp("api"), db_kind=_storage_kind(request)) as c:
        yield c
