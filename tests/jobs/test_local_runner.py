"""LocalRunner: a process per job, events back to the API process, bounded concurrency, cancel."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator

import pytest

from app.jobs.runner import LocalRunner
from app.names import TERMINAL_JOB_STATES as TERMINAL
from tests.utils.jobs import Collector, target


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie still answers kill(0); it has stopped running though.
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split()[2] != "Z"
    except FileNotFoundError:
        return False


@pytest.fixture(scope="module")
def runner() -> Iterator[tuple[LocalRunner, Collector]]:
    sink = Collector()
    r = LocalRunner(2, target=target, preload=())
    r.start(sink)
    yield r, sink
    r.shutdown()


def test_result_comes_back_from_another_process(runner: tuple[LocalRunner, Collector]) -> None:
    r, sink = runner
    r.submit(1, "echo", {"x": [1, 2, 3]})
    assert sink.wait_for(1, {"started"}).type == "started"
    done = sink.wait_for(1, TERMINAL)
    assert done.type == "succeeded"
    assert done.result is not None
    assert done.result["result"]["echo"] == {"x": [1, 2, 3]}
    assert done.result["result"]["pid"] != os.getpid()


def test_progress_is_reported_in_order(runner: tuple[LocalRunner, Collector]) -> None:
    r, sink = runner
    r.submit(2, "count", {"n": 5, "dt": 0.05})
    assert sink.wait_for(2, TERMINAL).type == "succeeded"
    fractions = [e.progress for e in sink.of(2) if e.type == "progress"]
    assert fractions, "no progress events"
    assert fractions == sorted(fractions)
    assert fractions[-1] == pytest.approx(1.0)


def test_failure_and_crash_are_reported(runner: tuple[LocalRunner, Collector]) -> None:
    r, sink = runner
    r.submit(3, "fail", {"why": "duration is negative"})
    r.submit(4, "crash", {})
    failed = sink.wait_for(3, TERMINAL)
    assert failed.type == "failed"
    assert failed.error == "bad input: duration is negative"
    crashed = sink.wait_for(4, TERMINAL)
    assert crashed.type == "failed"
    assert crashed.error is not None and "code 7" in crashed.error


def test_cancel_running_job_stops_its_process(runner: tuple[LocalRunner, Collector]) -> None:
    r, sink = runner
    r.submit(5, "sleep", {"seconds": 60})
    first = sink.wait_for(5, {"progress"})
    pid = int(first.message.split()[-1])
    assert _alive(pid)
    t0 = time.monotonic()
    assert r.cancel(5)
    assert sink.wait_for(5, TERMINAL).type == "cancelled"
    assert time.monotonic() - t0 < 5
    deadline = time.monotonic() + 5
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(pid)
    assert not r.cancel(5)  # no longer known


def test_concurrency_is_bounded_and_queued_jobs_cancel(
    runner: tuple[LocalRunner, Collector],
) -> None:
    r, sink = runner
    for job_id in (10, 11, 12):
        r.submit(job_id, "sleep", {"seconds": 0.8})
    time.sleep(0.4)
    info = r.info()
    assert info["running"] == 2 and info["queued"] == 1
    assert r.cancel(12)
    assert sink.wait_for(12, TERMINAL).type == "cancelled"
    assert all(e.type != "started" for e in sink.of(12))
    for job_id in (10, 11):
        assert sink.wait_for(job_id, TERMINAL).type == "succeeded"


def test_a_job_over_the_time_limit_is_stopped_and_failed() -> None:
    """Issue 14 item 8: no job had a time limit. With one, an overrunning job's process group
    is killed and the job fails with "time limit"; a job within it is untouched."""
    sink = Collector()
    r = LocalRunner(2, target=target, preload=(), time_limit=1.5)
    r.start(sink)
    try:
        r.submit(1, "sleep", {"seconds": 120})
        r.submit(2, "echo", {"x": 1})
        pid = int(sink.wait_for(1, {"progress"}).message.split()[-1])
        ended = sink.wait_for(1, TERMINAL, timeout=120)
        assert ended.type == "failed" and ended.error is not None
        assert ended.error.startswith("time limit:") and "BIOPLAN_JOB_TIME_LIMIT_S" in ended.error
        assert sink.wait_for(2, TERMINAL).type == "succeeded"
        deadline = time.monotonic() + 30
        while _alive(pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(pid)
    finally:
        r.shutdown()
