"""Untrusted uploads are read in a child process with a memory and a time limit.

The readers refuse what a file declares to be too large before reading it (decoded sizes,
inflated sizes, replicate counts), but a file can still cost more memory or time than its
declarations say. Read in the API process, such a file would take the whole server down with
it (issue 14 item 7); read here, it costs one child process, which is refused memory beyond
``memory_mb`` (``setrlimit(RLIMIT_AS)``: an allocation past it fails with ``MemoryError``)
and is killed after ``seconds``. The upload is then refused with 413 and the limit named.

The child is forked from the job runner's fork server (the readers already imported), so a
parse costs a fork, not an interpreter start. What the reader raises (a ``BioPlanError`` for
bad input, anything else for a bug) is raised again here unchanged, so a reader's bug stays a
500 and bad input stays a 4xx.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import resource
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import TypeVar

from app.jobs.runner import address_space, ensure_forkserver
from app.services.errors import ParseLimitError

T = TypeVar("T")

#: How much lower the child's CPU priority is than the API process's (``nice``).
NICENESS = 10
#: Seconds a killed child is given to be reaped.
REAP_SECONDS = 5.0


def _child(
    send: Connection, fn: Callable[..., object], args: tuple[object, ...], extra: int
) -> None:
    """Run ``fn(*args)`` with at most ``extra`` bytes more address space; send (ok, value)."""
    from app.jobs.tasks import preload

    # Everything a reader may import, before the limit: already there when forked from the
    # runner's warm fork server, imported here otherwise, so the limit counts the file's data
    # and never the libraries (found under load: a 100 kB CSV refused at 128 MB because SciPy
    # and the readers were imported inside the limit).
    preload()
    # Arrow's thread pools would reserve a stack per core, and its default allocator whole
    # arenas, inside the limit: one thread each, and plain malloc, so the limit counts data.
    import pyarrow

    pyarrow.set_cpu_count(1)
    pyarrow.set_io_thread_count(1)
    pyarrow.set_memory_pool(pyarrow.system_memory_pool())
    _one_malloc_arena()
    # Below the API process in the scheduler's eyes, so reads stay quick while a file is read.
    os.nice(NICENESS)
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = address_space() + extra
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    try:
        outcome: tuple[bool, object] = (True, fn(*args))
    except MemoryError:
        outcome = (False, MemoryError())
    except BaseException as exc:  # sent back whole: the parent raises it again
        outcome = (False, exc)
    try:
        send.send(outcome)
    except MemoryError:  # the answer itself does not fit
        send.send((False, MemoryError()))
    except Exception as exc:  # an exception that does not pickle: its type and text
        send.send((False, RuntimeError(f"{type(outcome[1]).__name__}: {outcome[1]} ({exc})")))


#: glibc's ``mallopt`` parameter for the most malloc arenas.
_M_ARENA_MAX = -8


def _one_malloc_arena() -> None:
    """One malloc arena for every thread of the child. glibc gives a thread that finds the main
    arena busy an arena of its own, reserving 64 MB of address space, which ``RLIMIT_AS``
    counts: under load (threads preempted holding the lock) Arrow's reader threads took enough
    to refuse a 100 kB CSV at 128 MB. Elsewhere than glibc, nothing to do."""
    import ctypes

    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).mallopt(_M_ARENA_MAX, 1)


class ParseSandbox:
    """Runs reader calls in a child process with limits.

    Args:
        memory_mb: memory a call may take beyond what the child starts with [MB].
        seconds: longest a call may run [s].
    """

    def __init__(self, *, memory_mb: float, seconds: float) -> None:
        self.memory_mb = memory_mb
        self.seconds = seconds

    def run(self, fn: Callable[..., T], *args: object, what: str) -> T:
        """``fn(*args)`` in a child; ``what`` names the file in a refusal.

        Raises:
            ParseLimitError: the call needed more memory or time than the limits.
            Exception: whatever ``fn`` raised, unchanged.
        """
        # From the keeper thread that outlives every request (a fork server started from a
        # request's thread would die with it), with the runner's preload when one is set.
        ensure_forkserver()
        ctx = mp.get_context("forkserver")
        recv, send = ctx.Pipe(duplex=False)
        extra = int(self.memory_mb * 1024 * 1024)
        child = ctx.Process(target=_child, args=(send, fn, args, extra), daemon=True)
        child.start()
        send.close()
        try:
            if not recv.poll(self.seconds):
                raise ParseLimitError(
                    f"{what}: reading it took longer than {self.seconds:g} s, the limit for "
                    "one file (BIOPLAN_PARSE_SECONDS)",
                    file=what,
                )
            try:
                ok, value = recv.recv()
            except EOFError:  # killed (the kernel's OOM killer, a signal) before it answered
                ok, value = False, MemoryError()
        finally:
            if child.is_alive():
                child.kill()
            child.join(REAP_SECONDS)
            recv.close()
        if ok:
            return value  # type: ignore[no-any-return]
        if isinstance(value, MemoryError):
            raise ParseLimitError(
                f"{what}: reading it needs more than {self.memory_mb:g} MB of memory, the limit "
                "for one file (BIOPLAN_PARSE_MEMORY_MB)",
                file=what,
            )
        raise value


#: Where the services read uploads: set by ``start_services``, in-process until then.
_active: ParseSandbox | None = None


def use(sandbox: ParseSandbox) -> None:
    """Read every upload through ``sandbox`` from now on."""
    global _active
    _active = sandbox


def release(sandbox: ParseSandbox) -> None:
    """Stop using ``sandbox``, if it is still the one in use (services of one process may
    start and stop in any order: tests do)."""
    global _active
    if _active is sandbox:
        _active = None


def read_untrusted(fn: Callable[..., T], *args: object, what: str) -> T:
    """``fn(*args)`` through the active sandbox, or in this process when there is none (the
    library and the CLI, which read the user's own files)."""
    if _active is None:
        return fn(*args)
    return _active.run(fn, *args, what=what)
