"""Job processes die with the server, at once, whatever the machine's load.

Three links, all kept by the kernel rather than by a thread that has to be scheduled:

1. The fork server asks for SIGKILL when the server's thread that started it exits
   (``prctl(PR_SET_PDEATHSIG)``); that thread (``runner._forkserver_keeper``) lives as long as
   the server process, so the fork server dies exactly when the server does.
2. Each job process asks for SIGKILL when the fork server, its parent, exits.
3. Each job process forks a tiny group reaper first: it blocks on a pipe only the job process
   holds, and when that pipe breaks (the job process is gone, however it ended) it SIGKILLs the
   job's process group, which takes the worker processes a job started (a sweep's pool) with
   it. The reaper needs one read and one kill, no interpreter time worth speaking of.

On systems without ``prctl`` (not Linux), links 1 and 2 fall back to a thread that polls the
parent's pid; link 3 works on every POSIX system.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time

#: ``PR_SET_PDEATHSIG`` from ``<linux/prctl.h>``.
PR_SET_PDEATHSIG = 1
#: Seconds between two checks of the parent's pid where ``prctl`` is missing.
POLL_SECONDS = 0.2


def _prctl_pdeathsig(sig: int) -> bool:
    """``prctl(PR_SET_PDEATHSIG, sig)``; False where it does not exist."""
    if not sys.platform.startswith("linux"):
        return False
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(PR_SET_PDEATHSIG, sig, 0, 0, 0) != 0:
        err = ctypes.get_errno()
        raise OSError(err, f"prctl(PR_SET_PDEATHSIG) failed: {os.strerror(err)}")
    return True


def _poll_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(POLL_SECONDS)
    os.kill(os.getpid(), signal.SIGKILL)


def die_with_parent(parent: int) -> None:
    """SIGKILL this process as soon as ``parent`` (its parent when called) exits.

    Args:
        parent: the pid this process's parent had when the caller learnt it; if the parent
            already died before the kernel was asked, this process is killed at once.
    """
    if not _prctl_pdeathsig(signal.SIGKILL):
        threading.Thread(target=_poll_parent, args=(parent,), daemon=True).start()
    if os.getppid() != parent:  # the parent exited before prctl took effect
        os.kill(os.getpid(), signal.SIGKILL)


def reap_group_on_exit() -> int:
    """Fork a reaper that SIGKILLs this process's group once this process has exited.

    Call it first thing in a process that leads its own group (after ``os.setsid()``) and has
    no other thread yet. The reaper keeps no file descriptor but its end of one pipe.

    Returns:
        The reaper's pid.
    """
    # Not inheritable: only this process ever holds the write end, which stays open for its
    # whole life (the kernel closes it at exit, whatever the cause).
    read_end, _write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the reaper: only system calls from here on
        try:
            os.closerange(0, read_end)
            os.closerange(read_end + 1, os.sysconf("SC_OPEN_MAX"))
            with contextlib.suppress(OSError):
                while os.read(read_end, 1):
                    pass
            os.killpg(0, signal.SIGKILL)
        finally:
            os._exit(0)
    os.close(read_end)
    return pid
