"""Job runners: where job functions execute. Two implementations of one interface.

``LocalRunner`` (default, embedded): each job runs in its own process, forked from a fork server
that has already imported the science packages; at most ``max_workers`` at a time, the rest wait
in a FIFO queue. Progress flows back through a pipe per job to one monitor thread.

``DaskRunner``: jobs are Dask tasks on a ``distributed`` cluster (``BIOPLAN_EXECUTOR=
dask://HOST:PORT``); progress flows back as structured events (``Worker.log_event`` ->
``Client.subscribe_topic``).

Both report to an ``EventSink`` callable in the API process: ``started``, ``progress``, then
exactly one of ``succeeded`` (with the plain-data result), ``failed`` (with a one-line error) or
``cancelled``. Workers never touch the database.

Job logs (both runners): a job records the ``bioplan`` loggers' records at INFO and above
(``app.logs.LogTail``: its last 500 lines, at most 64 kB; on Dask the records of the task's
thread only, as tasks share a worker process) and sends the new lines with each progress report
and with its outcome; the final event carries the log (``log``), so a cancelled or stopped job
keeps what it had said by its last progress report.

Cancellation semantics:
- queued job: removed from the queue at once (both runners).
- running job, local runner: its process group is terminated (SIGTERM) at once; any result it
  had not yet sent is discarded.
- the server dies (even SIGKILL), local runner: the fork server, every job process and what
  they started die with it at once (``app.jobs._lifeline``: kernel parent-death signals and a
  group reaper per job, no polling).
- running job, Dask: a distributed ``Event`` is set and the future cancelled; the job function
  stops at its next progress report (the progress callback raises ``JobCancelled``), since Dask
  cannot interrupt a running task.
A job that finishes before the cancel request is handled keeps its result.

Like every multiprocessing start method other than ``fork``, the fork server re-imports the
``__main__`` module of the API process in each job: a script that creates the app must guard its
top level with ``if __name__ == "__main__":`` (``bioplan serve``, uvicorn and pytest do).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import queue
import resource
import signal
import threading
import time
import traceback
import uuid
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from types import ModuleType
from typing import TYPE_CHECKING, Any, Literal, Protocol, Required, TypedDict

from app.errors import BioPlanError
from app.jobs._lifeline import die_with_parent, reap_group_on_exit
from app.logs import LogTail, capture
from app.progress import Progress, ProgressFn

if TYPE_CHECKING:  # not at run time: app.jobs.tasks imports the science packages
    from app.jobs.tasks.types import JobResult, Payload

logger = logging.getLogger(__name__)

EventType = Literal["started", "progress", "succeeded", "failed", "cancelled"]


class ProgressDetail(TypedDict):
    """A ``progress`` event's structured detail: the fields of ``app.progress.Progress``."""

    stage: str
    done: int
    of: int
    fraction: float
    best: float | None
    message: str


class _TaskMessage(TypedDict, total=False):
    """What a Dask task publishes on its job's topic: ``started``, or ``progress`` with
    ``Progress.to_dict()`` and the log lines since the last message."""

    job: Required[int]
    type: Required[Literal["started", "progress"]]
    detail: dict[str, object]
    log: list[str]


Target = Callable[[str, "Payload", ProgressFn], "JobResult"]


class JobCancelled(Exception):
    """Raised inside a job (from its progress callback) when it was cancelled."""


class JobFailed(Exception):
    """A job function raised; the message is the job's one-line ``error``."""


@dataclass(frozen=True)
class JobEvent:
    """Something that happened to a job, reported by a runner.

    Attributes:
        job_id: the job.
        type: what happened.
        progress: fraction done in [0, 1] (``progress`` events).
        message: human-readable status.
        detail: the structured progress, ``Progress.to_dict()`` (``progress`` events).
        result: the job function's return value (``succeeded``).
        error: one-line error message (``failed``).
        log: the job's log lines (``app.logs.LogTail.lines``) on its final event; None on
            the other events (and from a runner that keeps no log).
    """

    job_id: int
    type: EventType
    progress: float | None = None
    message: str = ""
    result: JobResult | None = None
    error: str | None = None
    detail: ProgressDetail | None = None
    log: list[str] | None = None


