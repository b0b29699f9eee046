"""How long a plan IPOPT finds infeasible takes to fail with its hint (issue 25, CI time).

``.venv/bin/python benchmarks/infeasible_hint.py [--runs 3]``: ``plan(...,
methods=("quintic", "human_optimal"))`` on tasks the limits cannot meet, each run in its own
child process (cold), per variant: ``probes`` (the default: each probe of the shortest-duration
search warm-started from the nearest longer solved motion and capped at
``shortest_duration.PROBE_ITERATIONS``) and ``cold`` (every probe from the quintic, uncapped:
before 2026-11-27). Prints the median wall and CPU seconds of the failed plan, the duration its
error names and the probes' count.
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: Infeasible tasks: robot, payload [kg], duration [s], objective.
CASES = (
    ("curtain_wall_6dof", 10.0, 0.75, "abs_work"),
    ("human_arm_2dof", 12.0, 0.3, "peak_power"),
)


def _child(robot_name: str, payload: float, duration: float, objective: str, variant: str) -> None:
    """One failed plan in this process; prints one JSON line."""
    import re

    from app.planning import shortest_duration
    from app.planning.planner import plan
    from app.planning.robots import load_robot

    if variant == "cold":
        shortest_duration.PROBE_ITERATIONS = None  # type: ignore[assignment]
        shortest_duration.stretched = lambda traj, duration: None  # type: ignore[assignment,misc]
    probes = 0
    real = shortest_duration.solve_optimal

    def counted(*args: object, **kwargs: object) -> object:
        nonlocal probes
        probes += 1
        return real(*args, **kwargs)  # type: ignore[arg-type]

    shortest_duration.solve_optimal = counted  # type: ignore[assignment]
    robot = load_robot(robot_name, payload=payload)
    wall, cpu = time.perf_counter(), time.process_time()
    error = ""
    try:
        plan(robot, duration=duration, objective=objective, methods=("quintic", "human_optimal"))
    except Exception as exc:  # the failure is the point
        error = str(exc)
    found = re.search(r"at least ([0-9.]+) s", error)
    print(json.dumps({
        "wall": time.perf_counter() - wall, "cpu": time.process_time() - cpu, "probes": probes,
        "hint": float(found.group(1)) if found else None,
    }))  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        robot, payload, duration, objective, variant = args.child
        _child(robot, float(payload), float(duration), objective, variant)
        return
    print(f"load average {os.getloadavg()[0]:.2f}")
    for robot, payload, duration, objective in CASES:
        for variant in ("cold", "probes"):
            rows = []
            for _ in range(args.runs):
                cmd = [sys.executable, __file__, "--child", robot, str(payload), str(duration)]
                out = subprocess.run(
                    [*cmd, objective, variant], capture_output=True, text=True, check=True
                )
                rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
            wall = statistics.median(r["wall"] for r in rows)
            cpu = statistics.median(r["cpu"] for r in rows)
            print(
                f"{robot} {payload:g} kg {duration:g} s {objective} {variant}: median wall "
                f"{wall:.1f} s, CPU {cpu:.1f} s; hint {rows[0]['hint']} s after "
                f"{rows[0]['probes']} probes ({args.runs} runs)",
                flush=True,
            )


if __name__ == "__main__":
    main()
