"""Become the child subreaper for a while, to learn how a killed server's descendants ended.

When a process dies, the kernel re-parents its children to the nearest ancestor marked as
"child subreaper" (``prctl(PR_SET_CHILD_SUBREAPER)``). A test that starts a server and marks
itself so receives the server's orphans and can ``waitpid`` them: their exit status says
whether they were killed (by which signal) or exited on their own, and when.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import pytest

PR_SET_CHILD_SUBREAPER = 36


def _prctl(option: int, value: int) -> None:
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(option, value, 0, 0, 0) != 0:
        err = ctypes.get_errno()
        raise OSError(err, os.strerror(err))


@contextlib.contextmanager
def subreaper() -> Iterator[None]:
    """This process is the child subreaper inside the block (Linux only; skips elsewhere)."""
    if not sys.platform.startswith("linux"):
        pytest.skip("PR_SET_CHILD_SUBREAPER is Linux-only")
    _prctl(PR_SET_CHILD_SUBREAPER, 1)
    try:
        yield
    finally:
        _prctl(PR_SET_CHILD_SUBREAPER, 0)


@dataclass(frozen=True)
class Ending:
    """How a reaped process ended."""

    pid: int
    signal: int | None  # the signal that killed it, or None when it exited
    code: int | None  # its exit code, or None when a signal killed it
    after: float  # seconds from the reference time to when it was reaped

    @property
    def killed(self) -> bool:
        return self.signal == signal.SIGKILL


def reap(pids: Iterable[int], since: float, timeout: float) -> dict[int, Ending]:
    """Wait (up to ``timeout`` s) for each pid, which must be our child by now or soon.

    Args:
        pids: processes to reap (children of this process, or orphans re-parented to it).
        since: reference ``time.monotonic()`` (e.g. when their server died).
        timeout: seconds to wait for all of them, generous: the machine may be busy.

    Returns:
        pid -> how it ended, for every pid reaped in time.
    """
    waiting, out = set(pids), {}
    deadline = time.monotonic() + timeout
    while waiting and time.monotonic() < deadline:
        for pid in list(waiting):
            try:
                done, status = os.waitpid(pid, os.WNOHANG)
            except ChildProcessError:  # not (yet) re-parented to us
                continue
            if done:
                waiting.discard(pid)
                sig = os.WTERMSIG(status) if os.WIFSIGNALED(status) else None
                code = os.WEXITSTATUS(status) if os.WIFEXITED(status) else None
                out[pid] = Ending(pid, sig, code, time.monotonic() - since)
        time.sleep(0.005)
    return out
