"""Database URLs for service tests: SQLite always, PostgreSQL when one is configured.

``BIOPLAN_TEST_POSTGRES_URL`` (e.g. printed by ``scripts/ci_postgres.sh``) runs the same tests
on PostgreSQL; the database's ``public`` schema is emptied before each test.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

POSTGRES_URL = os.environ.get("BIOPLAN_TEST_POSTGRES_URL", "").strip() or None
DB_KINDS = ["sqlite", "postgresql"]


def reset_postgres(url: str) -> None:
    from sqlalchemy import create_engine, text

    engine = create_engine(url)
    try:
        with engine.begin() as conn:
            conn.execute(text("DROP SCHEMA public CASCADE"))
            conn.execute(text("CREATE SCHEMA public"))
    finally:
        engine.dispose()


def database_url(kind: str, tmp_path: Path) -> str:
    """A fresh, empty database of ``kind``; skips when PostgreSQL is not configured."""
    if kind == "sqlite":
        return f"sqlite:///{tmp_path / 'bioplan.db'}"
    if POSTGRES_URL is None:
        pytest.skip("no PostgreSQL: set BIOPLAN_TEST_POSTGRES_URL (scripts/ci_postgres.sh)")
    reset_postgres(POSTGRES_URL)
    return POSTGRES_URL
