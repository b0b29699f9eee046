"""Database URLs for service tests: SQLite always, PostgreSQL when one is configured.

``BIOPLAN_TEST_POSTGRES_URL`` (e.g. printed by ``scripts/ci_postgres.sh``) runs the same tests
on PostgreSQL. Each test process (``make test`` runs pytest in parallel workers) has its own
database on that cluster, whose ``public`` schema is emptied before each test: two workers
never empty each other's tables mid-test.
"""

from __future__ import annotations

import functools
import os
import uuid
from pathlib import Path

import pytest

POSTGRES_URL = os.environ.get("BIOPLAN_TEST_POSTGRES_URL", "").strip() or None
DB_KINDS = ["sqlite", "postgresql"]


def fresh_postgres_database(prefix: str) -> str:
    """A new, empty database on the test cluster, named ``prefix`` and a random suffix (dropped
    by nobody: the cluster is throwaway), so the tests never meet another's tables."""
    from sqlalchemy import create_engine, text
    from sqlalchemy.engine import make_url

    assert POSTGRES_URL is not None
    name = f"{prefix}_{uuid.uuid4().hex[:8]}"
    admin = create_engine(POSTGRES_URL, isolation_level="AUTOCOMMIT")
    try:
        with admin.connect() as conn:
            conn.execute(text(f'CREATE DATABASE "{name}"'))
    finally:
        admin.dispose()
    return make_url(POSTGRES_URL).set(database=name).render_as_string(hide_password=False)


@functools.cache
def _process_database() -> str:
    """This test process's own database (one per pytest-xdist worker)."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    return fresh_postgres_database(f"bioplan_test_{worker}")


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
    url = _process_database()
    reset_postgres(url)
    return url
