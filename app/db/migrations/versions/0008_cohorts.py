"""Recordings carry a condition; cohort comparisons (job kind ``cohort``) get their result table.

Revision ID: 0008_cohorts
Revises: 0007_result_blobs
Create Date: 2026-11-27

Downgrade: the conditions go, and with the ``cohorts`` table the cohort jobs (an older server
knows no such kind) and their references to results kept in the file store.
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.db.migrations._tables import create_job_result_table, drop_job_result_table

revision: str = "0008_cohorts"
down_revision: str | None = "0007_result_blobs"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("recording_sessions") as batch:
        batch.add_column(sa.Column("condition", sa.String(100), nullable=True))
        batch.create_index(op.f("ix_recording_sessions_condition"), ["condition"])
    create_job_result_table("cohorts", sa.Column("result", sa.JSON(), nullable=True))


def downgrade() -> None:
    drop_job_result_table("cohorts", "cohort")
    with op.batch_alter_table("recording_sessions") as batch:
        batch.drop_index(op.f("ix_recording_sessions_condition"))
        batch.drop_column("condition")
