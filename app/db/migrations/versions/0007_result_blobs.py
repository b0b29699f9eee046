"""Job results too large for their row are kept in the file store, referenced from here.

Revision ID: 0007_result_blobs
Revises: 0006_labels
Create Date: 2026-11-27
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import sqlalchemy as sa
from alembic import op

from app.db.migrations._tables import foreign_key

revision: str = "0007_result_blobs"
down_revision: str | None = "0006_labels"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "result_blobs",
        sa.Column("job_id", sa.Integer(), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("size", sa.BigInteger(), nullable=False),
        foreign_key("result_blobs", "job_id", "jobs", ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("job_id", name=op.f("pk_result_blobs")),
    )
    op.create_index(op.f("ix_result_blobs_sha256"), "result_blobs", ["sha256"])


def downgrade() -> None:
    """Results kept in the file store are put back into their rows before the table goes."""
    conn = op.get_bind()
    rows = conn.execute(sa.text("SELECT job_id, sha256 FROM result_blobs")).all()
    if rows:
        _inline_again(conn, rows)
    op.drop_index(op.f("ix_result_blobs_sha256"), table_name="result_blobs")
    op.drop_table("result_blobs")


def _inline_again(conn: sa.Connection, rows: Sequence[Any]) -> None:
    from app.config import Settings

    blob_dir = Settings().blob_dir
    tables = ("analyses", "pose_extractions", "plans", "simulations", "sweeps", "profiles")
    for job_id, sha in rows:
        path = blob_dir / sha[:2] / sha
        if not path.is_file():
            raise RuntimeError(
                f"cannot downgrade: the result of job {job_id} is kept in the file store "
                f"({path}) and that file is missing; set BIOPLAN_DATA_DIR to the server's folder"
            )
        text = path.read_text(encoding="utf-8")
        value = "CAST(:r AS JSON)" if conn.dialect.name == "postgresql" else ":r"
        for table in tables:
            conn.execute(
                sa.text(f"UPDATE {table} SET result = {value} WHERE id = :i"),
                {"r": text, "i": job_id},
            )
