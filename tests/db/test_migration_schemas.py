"""Migrations are history: the schema each revision leaves behind, on the way up and on the way
down, is the one recorded in ``tests/db/data/migration_schemas.json`` (SQLite's own
``CREATE TABLE``/``CREATE INDEX`` text: every column, type, nullability, server default, key,
foreign key and index, in order). A refactoring of the migration files that changes a single
column fails here.

The file was written from the migrations as released (before their shared column sets were
factored into ``app/db/migrations/_tables.py``); it is never regenerated to make a change pass.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from sqlalchemy import text

from app.db.session import downgrade, make_engine, upgrade

EXPECTED = Path(__file__).parent / "data" / "migration_schemas.json"


def _revisions(url: str) -> list[str]:
    from alembic.script import ScriptDirectory

    from app.db.session import alembic_config

    script = ScriptDirectory.from_config(alembic_config(url))
    return [s.revision for s in reversed(list(script.walk_revisions()))]


def _parts(body: str) -> list[str]:
    """The comma-separated parts of a ``CREATE TABLE`` body (commas inside brackets kept)."""
    parts, depth, start = [], 0, 0
    for i, char in enumerate(body):
        depth += {"(": 1, ")": -1}.get(char, 0)
        if char == "," and depth == 0:
            parts.append(body[start:i].strip())
            start = i + 1
    return [*parts, body[start:].strip()]


def canonical(sql: str) -> str:
    """``sql`` with a table's constraints sorted: the columns keep their order, but the order
    of the table constraints means nothing and SQLite keeps the one Alembic's batch mode
    happened to write when it recreated the table (it varies from run to run)."""
    if not sql.startswith("CREATE TABLE"):
        return sql
    head, body = sql.split("(", 1)
    body, tail = body.rsplit(")", 1)
    constraint = re.compile(r"^(CONSTRAINT|PRIMARY KEY|FOREIGN KEY|UNIQUE|CHECK)\b")
    parts = _parts(body)
    columns = [p for p in parts if not constraint.match(p)]
    constraints = sorted(p for p in parts if constraint.match(p))
    return f"{head.strip()} ({', '.join(columns + constraints)}){tail}"


def _schema(url: str) -> list[list[str]]:
    """``[type, name, table, sql]`` of every table and index but Alembic's own, by name."""
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            rows = conn.execute(
                text(
                    "SELECT type, name, tbl_name, coalesce(sql, '') FROM sqlite_master "
                    "WHERE tbl_name != 'alembic_version' ORDER BY type, name"
                )
            ).all()
    finally:
        engine.dispose()
    return [
        [str(kind), str(name), str(table), canonical(str(sql))] for kind, name, table, sql in rows
    ]


def migration_schemas(tmp_path: Path) -> dict[str, dict[str, list[list[str]]]]:
    """The schema after upgrading a fresh SQLite database to each revision in turn, then after
    downgrading it back to each one (``"base"`` last)."""
    url = f"sqlite:///{tmp_path / 'schemas.db'}"
    revisions = _revisions(url)
    up: dict[str, list[list[str]]] = {}
    for revision in revisions:
        upgrade(url, revision)
        up[revision] = _schema(url)
    down: dict[str, list[list[str]]] = {}
    for revision in [*reversed(revisions[:-1]), "base"]:
        downgrade(url, revision)
        down[revision] = _schema(url)
    return {"upgrade": up, "downgrade": down}


def test_every_revision_leaves_the_recorded_schema(tmp_path: Path) -> None:
    expected = json.loads(EXPECTED.read_text(encoding="utf-8"))
    actual = migration_schemas(tmp_path)
    assert list(actual["upgrade"]) == list(expected["upgrade"])  # no revision added or lost
    for direction in ("upgrade", "downgrade"):
        for revision, schema in expected[direction].items():
            assert actual[direction][revision] == schema, (direction, revision)


def test_the_record_holds_every_table_of_head() -> None:
    """The recorded head is the models' schema (so the record is no empty file)."""
    from app.db.models import Base

    expected = json.loads(EXPECTED.read_text(encoding="utf-8"))
    head = list(expected["upgrade"].values())[-1]
    tables = {name for kind, name, _, _ in head if kind == "table"}
    assert tables == set(Base.metadata.tables)
    assert expected["downgrade"]["base"] == []
