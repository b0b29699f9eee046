"""Plans, simulations (every job) and recording sessions can carry the user's short name.

Revision ID: 0006_labels
Revises: 0005_recapi
Create Date: 2026-11-26
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0006_labels"
down_revision: str | None = "0005_recapi"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("label", sa.String(200), nullable=True))
    with op.batch_alter_table("recording_sessions") as batch:
        batch.add_column(sa.Column("label", sa.String(200), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("recording_sessions") as batch:
        batch.drop_column("label")
    with op.batch_alter_table("jobs") as batch:
        batch.drop_column("label")
