"""Table shapes several migrations create the same way.

Frozen, like the migrations that call it: a released revision must go on building the schema it
built, so never change a function here (a changed one would change every revision that calls
it); add a new one instead. ``tests/db/test_migration_schemas.py`` checks the schema every
revision leaves, up and down, against the one recorded when the revisions were released.
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op


def foreign_key(table: str, column: str, target: str, *, ondelete: str) -> sa.ForeignKeyConstraint:
    """``table.column`` referring to ``target.id``, named as the models' naming convention
    names it (``fk_<table>_<column>_<target>``)."""
    return sa.ForeignKeyConstraint(
        [column], [f"{target}.id"], name=op.f(f"fk_{table}_{column}_{target}"), ondelete=ondelete
    )


def create_job_result_table(
    name: str, *items: sa.schema.SchemaItem, indexed: Sequence[str] = ()
) -> None:
    """Create table ``name``, one row per job result: ``id`` (the job's id, the row deleted with
    its job), then ``items`` (columns and constraints) in order, and an index on each column of
    ``indexed``."""
    op.create_table(
        name,
        sa.Column("id", sa.Integer(), nullable=False),
        *items,
        foreign_key(name, "id", "jobs", ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id", name=op.f(f"pk_{name}")),
    )
    for column in indexed:
        op.create_index(op.f(f"ix_{name}_{column}"), name, [column])


def drop_job_result_table(name: str, kind: str, *, indexed: Sequence[str] = ()) -> None:
    """Drop a table made by :func:`create_job_result_table` (after ``0007_result_blobs``) with
    its jobs of ``kind`` and their stored blobs. Foreign keys are off while migrations run on
    SQLite, so the dependants are removed by hand."""
    jobs = f"SELECT id FROM jobs WHERE kind = '{kind}'"
    op.execute(f"DELETE FROM result_blobs WHERE job_id IN ({jobs})")
    for column in reversed(indexed):
        op.drop_index(op.f(f"ix_{name}_{column}"), table_name=name)
    op.drop_table(name)
    op.execute(f"DELETE FROM jobs WHERE kind = '{kind}'")
