"""One server per data directory (an inter-process lock on ``<data_dir>/bioplan.lock``) and one
server per database (:func:`lock_database`: a claim on the database itself, so two servers on
different data directories sharing one ``BIOPLAN_DATABASE_URL`` cannot both run).

Two servers on one data directory corrupt each other: the second's start-up cleanup removes
files the first has written but not yet committed, and it re-runs the first's running jobs. The
first server takes an exclusive ``flock`` on the lock file and writes its pid there; a second
one finds the lock taken and refuses to start, naming that pid. The kernel drops the lock when
the holder's descriptor closes, so a crashed (even SIGKILLed) server never leaves a stale lock:
job processes do not hold it (the fork server and every worker are started by ``exec``, which
closes the descriptor, which is not inheritable).

Within one process the lock is shared: ``bioplan serve`` takes it before migrating and seeding,
and the services it starts take it again (a count, released by the last holder).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from app.errors import BioPlanError

LOCK_NAME = "bioplan.lock"

_guard = threading.Lock()


class _Shared:
    """Claims shared within this process: the first :meth:`take` of a key makes the claim,
    later ones count; the last :meth:`release` frees it."""

    def __init__(self) -> None:
        self._held: dict[str, tuple[Callable[[], None], int]] = {}  # key -> (free, holders)

    def take(self, key: str, claim: Callable[[], Callable[[], None]]) -> None:
        """Share the claim on ``key``, or make it with ``claim()`` (which returns its free)."""
        with _guard:
            entry = self._held.get(key)
            self._held[key] = (entry[0], entry[1] + 1) if entry is not None else (claim(), 1)

    def release(self, key: str) -> None:
        with _guard:  # freed under the guard: a new claim of the key waits until it is
            entry = self._held.pop(key, None)
            if entry is None:
                return
            free, holders = entry
            if holders > 1:
                self._held[key] = (free, holders - 1)
                return
            # A failure only means the claim is gone already (the process or the database
            # session ends it anyway).
            with contextlib.suppress(Exception):
                free()


_dirs = _Shared()  # lock file path -> its descriptor's close
_databases = _Shared()  # database key -> its claim's release


def _exclusive(fd: int, holder_line: str, *, max_bytes: int = 512) -> str | None:
    """Take an exclusive ``flock`` on ``fd`` and write ``holder_line`` into its file; when
    another process holds it, close ``fd`` and return what that holder wrote ('' if
    nothing)."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = ""
        with contextlib.suppress(OSError):
            holder = os.pread(fd, max_bytes, 0).decode(errors="replace").strip()
        os.close(fd)
        return holder
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{holder_line}\n".encode(), 0)
    return None


class DataDirError(BioPlanError):
    """The data directory cannot be served: not writable, or another server's."""


class DataDirBusyError(DataDirError):
    """Another process serves this data directory."""


def _unusable(data_dir: Path, exc: OSError) -> DataDirError:
    reason = "a read-only file system" if exc.errno == errno.EROFS else (exc.strerror or str(exc))
    return DataDirError(
        f"the data directory {data_dir} is not writable ({reason}): the server stores its "
        "database and uploads there; choose a writable folder with --data-dir or "
        "BIOPLAN_DATA_DIR"
    )


@dataclass(frozen=True)
class DataDirLock:
    """A hold on a data directory's lock; :meth:`release` once (the last one unlocks)."""

    path: Path

    def release(self) -> None:
        _dirs.release(str(self.path))  # closing the descriptor drops the flock


def lock_data_dir(data_dir: Path) -> DataDirLock:
    """Take (or share, within this process) the data directory's lock.

    Args:
        data_dir: the server's data folder (created if missing).

    Raises:
        DataDirBusyError: another process holds it; the message names its pid and the folder.
        DataDirError: the folder cannot be created or written (a read-only file system, no
            permission, a file in the way).
    """
    try:
        data_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _unusable(data_dir, exc) from None
    path = (data_dir / LOCK_NAME).resolve()

    def claim() -> Callable[[], None]:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            raise _unusable(data_dir, exc) from None
        holder = _exclusive(fd, str(os.getpid()), max_bytes=32)
        if holder is not None:
            who = f"process {holder}" if holder.isdigit() else "another process"
            raise DataDirBusyError(
                f"the data directory {data_dir} is in use by {who} (another bioplan serve?): "
                "stop it, or choose another folder with --data-dir or BIOPLAN_DATA_DIR"
            )
        return lambda: os.close(fd)

    _dirs.take(str(path), claim)
    return DataDirLock(path)


