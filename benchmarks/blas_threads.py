"""casadi's OpenBLAS on one thread (``app.planning.blas_threads``, the default) against one
thread per core (``OPENBLAS_NUM_THREADS`` = the core count, OpenBLAS's own default).

Run: ``.venv/bin/python benchmarks/blas_threads.py [--runs 3] [--cases robot:objective,...]
[--converge both|off|on]``: the plans of ``benchmarks/jit_cache.py`` (each in its own process,
the compiled dynamics cache warm), CPU and wall seconds, medians of ``runs``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.jit_cache import DEFAULT_CASES, run_plan


def _run(case: str, converge: bool, threads: str | None) -> dict[str, Any]:
    """One plan with casadi's OpenBLAS on ``threads`` threads (None: BioPlan's default, one)."""
    return run_plan(case, converge, {"OPENBLAS_NUM_THREADS": threads, "OMP_NUM_THREADS": None})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="runs per variant (median)")
    parser.add_argument("--cases", default=DEFAULT_CASES, help="robot:objective,...")
    parser.add_argument("--converge", choices=("both", "off", "on"), default="both")
    args = parser.parse_args()
    cores = str(os.cpu_count() or 1)
    print(f"| case | converge | one thread: CPU / wall | {cores} threads: CPU / wall | load |")
    print("|---|---|---|---|---|")
    for case in args.cases.split(","):
        for converge in {"both": [False, True], "off": [False], "on": [True]}[args.converge]:
            _run(case, converge, None)  # the compiled dynamics cached
            per: dict[str, list[dict[str, Any]]] = {"one": [], "cores": []}
            for _ in range(args.runs):
                per["one"].append(_run(case, converge, None))
                per["cores"].append(_run(case, converge, cores))
            cells = []
            for rows in per.values():
                cpu = statistics.median(r["cpu"] + r["compiler"] for r in rows)
                wall = statistics.median(r["wall"] for r in rows)
                cells.append(f"{cpu:.2f} / {wall:.2f} s")
            values = {
                json.dumps(r["values"], sort_keys=True) for rows in per.values() for r in rows
            }
            loads = [r["load"] for rows in per.values() for r in rows]
            same = "" if len(values) == 1 else " (optima differ!)"
            print(
                f"| {case} | {'on' if converge else 'off'} | {' | '.join(cells)}{same} | "
                f"{min(loads):.1f}-{max(loads):.1f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
