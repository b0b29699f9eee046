"""What keeping an obstacle clear costs the optimal control (issue 27, item 1).

Two cases, each solved without and with the obstacle as a constraint
(:mod:`app.planning.clearance`), the constrained solve warm-started from the unconstrained
optimum (as ``app.planning.methods.run_optimal`` does):

* ``2dof``: the two-link arm of ``tests/planning/test_obstacle_clearance.py`` (a 3 cm cylinder
  along each link), folded back to folded forward in 2 s, a 0.3 x 0.3 x 0.2 m box under it;
* ``6dof``: ``curtain_wall_6dof`` swinging all six joints in 2.5 s, its wrist through a
  vertical pipe (cylinder, radius 7 cm, 0.3 m long) at (0.55, 0.35, 0.75) m.

Timed: ``solve_optimal`` (tau_sq, no human constraint, 40 intervals) "cold" (its IPOPT solver
built: the first solve of a structure) and "warm" (the solver cached, as in a sweep or a
re-solve of the same structure); "plane_only": with the mounting plane's rows alone (they do
not bind), to tell the obstacle's share. Also: the NLP's clearance rows and IPOPT iterations.

Run ``python benchmarks/obstacle_clearance.py [--repeat N] [--case 2dof|6dof]``; prints one
JSON object with the medians.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _case(name: str, folder: Path) -> tuple[Any, Any, Any, float, Any]:
    """(robot, start, goal, duration, obstacle)."""
    from app.planning.robots import load_robot
    from app.planning.robots._obstacles import Obstacle

    if name == "2dof":
        from tests.planning.test_clearance_constraint import DURATION, GOAL, START, _arm

        box = Obstacle("stand", "box", position=(0.0, 0.0, -0.55), size=(0.3, 0.3, 0.2))
        return _arm(folder, plane=-1.0), START, GOAL, DURATION, box
    pipe = Obstacle("pipe", "cylinder", position=(0.55, 0.35, 0.75), radius=0.07, length=0.3)
    goal = np.array([0.8, 0.349, 2.618, 0.4, 0.4, 0.4])
    return load_robot("curtain_wall_6dof"), np.zeros(6), goal, 2.5, pipe


def _measure(name: str, repeat: int) -> dict[str, Any]:
    from app.planning import optimal
    from app.planning.clearance import clearance_constraint
    from app.planning.optimal import ExtraConstraints, HumanSpec, solve_optimal
    from app.planning.safety import SafetyScene, check_safety

    with tempfile.TemporaryDirectory() as tmp:
        robot, start, goal, duration, obstacle = _case(name, Path(tmp))
        spec = HumanSpec("none", robot.elbow_joint)
        plane = -1.0 if name == "2dof" else 0.0
        scene = SafetyScene(plane, obstacles=(obstacle,))
        constraint = clearance_constraint(robot, scene)
        assert constraint is not None
        times: dict[str, list[float]] = {
            k: [] for k in ("free_cold", "free_warm", "plane_only_cold", "kept_cold", "kept_warm")
        }
        out: dict[str, Any] = {}
        for _ in range(repeat):
            optimal._SOLVERS.clear()
            for label in ("free_cold", "free_warm"):
                t0 = time.perf_counter()
                free = solve_optimal(robot, start, goal, duration, objective="tau_sq", human=spec)
                times[label].append(time.perf_counter() - t0)
            # The mounting plane's rows alone (they bind in neither case): the obstacle's share.
            plane_only = dataclasses.replace(constraint, obstacles=())
            t0 = time.perf_counter()
            solve_optimal(
                robot, start, goal, duration, objective="tau_sq", human=spec,
                warm_start=free.trajectory, extra=ExtraConstraints(clearance=plane_only),
            )  # fmt: skip
            times["plane_only_cold"].append(time.perf_counter() - t0)
            for label in ("kept_cold", "kept_warm"):
                t0 = time.perf_counter()
                kept = solve_optimal(
                    robot, start, goal, duration, objective="tau_sq", human=spec,
                    warm_start=free.trajectory, extra=ExtraConstraints(clearance=constraint),
                )  # fmt: skip
                times[label].append(time.perf_counter() - t0)
            before = check_safety(robot, {"bound": free.trajectory}, scene=scene)
            after = check_safety(robot, {"bound": kept.trajectory}, scene=scene)
            out.update(
                objective_free=free.solver.objective,
                objective_kept=kept.solver.objective,
                iterations_free=free.solver.iterations,
                iterations_kept=kept.solver.iterations,
                unconstrained_safety=before.summary(),
                constrained_safety=after.summary(),
            )
        points = 5 * 40  # quarter points of 40 intervals
        out.update(
            spheres=constraint.n_spheres,
            obstacle_pairs=constraint.n_pairs,
            obstacle_rows=constraint.n_pairs * points,
            plane_rows=constraint.n_spheres * points,
            **{k: statistics.median(v) for k, v in times.items()},
            **{f"{k}_range": [min(v), max(v)] for k, v in times.items()},
        )
        return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--case", choices=("2dof", "6dof"), action="append")
    args = parser.parse_args()
    out: dict[str, Any] = {
        "load_average_1min": os.getloadavg()[0],
        **{case: _measure(case, args.repeat) for case in (args.case or ["2dof", "6dof"])},
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