EventSink = Callable[[JobEvent], None]


def describe_error(exc: BaseException | None) -> str:
    """One line for a job's ``error`` field: bad input as is, anything else with its type."""
    if exc is None:
        return "unknown error"
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    if isinstance(exc, BioPlanError | JobFailed) and text:
        return text
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _progress_event(job_id: int, detail: dict[str, object]) -> JobEvent:
    """A ``progress`` event from a job's ``Progress.to_dict()``."""
    update = Progress.from_dict(detail)
    return JobEvent(
        job_id,
        "progress",
        progress=update.fraction,
        message=update.message,
        detail=ProgressDetail(
            stage=update.stage,
            done=update.done,
            of=update.of,
            fraction=update.fraction,
            best=update.best,
            message=update.message,
        ),
    )


def _default_target() -> Target:
    from app.jobs.tasks import run_task

    return run_task


class JobRunner(ABC):
    """Runs jobs somewhere and reports their events to a sink in this process."""

    executor: str

    @abstractmethod
    def start(self, sink: EventSink) -> None:
        """Start reporting events to ``sink`` (called once, before ``submit``)."""

    @abstractmethod
    def submit(self, job_id: int, kind: str, payload: Payload) -> None:
        """Queue a job; returns at once."""

    @abstractmethod
    def cancel(self, job_id: int) -> bool:
        """Cancel a queued or running job; False when this runner does not know it."""

    @abstractmethod
    def shutdown(self) -> None:
        """Stop every job and release resources; no events are reported afterwards."""

    @abstractmethod
    def info(self) -> dict[str, object]:
        """``executor``, ``workers``, ``running``, ``queued`` for the health endpoint."""


# ------------------------------------------------------------------------------------ local


def address_space() -> int:
    """This process's virtual memory now [bytes] (``VmSize``)."""
    with open("/proc/self/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0  # pragma: no cover - every Linux has VmSize


def limit_memory(memory_mb: float | None) -> None:
    """Refuse this process more than ``memory_mb`` of address space beyond what it has now
    (``RLIMIT_AS``: an allocation past it fails with ``MemoryError``; children inherit it)."""
    if memory_mb is None:
        return
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = address_space() + int(memory_mb * 1024 * 1024)
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))


def out_of_memory(memory_mb: float | None) -> str:
    """The ``error`` of a job that passed its memory limit."""
    return (
        f"ran out of memory: the job needed more than {memory_mb:g} MB beyond its start "
        f"(BIOPLAN_JOB_MEMORY_MB={memory_mb:g})"
    )


#: What a failed allocation says when it is not a ``MemoryError``: a C++ library's
#: ``std::bad_alloc``, a shared library that cannot be mapped, an ``ENOMEM``.
_MEMORY_WORDS = ("bad_alloc", "failed to map segment", "cannot allocate memory")


def _is_memory_error(exc: BaseException) -> bool:
    """``MemoryError``, or another type that says an allocation failed."""
    text = str(exc).lower()
    return isinstance(exc, MemoryError) or any(word in text for word in _MEMORY_WORDS)


