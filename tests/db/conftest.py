"""Database fixtures: every storage test runs on SQLite, and on PostgreSQL when configured."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.utils.db import DB_KINDS, database_url


@pytest.fixture(params=DB_KINDS)
def db_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    return database_url(request.param, tmp_path)
