"""Job targets and event sinks for runner and job-service tests.

Targets are top-level functions here (pickled by reference into job processes).
"""

from __future__ import annotations

import os
import queue
import time
from typing import Any

from app.errors import BioPlanError
from app.jobs.runner import EventSink, JobEvent, JobRunner
from app.logs import get_logger
from app.progress import ProgressFn, report


def target(kind: str, payload: dict[str, Any], progress: ProgressFn) -> dict[str, Any]:
    """Behaves as ``kind`` says: ``echo``, ``count``, ``sleep``, ``fail``, ``crash``, ``bug``."""
    if kind == "echo":
        return {"result": {"echo": payload, "pid": os.getpid()}}
    if kind == "count":
        n = int(payload["n"])
        for i in range(n):
            report(progress, "count", i + 1, n, best=float(n - i), message=f"step {i + 1} of {n}")
            time.sleep(payload.get("dt", 0.03))
        return {"result": {"steps": n}}
    if kind == "sleep":
        # Reports its pid first, so a test can check the process is gone after a cancel.
        report(progress, "sleep", 0, 2, message=f"pid {os.getpid()}")
        deadline = time.monotonic() + float(payload["seconds"])
        beat = payload.get("heartbeat")
        while time.monotonic() < deadline:
            time.sleep(0.05)
            if beat:  # evidence, outside the runner, that the work is still going on
                with open(beat, "w") as fh:
                    fh.write(repr(time.monotonic()))
            report(progress, "sleep", 1, 2, message=f"pid {os.getpid()}")
        return {"result": {"slept": payload["seconds"]}}
    if kind == "fail":
        raise BioPlanError(f"bad input: {payload.get('why', 'no reason')}")
    if kind == "bug":
        raise ValueError("a bug that raises ValueError")
    if kind == "crash":
        os._exit(7)
    raise KeyError(kind)


def log_target(kind: str, payload: dict[str, Any], progress: ProgressFn) -> dict[str, Any]:
    """Logs ``n`` INFO lines (and as many DEBUG ones, not kept) on the planning logger,
    reporting progress every ``every`` lines; fails at the end when ``fail`` is given."""
    log = get_logger("planning")
    n, every = int(payload["n"]), int(payload.get("every", 50))
    for i in range(n):
        log.info("line %d of %d", i, n)
        log.debug("detail %d", i)
        if (i + 1) % every == 0:
            report(progress, "log", i + 1, n)
            time.sleep(0.03)  # past the progress throttle: every report is sent
    if payload.get("sleep"):
        time.sleep(float(payload["sleep"]))
    if payload.get("fail"):
        raise BioPlanError(str(payload["fail"]))
    return {"result": {"n": n}}


def service_target(kind: str, payload: dict[str, Any], progress: ProgressFn) -> dict[str, Any]:
    """For JobService tests: real job kinds, behaviour chosen by ``payload["behave"]``."""
    out = target(payload["behave"], payload, progress)
    if payload["behave"] == "count":
        # What a plan job returns: the CLI JSON and arrays for plots.
        import numpy as np

        out["arrays"] = {"t": np.linspace(0.0, 1.0, int(payload["n"]))}
    return out


class Collector:
    """An event sink that lets a test wait for events."""

    def __init__(self) -> None:
        self.events: queue.Queue[JobEvent] = queue.Queue()
        self.seen: list[JobEvent] = []

    def __call__(self, event: JobEvent) -> None:
        self.events.put(event)

    def wait_for(self, job_id: int, types: set[str], timeout: float = 60.0) -> JobEvent:
        deadline = time.monotonic() + timeout
        for ev in self.seen:
            if ev.job_id == job_id and ev.type in types:
                return ev
        while time.monotonic() < deadline:
            try:
                ev = self.events.get(timeout=0.1)
            except queue.Empty:
                continue
            self.seen.append(ev)
            if ev.job_id == job_id and ev.type in types:
                return ev
        raise AssertionError(f"job {job_id}: no {types} event within {timeout} s")

    def of(self, job_id: int) -> list[JobEvent]:
        return [e for e in self.seen if e.job_id == job_id]


class RecordingRunner(JobRunner):
    """A runner that only records what it is asked to do (for restart tests)."""

    executor = "record"

    def __init__(self) -> None:
        self.submitted: list[tuple[int, str]] = []
        self.cancelled: list[int] = []

    def start(self, sink: EventSink) -> None:
        self.sink = sink

    def submit(self, job_id: int, kind: str, payload: dict[str, Any]) -> None:
        self.submitted.append((job_id, kind))

    def cancel(self, job_id: int) -> bool:
        self.cancelled.append(job_id)
        return True

    def shutdown(self) -> None:
        pass

    def info(self) -> dict[str, Any]:
        return {"executor": self.executor, "workers": 0, "running": 0, "queued": 0}
