"""Benchmarks of app.simulation (targets from the simulation issue).

1. One 1-second tracking simulation of ``curtain_wall_6dof`` at 1 kHz (1001 samples, the
   standard quintic curl, 4 kg panel): the whole ``simulate_tracking`` call (model compile with
   payload and armature, gains, batched Pinocchio feed-forward, ``mujoco.rollout``, metrics).
   Median of >= 5 runs; target < 50 ms. The Python-loop backend is timed beside it.
2. A 10 x 10 sweep (durations 0.5-2.0 s x payloads 0-20 kg, objective abs_work): plan + simulate
   both trajectories for each cell in a 2-process pool, modest PSO budget per cell (stated);
   target < 60 s on a 2-core machine.

Run: ``.venv/bin/python benchmarks/bench_simulation.py [--runs 7] [--skip-sweep] [--grid 10]``.
Prints one JSON object (the numbers) after a readable summary on stderr.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from typing import Any

import numpy as np


def bench_tracking(runs: int = 7) -> dict[str, Any]:
    """Median wall time of one 1 s, 1 kHz tracking simulation of curtain_wall_6dof."""
    from app.planning.profiles import quintic
    from app.planning.robots import load_robot
    from app.simulation import simulate_tracking

    robot = load_robot("curtain_wall_6dof")
    traj = quintic(robot.default_start, robot.default_goal, 1.0, n_samples=1001)
    out: dict[str, Any] = {"samples": 1001, "timestep_s": 1e-3, "runs": runs}
    for backend in ("rollout", "loop"):
        simulate_tracking(robot, traj, backend=backend)  # warm-up: imports, caches
        times = []
        for _ in range(runs):
            t0 = time.perf_counter()
            res = simulate_tracking(robot, traj, backend=backend)
            times.append(time.perf_counter() - t0)
        out[backend] = {
            "median_ms": 1e3 * statistics.median(times),
            "min_ms": 1e3 * min(times),
            "max_tracking_error_deg": float(np.degrees(res.tracking_max.max())),
        }
    out["target_ms"] = 50.0
    out["pass"] = out["rollout"]["median_ms"] < 50.0
    return out


def bench_sweep(grid: int = 10, workers: int = 2) -> dict[str, Any]:
    """Wall time of a grid x grid sweep (plan + simulate every cell) in a process pool."""
    from app.planning.robots import load_robot
    from app.simulation import run_sweep

    robot = load_robot("curtain_wall_6dof")
    durations = [round(float(d), 4) for d in np.linspace(0.5, 2.0, grid)]
    payloads = [round(float(p), 4) for p in np.linspace(0.0, 20.0, grid)]
    t0 = time.perf_counter()
    res = run_sweep(
        robot=robot,
        durations=durations,
        payloads=payloads,
        objectives=["abs_work"],
        seed=0,
        workers=workers,
    )
    seconds = time.perf_counter() - t0
    statuses: dict[str, int] = {}
    for cell in res.cells:
        statuses[cell.status] = statuses.get(cell.status, 0) + 1
    return {
        "cells": len(res.cells),
        "workers": workers,
        "seconds": seconds,
        "particles": res.conditions["particles"],
        "iterations": res.conditions["iterations"],
        "statuses": statuses,
        "abs_work_counts": res.counts("abs_work", "abs_work"),
        "peak_power_counts": res.counts("abs_work", "peak_power"),
        "target_s": 60.0,
        "pass": seconds < 60.0,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7, help="runs of the tracking benchmark")
    parser.add_argument("--grid", type=int, default=10, help="sweep grid size (grid x grid)")
    parser.add_argument("--workers", type=int, default=2, help="sweep processes")
    parser.add_argument("--skip-sweep", action="store_true", help="only the tracking benchmark")
    args = parser.parse_args(argv)
    result: dict[str, Any] = {"command": " ".join([sys.executable, *sys.argv])}
    result["tracking"] = bench_tracking(args.runs)
    tr = result["tracking"]
    print(
        f"tracking 1 s @ 1 kHz, curtain_wall_6dof: rollout median "
        f"{tr['rollout']['median_ms']:.1f} ms, loop median {tr['loop']['median_ms']:.1f} ms "
        f"(target < 50 ms)",
        file=sys.stderr,
    )
    if not args.skip_sweep:
        result["sweep"] = bench_sweep(args.grid, args.workers)
        sw = result["sweep"]
        print(
            f"sweep {args.grid}x{args.grid}: {sw['seconds']:.1f} s on {sw['workers']} workers "
            f"(PSO {sw['particles']}x{sw['iterations']} per cell; target < 60 s), "
            f"statuses {sw['statuses']}",
            file=sys.stderr,
        )
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
