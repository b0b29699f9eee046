"""Job targets for runner tests: top-level functions, picklable by reference."""

from __future__ import annotations

import os
import time
from typing import Any

from app.jobs.runner import Progress


def target(kind: str, payload: dict[str, Any], progress: Progress) -> dict[str, Any]:
    """Behaves as ``kind`` says: ``echo``, ``count``, ``sleep``, ``fail``, ``crash``."""
    if kind == "echo":
        return {"result": {"echo": payload, "pid": os.getpid()}}
    if kind == "count":
        n = int(payload["n"])
        for i in range(n):
            progress((i + 1) / n, f"step {i + 1} of {n}")
            time.sleep(payload.get("dt", 0.03))
        return {"result": {"steps": n}}
    if kind == "sleep":
        # Reports its pid first, so a test can check the process is gone after a cancel.
        progress(0.0, f"pid {os.getpid()}")
        deadline = time.monotonic() + float(payload["seconds"])
        while time.monotonic() < deadline:
            time.sleep(0.05)
            progress(0.5, f"pid {os.getpid()}")
        return {"result": {"slept": payload["seconds"]}}
    if kind == "fail":
        raise ValueError(f"bad input: {payload.get('why', 'no reason')}")
    if kind == "crash":
        os._exit(7)
    raise KeyError(kind)
