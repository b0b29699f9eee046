"""Initial schema: recordings, files, channels, robots, jobs and job results.

Revision ID: 0001
Revises:
Create Date: 2026-11-21
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.db.migrations._tables import foreign_key, create_job_result_table

revision: str = "0001"
down_revision: str | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

TZ = sa.DateTime(timezone=True)


def upgrade() -> None:
    # Over 80 lines on purpose: a released migration is a frozen record of the schema it
    # created, table after table; splitting it would only scatter that record.
    op.create_table(
        "jobs",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("state", sa.String(16), nullable=False),
        sa.Column("progress", sa.Float(), nullable=False),
        sa.Column("message", sa.Text(), nullable=False),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("params", sa.JSON(), nullable=False),
        sa.Column("attempts", sa.Integer(), nullable=False),
        sa.Column("created_at", TZ, nullable=False),
        sa.Column("started_at", TZ, nullable=True),
        sa.Column("finished_at", TZ, nullable=True),
        sa.Column("updated_at", TZ, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_jobs")),
    )
    op.create_index(op.f("ix_jobs_created_at"), "jobs", ["created_at"])
    op.create_index(op.f("ix_jobs_kind"), "jobs", ["kind"])
    op.create_index(op.f("ix_jobs_state"), "jobs", ["state"])

    op.create_table(
        "recording_sessions",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("subject", sa.String(200), nullable=True),
        sa.Column("task", sa.String(200), nullable=True),
        sa.Column("load_kg", sa.Float(), nullable=True),
        sa.Column("notes", sa.Text(), nullable=True),
        sa.Column("options", sa.JSON(), nullable=False),
        sa.Column("created_at", TZ, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_recording_sessions")),
    )
    op.create_index(op.f("ix_recording_sessions_created_at"), "recording_sessions", ["created_at"])
    op.create_index(op.f("ix_recording_sessions_subject"), "recording_sessions", ["subject"])
    op.create_index(op.f("ix_recording_sessions_task"), "recording_sessions", ["task"])

    op.create_table(
        "recording_files",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("session_id", sa.Integer(), nullable=False),
        sa.Column("original_name", sa.String(255), nullable=False),
        sa.Column("format", sa.String(64), nullable=False),
        sa.Column("size", sa.BigInteger(), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("file_metadata", sa.JSON(), nullable=False),
        foreign_key("recording_files", "session_id", "recording_sessions", ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_recording_files")),
    )
    op.create_index(op.f("ix_recording_files_format"), "recording_files", ["format"])
    op.create_index(op.f("ix_recording_files_session_id"), "recording_files", ["session_id"])
    op.create_index(op.f("ix_recording_files_sha256"), "recording_files", ["sha256"])

    op.create_table(
        "channels",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("file_id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("unit", sa.String(32), nullable=False),
        sa.Column("rate", sa.Float(), nullable=False),
        sa.Column("start", sa.Float(), nullable=False),
        sa.Column("site", sa.String(16), nullable=True),
        sa.Column("n_samples", sa.Integer(), nullable=False),
        sa.Column("dims", sa.Integer(), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.Column("confidence", sa.LargeBinary(), nullable=True),
        sa.Column("time", sa.LargeBinary(), nullable=True),
        foreign_key("channels", "file_id", "recording_files", ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_channels")),
    )
    op.create_index(op.f("ix_channels_file_id"), "channels", ["file_id"])

    op.create_table(
        "robots",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(100), nullable=False),
        sa.Column("urdf_sha256", sa.String(64), nullable=False),
        sa.Column("urdf_name", sa.String(255), nullable=False),
        sa.Column("mjcf_sha256", sa.String(64), nullable=True),
        sa.Column("mjcf_name", sa.String(255), nullable=True),
        sa.Column("payload", sa.Float(), nullable=True),
        sa.Column("description", sa.JSON(), nullable=False),
        sa.Column("created_at", TZ, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_robots")),
        sa.UniqueConstraint("name", name=op.f("uq_robots_name")),
    )

    create_job_result_table(
        "analyses",
        sa.Column("recording_id", sa.Integer(), nullable=True),
        sa.Column("template", sa.JSON(), nullable=True),
        foreign_key("analyses", "recording_id", "recording_sessions", ondelete="SET NULL"),
        sa.Column("result", sa.JSON(), nullable=True),
        indexed=["recording_id"],
    )
    for name, arrays in (("plans", True), ("simulations", True), ("sweeps", False)):
        create_job_result_table(
            name,
            sa.Column("robot", sa.String(100), nullable=False),
            sa.Column("result", sa.JSON(), nullable=True),
            *([sa.Column("arrays", sa.LargeBinary(), nullable=True)] if arrays else []),
            indexed=["robot"],
        )


def downgrade() -> None:
    for name in ("sweeps", "simulations", "plans", "analyses"):
        op.drop_table(name)
    op.drop_table("robots")
    op.drop_table("channels")
    op.drop_table("recording_files")
    op.drop_table("recording_sessions")
    op.drop_table("jobs")
