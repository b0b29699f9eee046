"""Security finding 10 (i): jobs had no memory limit (a simulation took +3 GB). A local job
process runs under ``RLIMIT_AS`` (``BIOPLAN_JOB_MEMORY_MB`` beyond what it starts with): a job
past it fails with "ran out of memory", and the runner goes on running jobs."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from app.jobs.runner import LocalRunner
from app.names import TERMINAL_JOB_STATES as TERMINAL
from app.progress import ProgressFn
from tests.utils.jobs import Collector, target

LIMIT_MB = 64


def hog(kind: str, payload: dict[str, Any], progress: ProgressFn) -> dict[str, Any]:
    """``hog``: hold ``mb`` megabytes (touched); anything else: ``tests.utils.jobs.target``."""
    if kind != "hog":
        return target(kind, payload, progress)
    block = bytearray(int(payload["mb"]) * 1024 * 1024)
    block[::4096] = b"x" * len(block[::4096])
    return {"result": {"held_mb": len(block) // (1024 * 1024)}}


@pytest.fixture
def runner() -> Iterator[tuple[LocalRunner, Collector]]:
    sink = Collector()
    r = LocalRunner(1, target=hog, preload=(), memory_mb=LIMIT_MB)
    r.start(sink)
    yield r, sink
    r.shutdown()


def test_a_job_past_its_memory_limit_fails_and_the_runner_goes_on(
    runner: tuple[LocalRunner, Collector],
) -> None:
    r, sink = runner
    r.submit(1, "hog", {"mb": 16 * LIMIT_MB})
    failed = sink.wait_for(1, TERMINAL)
    assert failed.type == "failed"
    assert failed.error is not None
    assert "ran out of memory" in failed.error
    assert f"BIOPLAN_JOB_MEMORY_MB={LIMIT_MB}" in failed.error
    # Within the limit, a job runs; the next job runs as before.
    r.submit(2, "hog", {"mb": LIMIT_MB // 4})
    done = sink.wait_for(2, TERMINAL)
    assert done.type == "succeeded", done.error
    r.submit(3, "echo", {"x": 1})
    assert sink.wait_for(3, TERMINAL).type == "succeeded"


def test_without_a_limit_the_same_job_runs() -> None:
    sink = Collector()
    r = LocalRunner(1, target=hog, preload=(), memory_mb=None)
    r.start(sink)
    try:
        r.submit(1, "hog", {"mb": 4 * LIMIT_MB})
        done = sink.wait_for(1, TERMINAL)
        assert done.type == "succeeded", done.error
    finally:
        r.shutdown()
