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

revision: str = "0010_fronts"
down_revision: str | None = "0009_robot_logs"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "fronts",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("result", sa.JSON(), nullable=True),
        sa.Column("robot", sa.String(100), nullable=False),
        sa.Column("arrays", sa.LargeBinary(), nullable=True),
        sa.ForeignKeyConstraint(
            ["id"], ["jobs.id"], name=op.f("fk_fronts_id_jobs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_fronts")),
    )
    op.create_index(op.f("ix_fronts_robot"), "fronts", ["robot"])


def downgrade() -> None:
    # Foreign keys are off while migrations run on SQLite: remove the dependants by hand.
    front_jobs = "SELECT id FROM jobs WHERE kind = 'front'"
    op.execute(f"DELETE FROM result_blobs WHERE job_id IN ({front_jobs})")
    op.drop_index(op.f("ix_fronts_robot"), table_name="fronts")
    op.drop_table("fronts")
    op.execute("DELETE FROM jobs WHERE kind = 'front'")
