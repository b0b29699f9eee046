"""Uploaded robots keep a package (zip with meshes), a sidecar and their options; MJCF-only
robots have no URDF file; ``profiles`` jobs get their result table.

Revision ID: 0004_planapi
Revises: 0003
Create Date: 2026-11-23
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.db.migrations._tables import create_job_result_table

revision: str = "0004_planapi"
down_revision: str | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("robots") as batch:
        batch.alter_column("urdf_sha256", existing_type=sa.String(64), nullable=True)
        batch.alter_column("urdf_name", existing_type=sa.String(255), nullable=True)
        batch.add_column(sa.Column("package_sha256", sa.String(64), nullable=True))
        batch.add_column(sa.Column("package_name", sa.String(255), nullable=True))
        batch.add_column(sa.Column("sidecar_sha256", sa.String(64), nullable=True))
        batch.add_column(sa.Column("sidecar_name", sa.String(255), nullable=True))
        batch.add_column(sa.Column("options", sa.JSON(), nullable=True))
    create_job_result_table(
        "profiles",
        sa.Column("robot", sa.String(100), nullable=False),
        sa.Column("result", sa.JSON(), nullable=True),
        indexed=["robot"],
    )


def downgrade() -> None:
    op.execute("DELETE FROM jobs WHERE kind = 'profiles'")
    op.drop_table("profiles")
    # Robots that 0003 cannot describe (an MJCF alone, or a package) are removed.
    op.execute("DELETE FROM robots WHERE urdf_sha256 IS NULL OR package_sha256 IS NOT NULL")
    with op.batch_alter_table("robots") as batch:
        batch.drop_column("options")
        batch.drop_column("sidecar_name")
        batch.drop_column("sidecar_sha256")
        batch.drop_column("package_name")
        batch.drop_column("package_sha256")
        batch.alter_column("urdf_name", existing_type=sa.String(255), nullable=False)
        batch.alter_column("urdf_sha256", existing_type=sa.String(64), nullable=False)
