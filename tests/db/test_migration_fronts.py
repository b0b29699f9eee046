"""Migration 0010: the fronts' table; the way down removes the front jobs (an older server
knows no such kind), their results kept in the file store, and nothing else."""

from __future__ import annotations

from sqlalchemy import inspect, text

from app.db.session import downgrade, make_engine, upgrade

JOB = (
    "INSERT INTO jobs (id, kind, state, progress, message, params, attempts, created_at,"
    " updated_at, stage, done, of) VALUES ({id}, '{kind}', 'succeeded', 1.0, 'done', '{{}}',"
    " 1, CURRENT_TIMESTAMP, CURRENT_TIMESTAMP, '', 1, 1)"
)


def test_0010_adds_fronts_and_removes_only_them(db_url: str) -> None:
    engine = make_engine(db_url)
    try:
        upgrade(db_url, "0009_robot_logs")
        assert "fronts" not in inspect(engine).get_table_names()
        with engine.begin() as conn:
            conn.execute(text(JOB.format(id=4, kind="plan")))
            conn.execute(text("INSERT INTO plans (id, robot) VALUES (4, 'human_arm_2dof')"))
        upgrade(db_url)
        columns = {c["name"] for c in inspect(engine).get_columns("fronts")}
        assert columns == {"id", "result", "robot", "arrays"}
        with engine.begin() as conn:
            conn.execute(text(JOB.format(id=5, kind="front")))
            conn.execute(
                text("INSERT INTO fronts (id, robot, result) VALUES (5, 'human_arm_2dof', '{}')")
            )
            conn.execute(
                text("INSERT INTO result_blobs (job_id, sha256, size) VALUES (5, 'ab', 1)")
            )
        downgrade(db_url, "0009_robot_logs")
        assert "fronts" not in inspect(engine).get_table_names()
        with engine.connect() as conn:
            assert [r[0] for r in conn.execute(text("SELECT id FROM jobs"))] == [4]
            assert conn.execute(text("SELECT count(*) FROM plans")).scalar() == 1
            assert conn.execute(text("SELECT count(*) FROM result_blobs")).scalar() == 0
        upgrade(db_url)
        with engine.connect() as conn:
            assert conn.execute(text("SELECT count(*) FROM fronts")).scalar() == 0
    finally:
        engine.dispose()
