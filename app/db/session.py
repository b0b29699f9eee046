"""Engine, sessions and migrations.

SQLite (the default, in the data directory) runs in WAL mode with foreign keys on, so readers
never wait for the job-progress writer and ``ON DELETE CASCADE`` works. PostgreSQL uses the same
code with a ``postgresql+psycopg://`` URL.

SQLite opens a database it cannot write (a disk remounted read-only) read-only, silently, and
such a connection never writes again. One opened so is marked, and replaced at its next checkout
once the file is writable again: reads go on while the disk is read-only, and writes work as
soon as it is back, without a restart.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from importlib.resources import files
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, create_engine, event
from sqlalchemy.exc import DisconnectionError
from sqlalchemy.orm import Session, sessionmaker

#: The Alembic environment and versions, shipped inside the package (``app/db/migrations``), so
#: an installed wheel migrates its database exactly as a source checkout does.
MIGRATIONS_DIR = Path(str(files("app.db.migrations")))


def _sqlite_pragmas(*, foreign_keys: bool) -> Callable[[Any, Any], None]:
    """A connect hook: WAL, foreign keys on or off, NORMAL sync, a busy timeout; a connection
    whose file is not writable is marked (``read_only_file``)."""

    def on_connect(dbapi_connection: Any, connection_record: Any) -> None:
        cursor = dbapi_connection.cursor()
        try:
            cursor.execute("PRAGMA journal_mode=WAL")
            cursor.execute(f"PRAGMA foreign_keys={'ON' if foreign_keys else 'OFF'}")
            # NORMAL is durable across process crashes in WAL mode (only an OS crash may lose
            # the last commits), and much faster than FULL for the job-progress writes.
            cursor.execute("PRAGMA synchronous=NORMAL")
            cursor.execute("PRAGMA busy_timeout=30000")
            main = next((row[2] for row in cursor.execute("PRAGMA database_list")), "")
        finally:
            cursor.close()
        if main and not os.access(main, os.W_OK):
            connection_record.info["read_only_file"] = main

    return on_connect


def _reopen_when_writable(dbapi_connection: Any, connection_record: Any, proxy: Any) -> None:
    """A checkout hook: a connection opened read-only is replaced once its file is writable."""
    del dbapi_connection, proxy
    path = connection_record.info.get("read_only_file")
    if path is not None and os.access(path, os.W_OK):
        raise DisconnectionError(f"{path} was opened read-only and is writable again")


def make_engine(url: str, *, for_migrations: bool = False, **kwargs: Any) -> Engine:
    """An engine for ``url`` with the pragmas and pool settings this service expects.

    Args:
        url: SQLAlchemy URL.
        for_migrations: SQLite only: leave foreign keys unenforced (Alembic's batch mode
            recreates tables, and dropping a referenced table would cascade).
    """
    if url.startswith("sqlite"):
        if url.startswith("sqlite:///") and not url.startswith("sqlite:///:memory:"):
            Path(url.removeprefix("sqlite:///")).parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(
            url, connect_args={"check_same_thread": False, "timeout": 30}, **kwargs
        )
        # SQLite's batch migrations copy a table, drop the old one and rename the copy: with
        # foreign keys enforced, dropping ``jobs`` would cascade into every result row.
        event.listen(engine, "connect", _sqlite_pragmas(foreign_keys=not for_migrations))
        event.listen(engine, "checkout", _reopen_when_writable)
        return engine
    return create_engine(url, pool_pre_ping=True, **kwargs)


def make_sessionmaker(engine: Engine) -> sessionmaker[Session]:
    return sessionmaker(engine, expire_on_commit=False)


def alembic_config(url: str) -> Any:
    """An Alembic ``Config`` for ``url`` that does not touch the logging configuration.

    Built in code (no ``alembic.ini`` needed): the scripts come from the installed package.
    """
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    cfg.set_main_option("path_separator", "os")
    # ConfigParser interpolation: a literal % in a password must be doubled.
    cfg.set_main_option("sqlalchemy.url", url.replace("%", "%%"))
    cfg.attributes["configure_logger"] = False
    return cfg


def upgrade(url: str, revision: str = "head") -> None:
    """Run ``alembic upgrade <revision>`` on ``url`` (programmatically, in this process)."""
    from alembic import command

    command.upgrade(alembic_config(url), revision)


def downgrade(url: str, revision: str) -> None:
    """Run ``alembic downgrade <revision>`` on ``url``."""
    from alembic import command

    command.downgrade(alembic_config(url), revision)


def current_revision(engine: Engine) -> str | None:
    from alembic.runtime.migration import MigrationContext

    with engine.connect() as conn:
        rev: str | None = MigrationContext.configure(conn).get_current_revision()
        return rev