def _child_main(
    target: Target,
    job_id: int,
    kind: str,
    payload: Payload,
    conn: Connection,
    server_pid: int,
    memory_mb: float | None = None,
) -> None:
    """Body of a local job process: run the target, send progress and the outcome."""
    fork_server = os.getppid()
    os.setsid()  # own process group, so cancel can stop helpers the job starts (sweep pools)
    # Before any thread starts: the reaper is forked from a single-threaded process.
    reap_group_on_exit()
    die_with_parent(fork_server)
    if not _alive(server_pid):  # the server died before the fork server could take us along
        os.killpg(0, signal.SIGKILL)
    limit_memory(memory_mb)
    last = [0.0]
    tail = LogTail()

    def send_log() -> None:
        lines = tail.take()
        if lines:
            conn.send(("log", lines))

    def progress(update: Progress) -> None:
        now = time.monotonic()
        # The API throttles further; this only keeps a tight loop from flooding the pipe.
        if update.fraction < 1.0 and now - last[0] < 0.02:
            return
        last[0] = now
        # From the thread that reports progress, never from a logging call: a sweep's pool
        # workers inherit the handler but not the right to write on this pipe.
        send_log()
        conn.send(("progress", update.to_dict()))

    try:
        with capture(tail):
            result = target(kind, payload, progress)
        send_log()
        conn.send(("result", result))
    except BaseException as exc:
        if memory_mb is not None and _is_memory_error(exc):
            del exc  # let go of the frames that hold the memory before saying so
            logger.error("job %d (%s) %s", job_id, kind, out_of_memory(memory_mb))
            error = out_of_memory(memory_mb)
        else:
            logger.error("job %d (%s) failed:\n%s", job_id, kind, traceback.format_exc())
            error = describe_error(exc)
        with contextlib.suppress(Exception):  # the log is a courtesy; the error is the outcome
            send_log()
            conn.send(("log", [f"{time.strftime('%H:%M:%S')} ERROR bioplan: job failed: {error}"]))
        conn.send(("error", error))
    finally:
        conn.close()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else (pid reused): not our server
        return False
    return True


# The fork server dies with the thread that started it (``prctl(PR_SET_PDEATHSIG)`` in
# ``app.jobs._forkserver``), so it is always started from this one thread, which lives as long as
# the process: never from a runner's monitor thread (a runner that shuts down would take the
# fork server, and every other runner's jobs, with it) nor from a short-lived worker thread.
_keeper_requests: queue.Queue[tuple[threading.Event, list[BaseException]]] = queue.Queue()
_keeper_lock = threading.Lock()
_keeper: threading.Thread | None = None


def _forkserver_keeper() -> None:
    from multiprocessing import forkserver

    while True:
        done, errors = _keeper_requests.get()
        try:
            forkserver.ensure_running()
        except BaseException as exc:  # handed to the caller
            errors.append(exc)
        finally:
            done.set()


def ensure_forkserver() -> None:
    """Start multiprocessing's fork server (if it is not running) from the keeper thread."""
    global _keeper
    with _keeper_lock:
        if _keeper is None:
            _keeper = threading.Thread(
                target=_forkserver_keeper, name="bioplan-forkserver-keeper", daemon=True
            )
            _keeper.start()
    done, errors = threading.Event(), list[BaseException]()
    _keeper_requests.put((done, errors))
    done.wait()
    if errors:
        raise errors[0]


@dataclass
class _Running:
    job_id: int
    process: BaseProcess
    conn: Connection
    result: JobResult | None = None
    error: str | None = None
    has_outcome: bool = False
    cancel_requested: bool = False
    conn_open: bool = True
    started: float = field(default_factory=time.monotonic)
    timed_out: bool = False
    log: LogTail = field(default_factory=LogTail)


@dataclass
class _Pending:
    job_id: int
    kind: str
    payload: Payload = field(repr=False)


