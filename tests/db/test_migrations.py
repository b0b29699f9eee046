"""Alembic: upgrade builds exactly the models' schema; downgrade removes it again."""

from __future__ import annotations

from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import inspect, text

from app.db.models import Base
from app.db.session import current_revision, downgrade, make_engine, upgrade


def test_upgrade_then_downgrade(db_url: str) -> None:
    engine = make_engine(db_url)
    try:
        upgrade(db_url)
        assert current_revision(engine) is not None
        tables = set(inspect(engine).get_table_names()) - {"alembic_version"}
        assert tables == set(Base.metadata.tables)
        with engine.connect() as conn:
            ctx = MigrationContext.configure(conn, opts={"compare_type": True})
            assert compare_metadata(ctx, Base.metadata) == []

        downgrade(db_url, "base")
        assert set(inspect(engine).get_table_names()) <= {"alembic_version"}
        assert current_revision(engine) is None

        upgrade(db_url)  # and back up, on the same database
        assert set(inspect(engine).get_table_names()) - {"alembic_version"} == tables
    finally:
        engine.dispose()


def test_sqlite_runs_in_wal_mode_with_foreign_keys(tmp_path: object) -> None:
    url = f"sqlite:///{tmp_path}/p.db"
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            assert conn.execute(text("PRAGMA journal_mode")).scalar() == "wal"
            assert conn.execute(text("PRAGMA foreign_keys")).scalar() == 1
    finally:
        engine.dispose()


def test_0002_keeps_existing_analyses(db_url: str) -> None:
    """An analysis stored before overlays existed survives the upgrade, with no arrays."""
    engine = make_engine(db_url)
    try:
        upgrade(db_url, "0001")
        with engine.begin() as conn:
            conn.execute(
                text(
                    "INSERT INTO jobs (id, kind, state, progress, message, params, attempts,"
                    " created_at, updated_at) VALUES (7, 'analysis', 'succeeded', 1.0, 'done',"
                    " '{}', 1, CURRENT_TIMESTAMP, CURRENT_TIMESTAMP)"
                )
            )
            conn.execute(text("INSERT INTO analyses (id, result) VALUES (7, '{\"n_lifts\": 3}')"))
        assert "arrays" not in {c["name"] for c in inspect(engine).get_columns("analyses")}
        upgrade(db_url)
        with engine.connect() as conn:
            row = conn.execute(text("SELECT id, result, arrays FROM analyses")).one()
        assert row[0] == 7 and "n_lifts" in str(row[1]) and row[2] is None
        downgrade(db_url, "0001")
        assert "arrays" not in {c["name"] for c in inspect(engine).get_columns("analyses")}
        with engine.connect() as conn:
            assert conn.execute(text("SELECT count(*) FROM analyses")).scalar() == 1
    finally:
        engine.dispose()


def test_0003_adds_structured_progress_and_loses_no_row(db_url: str) -> None:
    """Jobs and their results survive 0003 both ways; old jobs read as "no progress yet".

    SQLite recreates ``jobs`` to drop columns; with foreign keys enforced that would cascade
    into the result tables, so the migrations run with them off.
    """
    engine = make_engine(db_url)
    try:
        upgrade(db_url, "0002")
        with engine.begin() as conn:
            conn.execute(
                text(
                    "INSERT INTO jobs (id, kind, state, progress, message, params, attempts,"
                    " created_at, updated_at) VALUES (3, 'plan', 'running', 0.5, 'PSO',"
                    " '{}', 1, CURRENT_TIMESTAMP, CURRENT_TIMESTAMP)"
                )
            )
            conn.execute(text("INSERT INTO plans (id, robot) VALUES (3, 'human_arm_2dof')"))
        upgrade(db_url, "0003")
        with engine.connect() as conn:
            row = conn.execute(text("SELECT progress, stage, done, of, best FROM jobs")).one()
        assert tuple(row) == (0.5, "", 0, 1, None)
        downgrade(db_url, "0002")
        assert "stage" not in {c["name"] for c in inspect(engine).get_columns("jobs")}
        with engine.connect() as conn:
            assert conn.execute(text("SELECT count(*) FROM jobs")).scalar() == 1
            assert conn.execute(text("SELECT count(*) FROM plans")).scalar() == 1
    finally:
        engine.dispose()


