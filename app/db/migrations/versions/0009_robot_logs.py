"""Uploaded robot logs and identification jobs (job kind ``identify``) get their tables.

Revision ID: 0009_robot_logs
Revises: 0008_cohorts
Create Date: 2026-11-27

Downgrade: the logs' rows go (their files stay in the file store until its clean-up), and with
the ``identifications`` table the identify jobs (an older server knows no such kind); robots
they stored stay, as ordinary uploaded robots.
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.db.migrations._tables import create_job_result_table, drop_job_result_table

revision: str = "0009_robot_logs"
down_revision: str | None = "0008_cohorts"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "robot_logs",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("robot", sa.String(100), nullable=False),
        sa.Column("original_name", sa.String(255), nullable=False),
        sa.Column("format", sa.String(32), nullable=False),
        sa.Column("size", sa.BigInteger(), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("topic", sa.String(200), nullable=True),
        sa.Column("summary", sa.JSON(), nullable=False),
        sa.Column("label", sa.String(200), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_robot_logs")),
    )
    op.create_index(op.f("ix_robot_logs_robot"), "robot_logs", ["robot"])
    op.create_index(op.f("ix_robot_logs_sha256"), "robot_logs", ["sha256"])
    op.create_index(op.f("ix_robot_logs_created_at"), "robot_logs", ["created_at"])
    create_job_result_table(
        "identifications",
        sa.Column("result", sa.JSON(), nullable=True),
        sa.Column("robot", sa.String(100), nullable=False),
        sa.Column("version", sa.String(100), nullable=False),
        indexed=["robot"],
    )


def downgrade() -> None:
    drop_job_result_table("identifications", "identify", indexed=["robot"])
    op.drop_index(op.f("ix_robot_logs_created_at"), table_name="robot_logs")
    op.drop_index(op.f("ix_robot_logs_sha256"), table_name="robot_logs")
    op.drop_index(op.f("ix_robot_logs_robot"), table_name="robot_logs")
    op.drop_table("robot_logs")