# ------------------------------------------------------------------------------ database claim

#: The PostgreSQL advisory lock key of "the server of this database" (``b"bioplan"``).
PG_LOCK_KEY = 0x62696F706C616E


class DatabaseBusyError(DataDirError):
    """Another server uses this database (from another data directory, or another machine)."""


@dataclass(frozen=True)
class DatabaseLock:
    """A hold on a database's claim; :meth:`release` once (the last one in the process frees
    it)."""

    key: str

    def release(self) -> None:
        _databases.release(self.key)


def _holder_line(data_dir: Path | None) -> str:
    where = f" serving {data_dir.resolve()}" if data_dir is not None else ""
    return f"pid {os.getpid()} on {socket.gethostname()}{where}"


def lock_database(url: str, *, data_dir: Path | None = None) -> DatabaseLock:
    """Claim the database for this server (or share the claim, within this process).

    Two servers on one database, even from different data directories, re-run and fail each
    other's running jobs. SQLite: an exclusive ``flock`` on ``<database>.server.lock`` beside
    the database file, which names its holder. PostgreSQL: a session-level advisory lock
    (``pg_try_advisory_lock``) held by one connection for the server's life, whose
    ``application_name`` names its holder. The claim goes with the process, even a SIGKILLed
    one (the kernel closes the descriptor; PostgreSQL ends the session). Other databases (and
    in-memory SQLite) are not claimed.

    Raises:
        DatabaseBusyError: another server holds it; the message names that server.
    """
    from sqlalchemy.engine import make_url

    parsed = make_url(url)
    backend = parsed.get_backend_name()
    if backend == "sqlite":
        database = parsed.database or ""
        if not database or database == ":memory:" or database.startswith("file:"):
            return DatabaseLock("")
        key = f"sqlite:{Path(database).resolve()}"
    elif backend == "postgresql":
        key = parsed.render_as_string(hide_password=True)
    else:
        return DatabaseLock("")
    if backend == "sqlite":
        _databases.take(key, lambda: _claim_sqlite(Path(database).resolve(), data_dir))
    else:
        _databases.take(key, lambda: _claim_postgres(url, key, data_dir))
    return DatabaseLock(key)


def _claim_sqlite(database: Path, data_dir: Path | None) -> Callable[[], None]:
    path = database.with_name(database.name + ".server.lock")
    try:
        database.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    except OSError:  # a folder we cannot write: the database cannot be written either
        return lambda: None
    holder = _exclusive(fd, _holder_line(data_dir))
    if holder is not None:
        raise DatabaseBusyError(
            f"the database {database} is in use by another server "
            f"({holder or 'another process'}): one server per database; stop it, or give "
            "this one its own database (BIOPLAN_DATABASE_URL)"
        )
    return lambda: os.close(fd)


def _claim_postgres(url: str, shown: str, data_dir: Path | None) -> Callable[[], None]:
    from sqlalchemy import create_engine, text
    from sqlalchemy.pool import NullPool

    name = f"bioplan {_holder_line(data_dir)}"[:63]
    engine = create_engine(url, poolclass=NullPool, connect_args={"application_name": name})
    conn = engine.connect()
    try:
        got = conn.execute(text("SELECT pg_try_advisory_lock(:k)"), {"k": PG_LOCK_KEY}).scalar()
        conn.commit()
        if not got:
            row = conn.execute(
                text(
                    "SELECT a.application_name, a.client_addr, a.pid FROM pg_locks l "
                    "JOIN pg_stat_activity a ON a.pid = l.pid WHERE l.locktype = 'advisory' "
                    "AND l.granted AND l.classid = :hi AND l.objid = :lo AND l.database = "
                    "(SELECT oid FROM pg_database WHERE datname = current_database())"
                ),
                {"hi": PG_LOCK_KEY >> 32, "lo": PG_LOCK_KEY & 0xFFFFFFFF},
            ).first()
            who = "another server"
            if row is not None:
                client = row[1] or "a local socket"
                who = f"{row[0] or 'a client'} (connection from {client}, backend {row[2]})"
            raise DatabaseBusyError(
                f"the database {shown} is in use by {who}: one server per database; stop it, "
                "or give this one its own database (BIOPLAN_DATABASE_URL)"
            )
    except BaseException:
        conn.close()
        engine.dispose()
        raise

    def free() -> None:
        try:
            conn.execute(text("SELECT pg_advisory_unlock(:k)"), {"k": PG_LOCK_KEY})
        finally:
            conn.close()
            engine.dispose()

    return free