class LocalRunner(JobRunner):
    """A process per job on this machine, at most ``max_workers`` at a time.

    Args:
        max_workers: jobs running at the same time.
        target: job entry point ``fn(kind, payload, progress) -> dict``; a top-level function
            (it is pickled by reference). Defaults to ``app.jobs.tasks.run_task``.
        preload: modules the fork server imports once, so forked jobs start warm.
        time_limit: wall-clock seconds a job may run before it is stopped and failed with
            "time limit" (None: no limit).
        memory_mb: memory [MB] each job process may take beyond what it starts with
            (``RLIMIT_AS``; None: no limit); past it the job fails with "ran out of memory".
    """

    executor = "local"

    def __init__(
        self,
        max_workers: int = 2,
        *,
        target: Target | None = None,
        preload: tuple[str, ...] = ("app.jobs._preload",),
        time_limit: float | None = None,
        memory_mb: float | None = None,
    ) -> None:
        import multiprocessing as mp

        if max_workers < 1:
            raise ValueError(f"max_workers must be >= 1, got {max_workers}")
        self.max_workers = max_workers
        self.time_limit = time_limit
        self.memory_mb = memory_mb
        self._target = target or _default_target()
        self._ctx = mp.get_context("forkserver")
        # The fork server first ties its life to the server's, then imports what jobs need.
        self._preload = ["app.jobs._forkserver", *preload]
        self._pending: deque[_Pending] = deque()
        self._running: dict[int, _Running] = {}
        self._starting: dict[int, bool] = {}  # job id -> cancel requested while starting
        self._lock = threading.Lock()
        self._sink: EventSink | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._wake_r, self._wake_w = self._ctx.Pipe(duplex=False)

    # public API ---------------------------------------------------------------------------

    def start(self, sink: EventSink) -> None:
        self._sink = sink
        self._ctx.set_forkserver_preload(self._preload)
        self._thread = threading.Thread(target=self._monitor, name="bioplan-jobs", daemon=True)
        self._thread.start()

    def submit(self, job_id: int, kind: str, payload: Payload) -> None:
        if kind == "sweep" and payload.get("workers") is None:
            # A sweep fans its cells out over as many processes as the runner runs jobs.
            payload = {**payload, "workers": self.max_workers}
        with self._lock:
            self._pending.append(_Pending(job_id, kind, payload))
        self._wake()

    def cancel(self, job_id: int) -> bool:
        with self._lock:
            for p in self._pending:
                if p.job_id == job_id:
                    self._pending.remove(p)
                    self._emit(JobEvent(job_id, "cancelled", message="cancelled while queued"))
                    return True
            if job_id in self._starting:
                self._starting[job_id] = True
                return True
            run = self._running.get(job_id)
            if run is None:
                return False
            run.cancel_requested = True
            self._kill(run, signal.SIGTERM)
        self._wake()
        return True

    def shutdown(self) -> None:
        self._stop.set()
        self._wake()
        if self._thread is not None:
            self._thread.join(timeout=10)
        with self._lock:
            self._pending.clear()
            runs = list(self._running.values())
            self._running.clear()
        for run in runs:
            self._kill(run, signal.SIGKILL)
            run.process.join(timeout=5)
            run.conn.close()
        self._sink = None

    def info(self) -> dict[str, object]:
        with self._lock:
            return {
                "executor": self.executor,
                "workers": self.max_workers,
                "running": len(self._running),
                "queued": len(self._pending),
            }

    # internals ----------------------------------------------------------------------------

    def _emit(self, event: JobEvent) -> None:
        sink = self._sink
        if sink is not None:
            sink(event)

    def _wake(self) -> None:
        with contextlib.suppress(OSError):  # closed during shutdown
            self._wake_w.send_bytes(b"x")

    @staticmethod
    def _kill(run: _Running, sig: int) -> None:
        pid = run.process.pid
        if pid is None:
            return
        try:
            os.killpg(pid, sig)  # the job called setsid(): its pid is its group id
        except (ProcessLookupError, PermissionError):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, sig)

    def _launch_pending(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                if len(self._running) + len(self._starting) >= self.max_workers:
                    return
                if not self._pending:
                    return
                job = self._pending.popleft()
                self._starting[job.job_id] = False
            reader, writer = self._ctx.Pipe(duplex=False)
            proc = self._ctx.Process(
                target=_child_main,
                args=(
                    self._target,
                    job.job_id,
                    job.kind,
                    job.payload,
                    writer,
                    os.getpid(),
                    self.memory_mb,
                ),
                name=f"bioplan-job-{job.job_id}",
                daemon=False,  # a sweep may start its own worker pool
            )
            try:
                # Outside the lock: the first start waits for the fork server to import.
                ensure_forkserver()
                proc.start()
            except Exception as exc:
                logger.exception("cannot start job %d", job.job_id)
                reader.close()
                writer.close()
                with self._lock:
                    self._starting.pop(job.job_id, None)
                self._emit(JobEvent(job.job_id, "failed", error=f"cannot start job process: {exc}"))
                continue
            writer.close()
            run = _Running(job.job_id, proc, reader)
            with self._lock:
                run.cancel_requested = self._starting.pop(job.job_id, False)
                self._running[job.job_id] = run
            if run.cancel_requested:
                self._kill(run, signal.SIGTERM)
            else:
                self._emit(JobEvent(job.job_id, "started", progress=0.0, message="running"))

    def _read(self, run: _Running) -> None:
        try:
            msg = run.conn.recv()
        except (EOFError, OSError):
            run.conn_open = False
            return
        tag = msg[0]
        if tag == "progress":
            if not run.cancel_requested:
                self._emit(_progress_event(run.job_id, msg[1]))
        elif tag == "result":
            run.result, run.has_outcome = msg[1], True
        elif tag == "error":
            run.error, run.has_outcome = msg[1], True
        elif tag == "log":
            run.log.extend(list(msg[1]))

    def _finish(self, run: _Running) -> None:
        while run.conn_open and run.conn.poll():
            self._read(run)
        run.process.join(timeout=5)
        code = run.process.exitcode
        run.conn.close()
        with self._lock:
            self._running.pop(run.job_id, None)
        if run.timed_out and run.result is None:
            limit = f"{self.time_limit:g}"
            self._emit_end(
                run,
                JobEvent(
                    run.job_id,
                    "failed",
                    error=f"time limit: the job ran longer than {limit} s "
                    "(BIOPLAN_JOB_TIME_LIMIT_S) and was stopped",
                ),
            )
        elif run.cancel_requested and run.result is None:
            self._emit_end(
                run, JobEvent(run.job_id, "cancelled", message="cancelled while running")
            )
        elif run.result is not None:
            self._emit_end(run, JobEvent(run.job_id, "succeeded", progress=1.0, result=run.result))
        elif run.error is not None:
            self._emit_end(run, JobEvent(run.job_id, "failed", error=run.error))
        else:
            self._emit_end(
                run,
                JobEvent(
                    run.job_id,
                    "failed",
                    error=f"job process exited with code {code} before reporting a result",
                ),
            )
        with contextlib.suppress(ValueError):  # still running after the join timeout
            run.process.close()

    def _emit_end(self, run: _Running, event: JobEvent) -> None:
        """Report a job's final event with its log."""
        self._emit(dataclasses.replace(event, log=run.log.lines()))

    def _stop_overdue(self, runs: list[_Running]) -> None:
        """Stop (the whole process group, pools included) every job over the time limit."""
        if self.time_limit is None:
            return
        now = time.monotonic()
        for run in runs:
            if not run.timed_out and now - run.started > self.time_limit:
                run.timed_out = run.cancel_requested = True
                self._kill(run, signal.SIGKILL)

    def _monitor(self) -> None:
        from multiprocessing.connection import wait

        try:
            ensure_forkserver()  # import the science packages once, now
        except Exception:  # pragma: no cover - reported when a job starts
            logger.exception("cannot start the fork server")
        while not self._stop.is_set():
            try:
                self._launch_pending()
                with self._lock:
                    runs = list(self._running.values())
                self._stop_overdue(runs)
                handles: dict[Any, tuple[str, _Running | None]] = {self._wake_r: ("wake", None)}
                for run in runs:
                    if run.conn_open:
                        handles[run.conn] = ("conn", run)
                    handles[run.process.sentinel] = ("exit", run)
                for ready in wait(list(handles), timeout=1.0):
                    what, which = handles[ready]
                    if what == "wake":
                        while self._wake_r.poll():
                            self._wake_r.recv_bytes()
                    elif what == "conn" and which is not None:
                        self._read(which)
                for ready in wait([h for h, (w, _) in handles.items() if w == "exit"], timeout=0):
                    _, which = handles[ready]
                    if which is not None:
                        self._finish(which)
            except Exception:  # pragma: no cover - keep the monitor alive whatever happens
                logger.exception("job monitor error")
                time.sleep(0.5)


# ------------------------------------------------------------------------------------- dask


class _TaskOutcome(TypedDict):
    """What a Dask task returns: the job function's output and the job's log lines."""

    output: JobResult
    log: list[str]


class _Future(Protocol):
    """The part of a ``distributed.Future`` the runner uses."""

    @property
    def key(self) -> object: ...

    @property
    def status(self) -> str: ...

    def result(self) -> _TaskOutcome: ...

    def exception(self) -> BaseException | None: ...

    def cancel(self) -> object: ...


def _distributed() -> ModuleType:
    """The ``distributed`` module, imported on first use (an optional dependency)."""
    import distributed

    return distributed


class _ThisThread(logging.Filter):
    """Keeps the records of the thread that made it: a Dask worker runs several tasks in
    threads of one process, and each job's log must hold its own records only."""

    def __init__(self) -> None:
        super().__init__()
        self.thread = threading.get_ident()

    def filter(self, record: logging.LogRecord) -> bool:
        return record.thread == self.thread


def _dask_entry(
    target: Target,
    job_id: int,
    kind: str,
    payload: Payload,
    topic: str,
    cancel_name: str,
) -> _TaskOutcome:
    """Body of a Dask task: report through worker events, stop when the cancel event is set.

    The job's log (``app.logs.LogTail``, this thread's records) travels as the local runner's
    does: new lines with each progress event, the rest with the outcome (``{"output", "log"}``
    returned, or :class:`JobFailed` ``(error, lines)``).
    """
    distributed = _distributed()
    worker = distributed.get_worker()
    worker.log_event(topic, {"job": job_id, "type": "started"})
    cancel = distributed.Event(cancel_name)
    last = [0.0]
    tail = LogTail()
    tail.addFilter(_ThisThread())

    def progress(update: Progress) -> None:
        now = time.monotonic()
        if update.fraction < 1.0 and now - last[0] < 0.2:
            return
        last[0] = now
        if cancel.is_set():
            raise JobCancelled(f"job {job_id} cancelled")
        detail = update.to_dict()
        worker.log_event(topic, {"job": job_id, "type": "progress", "detail": detail,
                                 "log": tail.take()})  # fmt: skip

    try:
        with capture(tail):
            output = target(kind, payload, progress)
        return {"output": output, "log": tail.take()}
    except JobCancelled:
        raise
    except BaseException as exc:
        # Exceptions of the science packages may not unpickle on the client; send a string.
        error = describe_error(exc)
        lines = [*tail.take(), f"{time.strftime('%H:%M:%S')} ERROR bioplan: job failed: {error}"]
        raise JobFailed(error, lines) from None


@dataclass
class _DaskJob:
    job_id: int
    future: _Future
    cancel_name: str
    cancel_requested: bool = False
    log: LogTail = field(default_factory=LogTail)


class DaskRunner(JobRunner):
    """Jobs as tasks on a Dask ``distributed`` cluster.

    Args:
        address: scheduler address, ``tcp://HOST:PORT``.
        target: job entry point, importable on the workers (default
            ``app.jobs.tasks.run_task``).
        timeout: seconds to wait for the scheduler at start.
    """

    def __init__(self, address: str, *, target: Target | None = None, timeout: float = 10.0):
        self.address = address
        self.executor = f"dask://{address.split('://', 1)[-1]}"
        self._target = target or _default_target()
        self._timeout = timeout
        self._client: Any = None  # a distributed.Client once started (its stubs are partial)
        self._sink: EventSink | None = None
        self._jobs: dict[int, _DaskJob] = {}
        self._lock = threading.Lock()
        self._topic = f"bioplan-jobs-{uuid.uuid4().hex}"
        self._closing = False

    def start(self, sink: EventSink) -> None:
        self._sink = sink
        self._client = _distributed().Client(
            self.address, timeout=self._timeout, set_as_default=False
        )
        self._client.subscribe_topic(self._topic, self._on_event)

    def submit(self, job_id: int, kind: str, payload: Payload) -> None:
        key = f"bioplan-job-{job_id}-{uuid.uuid4().hex[:8]}"
        if kind == "sweep":
            # Child tasks: the sweep job submits one task per cell to this cluster (Dask worker
            # processes are daemonic and cannot start a pool of their own).
            payload = {**payload, "workers": 1, "cell_executor": "dask"}
        # Large inputs (raw recordings) go to the cluster once, not inside the task graph.
        [data] = self._client.scatter([payload], hash=False)
        future = self._client.submit(
            _dask_entry,
            self._target,
            job_id,
            kind,
            data,
            self._topic,
            f"{key}-cancel",
            key=key,
            pure=False,
        )
        with self._lock:
            self._jobs[job_id] = _DaskJob(job_id, future, f"{key}-cancel")
        future.add_done_callback(self._on_done)

    def cancel(self, job_id: int) -> bool:
        with self._lock:
            job = self._jobs.get(job_id)
            if job is None:
                return False
            job.cancel_requested = True
        self._cancel_on_cluster(job)
        return True

    def shutdown(self) -> None:
        self._closing = True
        with self._lock:
            jobs = list(self._jobs.values())
            self._jobs.clear()
        for job in jobs:
            try:
                self._cancel_on_cluster(job)
            except Exception:  # pragma: no cover - the scheduler may be gone
                logger.warning("could not cancel job %d on the cluster", job.job_id)
        if self._client is not None:
            with contextlib.suppress(ValueError):
                self._client.unsubscribe_topic(self._topic)
            self._client.close()
        self._sink = None

    def _cancel_on_cluster(self, job: _DaskJob) -> None:
        _distributed().Event(job.cancel_name, client=self._client).set()
        job.future.cancel()

    def info(self) -> dict[str, object]:
        workers = None
        try:
            workers = len(self._client.scheduler_info(n_workers=-1)["workers"])
        except Exception:  # pragma: no cover - scheduler unreachable
            workers = None
        with self._lock:
            return {
                "executor": self.executor,
                "workers": workers,
                "running": len(self._jobs),
                "queued": None,
            }

    # callbacks ------------------------------------------------------------------------------

    def _emit(self, event: JobEvent) -> None:
        sink = self._sink
        if sink is not None and not self._closing:
            sink(event)

    def _on_event(self, event: tuple[float, _TaskMessage]) -> None:
        _, msg = event
        job_id = int(msg["job"])
        with self._lock:
            job = self._jobs.get(job_id)
        if job is None or job.cancel_requested:
            return
        job.log.extend(list(msg.get("log") or ()))
        if msg["type"] == "started":
            self._emit(JobEvent(job_id, "started", progress=0.0, message="running"))
        elif msg["type"] == "progress":
            self._emit(_progress_event(job_id, msg["detail"]))

    def _on_done(self, future: _Future) -> None:
        with self._lock:
            match = [j for j in self._jobs.values() if j.future.key == future.key]
            if not match:
                return
            job = match[0]
            del self._jobs[job.job_id]
        if future.status == "finished":
            done = future.result()
            job.log.extend(list(done.get("log") or ()))
            self._end(job, JobEvent(job.job_id, "succeeded", progress=1.0, result=done["output"]))
            return
        if job.cancel_requested or future.status == "cancelled":
            self._end(job, JobEvent(job.job_id, "cancelled", message="cancelled"))
            return
        exc = future.exception()
        if isinstance(exc, JobCancelled):
            self._end(job, JobEvent(job.job_id, "cancelled", message="cancelled"))
            return
        if isinstance(exc, JobFailed) and len(exc.args) == 2:
            job.log.extend([str(line) for line in exc.args[1]])
            error = str(exc.args[0])
        else:  # the worker died, or the task could not run at all
            error = describe_error(exc)
        self._end(job, JobEvent(job.job_id, "failed", error=error))

    def _end(self, job: _DaskJob, event: JobEvent) -> None:
        """Report a job's final event with its log (as the local runner does)."""
        self._emit(dataclasses.replace(event, log=job.log.lines()))


def make_runner(
    executor: str,
    *,
    max_workers: int = 2,
    time_limit: float | None = None,
    memory_mb: float | None = None,
) -> JobRunner:
    """The runner for a ``Settings.executor`` value (``local`` or ``dask://HOST:PORT``);
    ``time_limit`` [s] and ``memory_mb`` apply to the local executor (a Dask cluster has its
    own: its workers' ``memory_limit``)."""
    if executor == "local":
        return LocalRunner(max_workers, time_limit=time_limit, memory_mb=memory_mb)
    address = executor.replace("dask://", "tcp://", 1)
    return DaskRunner(address)
