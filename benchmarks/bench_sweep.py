"""A sweep on the local process pool and on a 2-worker Dask LocalCluster, side by side.

Run:  .venv/bin/python benchmarks/bench_sweep.py [--durations 0.8,1.0,1.2] [--payloads 0,4,8]
          [--methods all] [--repeats 3] [--full] [--json]

Both executors run the same grid with the same seeds, one after the other in each repeat (so a
change in the machine's load hits both): ``run_sweep(workers=2)`` (a spawned pool of two
processes) and ``run_sweep(executor="dask://...")`` on ``LocalCluster(n_workers=2,
threads_per_worker=1, processes=True)`` (one task per cell). The cluster is started once, before
timing (a service's cluster is already running). Reported: median wall time of each, their
ratio (target: Dask within 1.3x of the local pool, issue 12), and the cells each Dask worker
ran. ``--full`` adds one run of each on the 10x10 grid of the issue (durations 0.5..2.0 s,
payloads 0..20 kg) with every method.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

FULL_DURATIONS = [0.5, 0.65, 0.8, 0.95, 1.1, 1.25, 1.4, 1.55, 1.7, 2.0]
FULL_PAYLOADS = [0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 14.0, 17.0, 20.0]


def _floats(text: str) -> list[float]:
    return [float(x) for x in text.split(",") if x.strip()]


def one_pair(robot: Any, address: str, grid: dict[str, Any]) -> dict[str, Any]:
    """One local-pool run and one Dask run of ``grid``; wall times [s] and Dask's placement."""
    from app.simulation import run_sweep

    started = time.perf_counter()
    local = run_sweep(robot=robot, workers=2, **grid)
    local_s = time.perf_counter() - started
    started = time.perf_counter()
    dask = run_sweep(robot=robot, executor=address, **grid)
    dask_s = time.perf_counter() - started
    same = [a.status for a in local.cells] == [b.status for b in dask.cells]
    return {
        "local_s": local_s,
        "dask_s": dask_s,
        "cells": len(local.cells),
        "same_statuses": same,
        "cells_per_worker": dask.conditions["cells_per_worker"],
        "pool_note": local.conditions["pool_note"],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robot", default="curtain_wall_6dof")
    parser.add_argument("--durations", default="0.8,1.0,1.2")
    parser.add_argument("--payloads", default="0,4,8")
    parser.add_argument("--methods", default="all", help="comma-separated, or all")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--full", action="store_true", help="also one 10x10 run of each")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()

    from distributed import LocalCluster

    from app.names import METHODS
    from app.planning import load_robot

    methods = list(METHODS) if args.methods == "all" else args.methods.split(",")
    robot = load_robot(args.robot)
    grid = {
        "durations": _floats(args.durations),
        "payloads": _floats(args.payloads),
        "methods": methods,
        "seed": 0,
    }
    out: dict[str, Any] = {"robot": args.robot, "methods": methods, "grid": grid}
    with LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=":0",  # no fixed port: other clusters may run
        silence_logs=40,
    ) as cluster:
        address = cluster.scheduler_address.replace("tcp://", "dask://")
        runs = [one_pair(robot, address, grid) for _ in range(args.repeats)]
        local = statistics.median(r["local_s"] for r in runs)
        dask = statistics.median(r["dask_s"] for r in runs)
        out["repeated"] = {
            "runs": runs,
            "local_median_s": local,
            "dask_median_s": dask,
            "ratio": dask / local,
        }
        if args.full:
            full = {**grid, "durations": FULL_DURATIONS, "payloads": FULL_PAYLOADS}
            pair = one_pair(robot, address, full)
            pair["ratio"] = pair["dask_s"] / pair["local_s"]
            out["full_10x10"] = pair
    if args.json:
        print(json.dumps(out))
        return 0
    rep = out["repeated"]
    cells = len(grid["durations"]) * len(grid["payloads"])
    print(
        f"{args.robot}, {cells} cells, methods {','.join(methods)}, median of {args.repeats}: "
        f"local pool {rep['local_median_s']:.1f} s, Dask LocalCluster {rep['dask_median_s']:.1f}"
        f" s, ratio {rep['ratio']:.2f} (target <= 1.3)"
    )
    print("cells per Dask worker (last run):", rep["runs"][-1]["cells_per_worker"])
    if "full_10x10" in out:
        f = out["full_10x10"]
        print(
            f"10x10 once: local pool {f['local_s']:.1f} s, Dask {f['dask_s']:.1f} s, "
            f"ratio {f['ratio']:.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
