"""Our PSO against pyswarms' GlobalBestPSO, side by side, same objective and budget.

Run: ``.venv/bin/python benchmarks/bench_pso.py [--runs 7] [--json]``.

Both optimisers get the same batched objective (a function of a (P, D) array), the same swarm
size and number of iterations (= swarm evaluations; neither stops early), the same inertia
schedule (linear 0.9 -> 0.4; pyswarms' ``lin_variation``), c1 = c2 = 1.5, the same velocity
clamp (0.2 of the box width) and positions clipped to the box (pyswarms ``bh_strategy=
"nearest"``). pyswarms draws from numpy's global generator, which is seeded per run.

``compare()`` returns a plain dict so other benchmarks (the planner's objective) can reuse it.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import statistics
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

if __package__ in (None, ""):  # run as a script: make ``app`` importable
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from app.planning.pso import pso_minimize

FloatArray = NDArray[np.float64]
Objective = Callable[[FloatArray], FloatArray | tuple[FloatArray, FloatArray]]

INERTIA = (0.9, 0.4)
C1 = C2 = 1.5
VELOCITY_CLAMP = 0.2


def rastrigin(x: FloatArray) -> FloatArray:
    """Rastrigin, minimum 0 at 0; (P, D) -> (P,)."""
    out: FloatArray = 10.0 * x.shape[1] + np.sum(x * x - 10.0 * np.cos(2.0 * np.pi * x), axis=1)
    return out


def rosenbrock(x: FloatArray) -> FloatArray:
    """Rosenbrock, minimum 0 at (1, ..., 1); (P, D) -> (P,)."""
    out: FloatArray = np.sum(
        100.0 * (x[:, 1:] - x[:, :-1] ** 2) ** 2 + (1.0 - x[:, :-1]) ** 2, axis=1
    )
    return out


def _penalised(objective: Objective, penalty: float) -> Callable[[FloatArray], FloatArray]:
    """pyswarms knows no constraints: fold a violation into the cost as cost + penalty * v."""

    def fn(x: FloatArray) -> FloatArray:
        out = objective(x)
        if isinstance(out, tuple):
            cost, viol = out
            return np.asarray(cost, dtype=np.float64) + penalty * np.asarray(viol)
        return np.asarray(out, dtype=np.float64)

    return fn


def _run_pyswarms(
    objective: Callable[[FloatArray], FloatArray],
    lo: FloatArray,
    hi: FloatArray,
    *,
    particles: int,
    iterations: int,
    seed: int,
) -> tuple[float, float, float]:
    import pyswarms as ps

    np.random.seed(seed)  # noqa: NPY002 (pyswarms draws from the global generator)
    v_max = VELOCITY_CLAMP * (hi - lo)
    cpu = time.process_time()
    start = time.perf_counter()
    optimizer = ps.single.GlobalBestPSO(
        n_particles=particles,
        dimensions=lo.size,
        options={"c1": C1, "c2": C2, "w": INERTIA[0]},
        bounds=(lo, hi),
        oh_strategy={"w": "lin_variation"},  # ends at w = 0.4, pyswarms' default end value
        bh_strategy="nearest",
        velocity_clamp=(-v_max, v_max),
    )
    best_cost, _ = optimizer.optimize(objective, iters=iterations, verbose=False)
    return time.perf_counter() - start, time.process_time() - cpu, float(best_cost)


def compare(
    objective: Objective,
    lower: ArrayLike,
    upper: ArrayLike,
    *,
    particles: int = 40,
    iterations: int = 100,
    runs: int = 5,
    penalty: float = 1e6,
) -> dict[str, Any]:
    """Run ours and pyswarms ``runs`` times each (seeds 0..runs-1), interleaved, same budget.

    Args:
        objective: (P, D) -> cost (P,) or (cost (P,), violation (P,)); pyswarms minimises
            cost + penalty * violation, ours uses feasibility rules (best costs are compared
            as returned by each, so keep ``penalty`` large or use unconstrained objectives).
        lower: (D,) lower bounds.
        upper: (D,) upper bounds.
        particles: swarm size for both.
        iterations: swarm evaluations for both (no early stop).
        runs: repetitions per optimiser (>= 5 for the medians in RESULTS.md).
        penalty: weight of the violation for pyswarms.

    Returns:
        ``{"particles", "iterations", "runs", "dimensions", "ours": {...}, "pyswarms": {...},
        "time_ratio", "cpu_time_ratio", "cost_rel_diff", "same_cost"}`` where each optimiser's
        entry has ``seconds`` (wall), ``cpu_seconds`` (process CPU time, steadier on a shared
        machine) and ``best_cost`` lists and their medians, ``time_ratio`` is pyswarms' median
        wall time over ours (> 1: ours is faster), ``cpu_time_ratio`` the same for CPU time,
        ``cost_rel_diff`` is
        (ours − pyswarms) / max(|pyswarms|, 1e-12) of the median best costs, and ``same_cost``
        says whether the medians agree within 0.1 % (or 1e-9 absolute near zero).
    """
    lo = np.asarray(lower, dtype=np.float64)
    hi = np.asarray(upper, dtype=np.float64)
    swarm_fn = _penalised(objective, penalty)
    logging.getLogger("pyswarms").setLevel(logging.CRITICAL)
    ours: dict[str, list[float]] = {"seconds": [], "cpu_seconds": [], "best_cost": []}
    theirs: dict[str, list[float]] = {"seconds": [], "cpu_seconds": [], "best_cost": []}
    for seed in range(runs):
        cpu = time.process_time()
        start = time.perf_counter()
        result = pso_minimize(
            objective,
            lo,
            hi,
            particles=particles,
            iterations=iterations,
            seed=seed,
            inertia=INERTIA,
            cognitive=C1,
            social=C2,
            velocity_clamp=VELOCITY_CLAMP,
            stagnation_iterations=None,
        )
        ours["seconds"].append(time.perf_counter() - start)
        ours["cpu_seconds"].append(time.process_time() - cpu)
        ours["best_cost"].append(result.best_cost)
        seconds, cpu_seconds, cost = _run_pyswarms(
            swarm_fn, lo, hi, particles=particles, iterations=iterations, seed=seed
        )
        theirs["seconds"].append(seconds)
        theirs["cpu_seconds"].append(cpu_seconds)
        theirs["best_cost"].append(cost)

    def summary(d: dict[str, list[float]]) -> dict[str, Any]:
        return {
            **d,
            "median_seconds": statistics.median(d["seconds"]),
            "median_cpu_seconds": statistics.median(d["cpu_seconds"]),
            "median_best_cost": statistics.median(d["best_cost"]),
        }

    a, b = summary(ours), summary(theirs)
    diff = a["median_best_cost"] - b["median_best_cost"]
    return {
        "particles": particles,
        "iterations": iterations,
        "runs": runs,
        "dimensions": int(lo.size),
        "ours": a,
        "pyswarms": b,
        "time_ratio": b["median_seconds"] / a["median_seconds"],
        "cpu_time_ratio": b["median_cpu_seconds"] / a["median_cpu_seconds"],
        "cost_rel_diff": diff / max(abs(b["median_best_cost"]), 1e-12),
        "same_cost": abs(diff) <= max(1e-3 * abs(b["median_best_cost"]), 1e-9),
    }


def _planner_overhead_objective(
    n_samples: int = 100, n_joints: int = 6, duration: float = 1.0
) -> tuple[Objective, FloatArray, FloatArray]:
    """Our share of the planner's swarm cost without a robot: piecewise quintic through one
    via point for each of ``n_joints`` joints, a cheap stand-in for the dynamics (a decoupled
    pendulum per joint), and the ``abs_work`` metric. Measures trajectory + metric overhead."""
    from app.planning.energy import objective_values
    from app.planning.profiles import piecewise_quintic_batch, time_grid

    t = time_grid(duration, n_samples)
    start = np.zeros(n_joints)
    goal = np.linspace(0.5, 1.5, n_joints)
    inertia = np.linspace(2.0, 0.2, n_joints)
    gravity = np.linspace(40.0, 4.0, n_joints)
    mean_speed = (goal - start) / duration

    def objective(x: FloatArray) -> FloatArray:
        p = x.shape[0]
        frac, pos, vel = x[:, :1], x[:, 1 : 1 + n_joints], x[:, 1 + n_joints :]
        tk = np.hstack([np.zeros((p, 1)), frac * duration, np.full((p, 1), duration)])
        qk = np.stack(
            [np.tile(start, (p, 1)), start + pos * (goal - start), np.tile(goal, (p, 1))], 1
        )
        qdk = np.zeros_like(qk)
        qdk[:, 1] = vel * mean_speed
        q, qd, qdd = piecewise_quintic_batch(tk, qk, qdk, np.zeros_like(qk), t)
        tau = inertia * qdd + gravity * np.sin(q)
        return objective_values("abs_work", t, qd, tau)

    lower = np.concatenate([[0.2], np.full(n_joints, 0.2), np.full(n_joints, 0.5)])
    upper = np.concatenate([[0.8], np.full(n_joints, 0.8), np.full(n_joints, 2.5)])
    return objective, lower, upper


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--particles", type=int, default=40)
    parser.add_argument("--iterations", type=int, default=100)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)

    overhead, lo_o, hi_o = _planner_overhead_objective()
    cases: dict[str, tuple[Objective, FloatArray, FloatArray]] = {
        "rastrigin_2d": (rastrigin, np.full(2, -5.12), np.full(2, 5.12)),
        "rastrigin_5d": (rastrigin, np.full(5, -5.12), np.full(5, 5.12)),
        "rosenbrock_2d": (rosenbrock, np.full(2, -2.048), np.full(2, 2.048)),
        "rosenbrock_4d": (rosenbrock, np.full(4, -2.048), np.full(4, 2.048)),
        "planner_overhead_6dof": (overhead, lo_o, hi_o),
    }
    results = {
        name: compare(
            fn, lo, hi, particles=args.particles, iterations=args.iterations, runs=args.runs
        )
        for name, (fn, lo, hi) in cases.items()
    }
    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    print(
        f"PSO, {args.particles} particles x {args.iterations} iterations, "
        f"median of {args.runs} runs"
    )
    header = f"{'objective':<24}{'ours [ms]':>11}{'pyswarms [ms]':>15}{'ratio':>8}{'cpu ratio':>11}"
    print(header + f"{'ours cost':>14}{'pyswarms cost':>15}  same")
    for name, r in results.items():
        print(
            f"{name:<24}{1e3 * r['ours']['median_seconds']:>11.1f}"
            f"{1e3 * r['pyswarms']['median_seconds']:>15.1f}{r['time_ratio']:>8.2f}"
            f"{r['cpu_time_ratio']:>11.2f}"
            f"{r['ours']['median_best_cost']:>14.6g}{r['pyswarms']['median_best_cost']:>15.6g}"
            f"  {r['same_cost']}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
