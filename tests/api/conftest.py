"""API test fixtures: the real app on a temporary data folder, database upgraded by Alembic."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.utils.api import TestClient, make_client
from tests.utils.db import DB_KINDS


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