def test_0006_adds_labels_and_loses_no_row(db_url: str) -> None:
    """Issue 15 item 6: a plan and a recording stored before labels existed survive 0006 both
    ways, unlabelled (and the plan's result row is not cascaded away when SQLite recreates
    ``jobs`` on the way down)."""
    engine = make_engine(db_url)
    try:
        upgrade(db_url, "0005_recapi")
        with engine.begin() as conn:
            conn.execute(
                text(
                    "INSERT INTO jobs (id, kind, state, progress, message, params, attempts,"
                    " created_at, updated_at, stage, done, of) VALUES (4, 'plan', 'succeeded',"
                    " 1.0, 'done', '{}', 1, CURRENT_TIMESTAMP, CURRENT_TIMESTAMP, '', 1, 1)"
                )
            )
            conn.execute(text("INSERT INTO plans (id, robot) VALUES (4, 'human_arm_2dof')"))
            conn.execute(
                text(
                    "INSERT INTO recording_sessions (id, subject, options, session_mode,"
                    " created_at) VALUES (2, 'S01', '{}', 'separate', CURRENT_TIMESTAMP)"
                )
            )
        upgrade(db_url)
        with engine.connect() as conn:
            assert conn.execute(text("SELECT label FROM jobs")).one()[0] is None
            assert conn.execute(text("SELECT label FROM recording_sessions")).one()[0] is None
        with engine.begin() as conn:
            conn.execute(text("UPDATE jobs SET label = 'slow and heavy'"))
        downgrade(db_url, "0005_recapi")
        for table in ("jobs", "recording_sessions"):
            assert "label" not in {c["name"] for c in inspect(engine).get_columns(table)}
        with engine.connect() as conn:
            for table in ("jobs", "plans", "recording_sessions"):
                assert conn.execute(text(f"SELECT count(*) FROM {table}")).scalar() == 1
    finally:
        engine.dispose()


def test_0008_adds_conditions_and_cohorts_and_loses_no_row(db_url: str) -> None:
    """Issue 29 item 1: a recording stored before conditions existed survives 0008 both ways
    (without a condition, then with its label and files intact); the way down removes the
    cohort jobs with their table (an older server knows no such kind) and nothing else."""
    engine = make_engine(db_url)
    job = (
        "INSERT INTO jobs (id, kind, state, progress, message, params, attempts, created_at,"
        " updated_at, stage, done, of) VALUES ({id}, '{kind}', 'succeeded', 1.0, 'done', '{{}}',"
        " 1, CURRENT_TIMESTAMP, CURRENT_TIMESTAMP, '', 1, 1)"
    )
    try:
        upgrade(db_url, "0007_result_blobs")
        with engine.begin() as conn:
            conn.execute(
                text(
                    "INSERT INTO recording_sessions (id, subject, label, options, session_mode,"
                    " created_at) VALUES (2, 'S01', 'heavy', '{}', 'separate', CURRENT_TIMESTAMP)"
                )
            )
            conn.execute(text(job.format(id=4, kind="plan")))
            conn.execute(text("INSERT INTO plans (id, robot) VALUES (4, 'human_arm_2dof')"))
        upgrade(db_url)
        with engine.begin() as conn:
            assert conn.execute(text("SELECT condition FROM recording_sessions")).one()[0] is None
            conn.execute(text("UPDATE recording_sessions SET condition = 'fatigued'"))
            conn.execute(text(job.format(id=5, kind="cohort")))
            conn.execute(text("INSERT INTO cohorts (id, result) VALUES (5, '{\"groups\": {}}')"))
            conn.execute(
                text("INSERT INTO result_blobs (job_id, sha256, size) VALUES (5, 'ab', 1)")
            )
        downgrade(db_url, "0007_result_blobs")
        assert "cohorts" not in inspect(engine).get_table_names()
        columns = {c["name"] for c in inspect(engine).get_columns("recording_sessions")}
        assert "condition" not in columns
        with engine.connect() as conn:
            row = conn.execute(text("SELECT id, subject, label FROM recording_sessions")).one()
            assert tuple(row) == (2, "S01", "heavy")
            assert [r[0] for r in conn.execute(text("SELECT id FROM jobs"))] == [4]
            assert conn.execute(text("SELECT count(*) FROM plans")).scalar() == 1
            assert conn.execute(text("SELECT count(*) FROM result_blobs")).scalar() == 0
        upgrade(db_url)
        with engine.connect() as conn:
            assert conn.execute(text("SELECT count(*) FROM recording_sessions")).scalar() == 1
    finally:
        engine.dispose()
