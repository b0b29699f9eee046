"""Pareto fronts (job kind ``front``) get their result table.

Revision ID: 0010_fronts
Revises: 0009_robot_logs
Create Date: 2026-11-27

Downgrade: with the ``fronts`` table the front jobs go (an older server knows no such kind),
and their references to results kept in the file store.
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.db.migrations._tables import create_job_result_table, drop_job_result_table

revision: str = "0010_fronts"
down_revision: str | None = "0009_robot_logs"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    create_job_result_table(
        "fronts",
        sa.Column("result", sa.JSON(), nullable=True),
        sa.Column("robot", sa.String(100), nullable=False),
        sa.Column("arrays", sa.LargeBinary(), nullable=True),
        indexed=["robot"],
    )


def downgrade() -> None:
    drop_job_result_table("fronts", "front", indexed=["robot"])
