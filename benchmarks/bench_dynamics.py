"""Batched inverse dynamics of curtain_wall_6dof: configurations per second on one core.

Run:  .venv/bin/python benchmarks/bench_dynamics.py [--configs 1000000] [--repeats 7]
Target: >= 0.8 million configurations per second with one thread.

Random configurations (within the joint limits), velocities and accelerations; the timed call is
``robot.dynamics().inverse_dynamics(q, qd, qdd)`` on (N, 6) arrays, i.e. input checks, the
Fortran-order views and one ``pin.rneaInParallel`` call with one thread. For context the script
also times a plain Python loop over ``pin.rnea`` on a subset.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.planning.dynamics import PinocchioDynamics
from app.planning.robots import load_robot


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", type=int, default=1_000_000, help="batch size N")
    parser.add_argument("--repeats", type=int, default=7, help="timed runs (median reported)")
    parser.add_argument("--threads", type=int, default=1, help="rneaInParallel threads")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    if args.repeats < 5:
        parser.error("--repeats must be >= 5")

    robot = load_robot("curtain_wall_6dof")
    dyn = PinocchioDynamics(
        robot.urdf_path,
        payload=robot.payload,
        payload_body=robot.payload_body,
        armature=robot.armature,
        num_threads=args.threads,
    )
    rng = np.random.default_rng(args.seed)
    n = args.configs
    q = rng.uniform(robot.q_min, robot.q_max, size=(n, 6))
    qd = rng.uniform(-1.0, 1.0, size=(n, 6)) * robot.qd_max
    qdd = rng.normal(scale=10.0, size=(n, 6))

    dyn.inverse_dynamics(q[:1000], qd[:1000], qdd[:1000])  # warm-up
    times, cpu_times = [], []
    for _ in range(args.repeats):
        start, cpu_start = time.perf_counter(), time.process_time()
        tau = dyn.inverse_dynamics(q, qd, qdd)
        times.append(time.perf_counter() - start)
        cpu_times.append(time.process_time() - cpu_start)
    median = statistics.median(times)
    cpu_median = statistics.median(cpu_times)

    # Reference: one pin.rnea call per configuration from Python.
    model = dyn.model
    data = model.createData()
    rnea = __import__("pinocchio").rnea
    subset = min(n, 50_000)
    start = time.perf_counter()
    for i in range(subset):
        rnea(model, data, q[i], qd[i], qdd[i])
    loop_rate = subset / (time.perf_counter() - start)
    assert np.allclose(rnea(model, data, q[-1], qd[-1], qdd[-1]), tau[-1], atol=1e-9)

    result = {
        "benchmark": "inverse_dynamics curtain_wall_6dof",
        "command": " ".join(shlex.quote(a) for a in [sys.executable, *sys.argv]),
        "configs": n,
        "threads": args.threads,
        "repeats": args.repeats,
        "median_seconds": median,
        "configs_per_second": n / median,
        "best_configs_per_second": n / min(times),
        "cpu_time_configs_per_second": n / cpu_median,
        "load_average_1min": os.getloadavg()[0],
        "python_loop_configs_per_second": loop_rate,
        "target_configs_per_second": 0.8e6,
        "meets_target": n / median >= 0.8e6,
        "machine": f"{platform.machine()} {platform.processor() or platform.system()}",
    }
    if args.json:
        print(json.dumps(result))
        return
    print(f"command:  {result['command']}")
    print(f"batch:    {n} configurations, {args.threads} thread(s), median of {args.repeats} runs")
    print(f"median:   {median * 1e3:.1f} ms  ->  {n / median / 1e6:.3f} M configurations/s")
    print(f"best:     {n / min(times) / 1e6:.3f} M configurations/s")
    print(f"CPU time: {n / cpu_median / 1e6:.3f} M configurations/s (median process time)")
    print(f"load:     {result['load_average_1min']:.2f} (1-min load average; others share cores)")
    print(f"python loop over pin.rnea: {loop_rate / 1e6:.3f} M configurations/s (reference)")
    print(f"target >= 0.8 M/s: {'met' if result['meets_target'] else 'NOT met'}")


if __name__ == "__main__":
    main()
