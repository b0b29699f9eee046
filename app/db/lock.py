"""One server per data directory: an inter-process lock on ``<data_dir>/bioplan.lock``.

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
import threading
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
