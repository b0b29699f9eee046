"""Planner speed: in-process planning, `bioplan plan` end to end, and our PSO vs pyswarms.

Run: ``.venv/bin/python benchmarks/bench_planner.py [--runs 5] [--json]``.

1. ``plan()`` on ``curtain_wall_6dof``, 40 particles x 100 iterations, 100 time samples
   (40 x 100 x 100 = 400 k inverse-dynamics evaluations), in-process, median of ``runs``
   (target < 0.6 s).
2. ``bioplan plan --method quintic,paper --json`` (the paper's method alone, as before the
   optimal-control methods; ``bench_optimal.py`` times all of them) from process start to JSON,
   median of ``runs`` (target < 1.2 s).
3. The planner's own PSO problem (same bounds, same batched cost and constraints) through our
   PSO and pyswarms' GlobalBestPSO, same budget, side by side (``bench_pso.compare``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

ROOT = Path(__file__).resolve().parents[1]


def json_command_seconds(cmd: list[str], runs: int) -> list[float]:
    """Wall seconds of each of ``runs`` runs of a command that must print JSON, start to end."""
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
        times.append(time.perf_counter() - t0)
        json.loads(proc.stdout)
    return times


def bench_plan(runs: int) -> dict[str, Any]:
    from app.planning.planner import plan
    from app.planning.robots import load_robot

    robot = load_robot("curtain_wall_6dof")
    plan(robot, duration=1.0, particles=8, iterations=3)  # warm caches (model build)
    total, pso, iters = [], [], []
    for seed in range(runs):
        t0 = time.perf_counter()
        res = plan(
            robot,
            duration=1.0,
            objective="abs_work",
            particles=40,
            iterations=100,
            n_samples=100,
            seed=seed,
        )
        total.append(time.perf_counter() - t0)
        pso.append(res.optimizer.seconds)
        iters.append(res.optimizer.iterations)
    return {
        "total_seconds": total,
        "median_total_seconds": statistics.median(total),
        "median_pso_seconds": statistics.median(pso),
        "iterations_run": iters,
        "target_seconds": 0.6,
    }


def bench_cli(runs: int) -> dict[str, Any]:
    exe = ROOT / ".venv" / "bin" / "bioplan"
    cmd = [
        str(exe) if exe.exists() else "bioplan",
        "plan",
        "--robot",
        "curtain_wall_6dof",
        "--duration",
        "1",
        "--payload",
        "4",
        "--objective",
        "abs_work",
        "--method",
        "quintic,paper",
        "--json",
    ]
    times = json_command_seconds(cmd, runs)
    return {
        "command": " ".join(cmd[1:]),
        "seconds": times,
        "median_seconds": statistics.median(times),
        "target_seconds": 1.2,
    }


def bench_vs_pyswarms(runs: int) -> dict[str, Any]:
    import numpy as np

    from app.planning.planner import PlanProblem, PlanTask
    from app.planning.robots import load_robot
    from benchmarks.bench_pso import compare

    robot = load_robot("curtain_wall_6dof")
    problem = PlanProblem.build(
        robot,
        PlanTask.default(robot),
        duration=1.0,
        objective="abs_work",
        q_via_elbow=float(np.radians(62.0)),
        n_samples=100,
    )
    out = compare(
        problem.swarm_cost, problem.lower, problem.upper, particles=40, iterations=100, runs=runs
    )
    # Time to the same cost: ours as the planner runs it (early stop after 20 stagnant
    # iterations) against pyswarms' full budget.
    from app.planning.pso import pso_minimize

    times, costs, iters = [], [], []
    for seed in range(runs):
        t0 = time.perf_counter()
        res = pso_minimize(
            problem.swarm_cost,
            problem.lower,
            problem.upper,
            particles=40,
            iterations=100,
            seed=seed,
            initial=problem.initial,
        )
        times.append(time.perf_counter() - t0)
        costs.append(res.best_cost)
        iters.append(res.iterations)
    theirs_cost = out["pyswarms"]["median_best_cost"]
    out["ours_with_early_stop"] = {
        "median_seconds": statistics.median(times),
        "median_best_cost": statistics.median(costs),
        "iterations_run": iters,
        "time_ratio_vs_pyswarms": out["pyswarms"]["median_seconds"] / statistics.median(times),
        "same_cost": abs(statistics.median(costs) - theirs_cost) <= 1e-3 * abs(theirs_cost),
    }
    out["problem"] = "planner: curtain_wall_6dof, 1 s, 4 kg, abs_work, 62 deg"
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    results = {
        "plan_in_process": bench_plan(args.runs),
        "cli_end_to_end": bench_cli(args.runs),
        "pso_vs_pyswarms_on_planner": bench_vs_pyswarms(args.runs),
        "load_average": os.getloadavg(),
    }
    if args.json:
        print(json.dumps(results, indent=2))
        return
    p, c, v = (
        results[k] for k in ("plan_in_process", "cli_end_to_end", "pso_vs_pyswarms_on_planner")
    )
    print(
        f"plan() 40x100x100 on curtain_wall_6dof: median {p['median_total_seconds']:.3f} s "
        f"(PSO {p['median_pso_seconds']:.3f} s), target < 0.6 s"
    )
    print(f"bioplan plan end to end: median {c['median_seconds']:.3f} s, target < 1.2 s")
    print(
        f"planner problem, ours vs pyswarms: time ratio {v['time_ratio']:.2f}x, "
        f"best cost ours {v['ours']['median_best_cost']:.6g} vs pyswarms "
        f"{v['pyswarms']['median_best_cost']:.6g} (same within 0.1%: {v['same_cost']})"
    )
    e = v["ours_with_early_stop"]
    print(
        f"  ours as the planner runs it (early stop): {e['median_seconds']:.3f} s, "
        f"{e['time_ratio_vs_pyswarms']:.2f}x faster than pyswarms' full budget, best cost "
        f"{e['median_best_cost']:.6g} (same within 0.1%: {e['same_cost']}), iterations "
        f"{e['iterations_run']}"
    )
    print(f"load average {results['load_average']}")


if __name__ == "__main__":
    main()
