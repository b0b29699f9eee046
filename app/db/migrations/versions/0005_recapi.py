"""Recordings keep their session mode and edits, files their role (recording, sidecar, video)
and parent, videos their skeleton frames; pose extraction is a job kind with a result table.

Revision ID: 0005_recapi
Revises: 0004_planapi
Create Date: 2026-11-24
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.db.migrations._tables import foreign_key

revision: str = "0005_recapi"
down_revision: str | None = "0004_planapi"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("recording_sessions") as batch:
        batch.add_column(
            sa.Column("session_mode", sa.String(16), nullable=False, server_default="separate")
        )
        batch.add_column(sa.Column("updated_at", sa.DateTime(timezone=True), nullable=True))
    with op.batch_alter_table("recording_files") as batch:
        batch.add_column(
            sa.Column("role", sa.String(16), nullable=False, server_default="recording")
        )
        batch.add_column(sa.Column("parent_id", sa.Integer(), nullable=True))
        batch.create_foreign_key(
            op.f("fk_recording_files_parent_id_recording_files"),
            "recording_files",
            ["parent_id"],
            ["id"],
            ondelete="CASCADE",
        )
        batch.create_index(op.f("ix_recording_files_parent_id"), ["parent_id"])
    op.create_table(
        "skeleton_frames",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("file_id", sa.Integer(), nullable=False),
        sa.Column("frame", sa.Integer(), nullable=False),
        sa.Column("time", sa.Float(), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("jpeg", sa.LargeBinary(), nullable=False),
        foreign_key("skeleton_frames", "file_id", "recording_files", ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_skeleton_frames")),
    )
    op.create_index(op.f("ix_skeleton_frames_file_id"), "skeleton_frames", ["file_id"])
    op.create_table(
        "pose_extractions",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("recording_id", sa.Integer(), nullable=True),
        sa.Column("video_file_id", sa.Integer(), nullable=True),
        sa.Column("result", sa.JSON(), nullable=True),
        foreign_key("pose_extractions", "id", "jobs", ondelete="CASCADE"),
        foreign_key("pose_extractions", "recording_id", "recording_sessions", ondelete="SET NULL"),
        foreign_key("pose_extractions", "video_file_id", "recording_files", ondelete="SET NULL"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_pose_extractions")),
    )
    op.create_index(
        op.f("ix_pose_extractions_recording_id"), "pose_extractions", ["recording_id"]
    )
    op.create_index(
        op.f("ix_pose_extractions_video_file_id"), "pose_extractions", ["video_file_id"]
    )


def downgrade() -> None:
    op.drop_index(op.f("ix_pose_extractions_video_file_id"), table_name="pose_extractions")
    op.drop_index(op.f("ix_pose_extractions_recording_id"), table_name="pose_extractions")
    op.drop_table("pose_extractions")
    op.drop_index(op.f("ix_skeleton_frames_file_id"), table_name="skeleton_frames")
    op.drop_table("skeleton_frames")
    with op.batch_alter_table("recording_files") as batch:
        batch.drop_index(op.f("ix_recording_files_parent_id"))
        batch.drop_constraint(
            op.f("fk_recording_files_parent_id_recording_files"), type_="foreignkey"
        )
        batch.drop_column("parent_id")
        batch.drop_column("role")
    with op.batch_alter_table("recording_sessions") as batch:
        batch.drop_column("updated_at")
        batch.drop_column("session_mode")
