"""Job targets for runner tests: top-level functions, picklable by reference."""

from __future__ import annotations

import os
import time
from typing import Any

from app.errors import BioPlanError
from app.progress import ProgressFn, report


def target(kind: str, payload: dict[str, Any], progress: ProgressFn) -> dict[str, Any]:
    """Behaves as ``kind`` says: ``echo``, ``count``, ``sleep``, ``fail``, ``crash``."""
    if kind == "echo":
        return {"result": {"echo": payload, "pid": os.getpid()}}
    if kind == "count":
        n = int(payload["n"])
        for i in range(n):
            report(progress, "count", i + 1, n, message=f"step {i + 1} of {n}")
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
    if kind == "crash":
        os._exit(7)
    raise KeyError(kind)


def service_target(kind: str, payload: dict[str, Any], progress: ProgressFn) -> dict[str, Any]:
    """For JobService tests: real job kinds, behaviour chosen by ``payload["behave"]``."""
    out = target(payload["behave"], payload, progress)
    if payload["behave"] == "count":
        # What a plan job returns: the CLI JSON and arrays for plots.
        import numpy as np

        out["arrays"] = {"t": np.linspace(0.0, 1.0, int(payload["n"]))}
    return out
