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

_held: dict[Path, list[int]] = {}  # lock file -> [descriptor, holders in this process]
_guard = threading.Lock()


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
        with _guard:
            entry = _held.get(self.path)
            if entry is None:
                return
            entry[1] -= 1
            if entry[1] == 0:
                del _held[self.path]
                os.close(entry[0])  # closing the descriptor drops the flock


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
    with _guard:
        entry = _held.get(path)
        if entry is not None:
            entry[1] += 1
            return DataDirLock(path)
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            raise _unusable(data_dir, exc) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_pid(fd)
            os.close(fd)
            who = f"process {holder}" if holder else "another process"
            raise DataDirBusyError(
                f"the data directory {data_dir} is in use by {who} (another bioplan serve?): "
                "stop it, or choose another folder with --data-dir or BIOPLAN_DATA_DIR"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        _held[path] = [fd, 1]
        return DataDirLock(path)


def _read_pid(fd: int) -> int | None:
    with contextlib.suppress(OSError, ValueError):
        return int(os.pread(fd, 32, 0).decode().strip())
    return None


# ------------------------------------------------------------------------------ database claim

#: The PostgreSQL advisory lock key of "the server of this database" (``b"bioplan"``).
PG_LOCK_KEY = 0x62696F706C616E

_db_held: dict[str, list[object]] = {}  # database key -> [release callable, holders]


class DatabaseBusyError(DataDirError):
    """Another server uses this database (from another data directory, or another machine)."""


@dataclass(frozen=True)
class DatabaseLock:
    """A hold on a database's claim; :meth:`release` once (the last one in the process frees
    it)."""

    key: str

    def release(self) -> None:
        with _guard:
            entry = _db_held.get(self.key)
            if entry is None:
                return
            entry[1] = int(entry[1]) - 1  # type: ignore[call-overload]
            if entry[1] == 0:
                del _db_held[self.key]
                free = entry[0]
                assert callable(free)
                with contextlib.suppress(Exception):
                    free()


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
    with _guard:
        entry = _db_held.get(key)
        if entry is not None:
            entry[1] = int(entry[1]) + 1  # type: ignore[call-overload]
            return DatabaseLock(key)
        if backend == "sqlite":
            free = _claim_sqlite(Path(database).resolve(), data_dir)
        else:
            free = _claim_postgres(url, key, data_dir)
        _db_held[key] = [free, 1]
        return DatabaseLock(key)


def _claim_sqlite(database: Path, data_dir: Path | None) -> Callable[[], None]:
    path = database.with_name(database.name + ".server.lock")
    try:
        database.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    except OSError:  # a folder we cannot write: the database cannot be written either
        return lambda: None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = ""
        with contextlib.suppress(OSError):
            holder = os.pread(fd, 512, 0).decode(errors="replace").strip()
        os.close(fd)
        who = holder or "another process"
        raise DatabaseBusyError(
            f"the database {database} is in use by another server ({who}): one server per "
            "database; stop it, or give this one its own database (BIOPLAN_DATABASE_URL)"
        ) from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{_holder_line(data_dir)}\n".encode(), 0)

    def free() -> None:
        os.close(fd)

    return free


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
