"""Safety check speed: a 1 s plan of five trajectories at 1 kHz on the UR5 (meshes).

The robot is example-robot-data's UR5 with its 7 collision meshes (docs/examples/ur5.sidecar.yaml:
wrist 3 locked, five free joints). Five rest-to-rest trajectories of the same task stand in for
a plan's five methods (quintic, cubic, trapezoidal, s-curve, minimum jerk), 1001 samples each.
Two tasks: the UR5's default task (below its mounting plane: many contacts) and a safe task
(arm raised, every pair clear). Timed: ``check_safety`` on a freshly loaded robot ("cold":
meshes read and their convex hulls built, as in a plan request) and again on the same robot
("warm": the collision model cached on it).

Run ``python benchmarks/safety.py [--repeat N]``; prints one JSON object with the medians.
Target: the check of the five trajectories in <= 0.5 s.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SAFE_START_DEG = (0.0, -90.0, 0.0, -90.0, 0.0)
SAFE_GOAL_DEG = (0.0, -70.0, 100.0, -90.0, 0.0)


def _robot() -> Any:
    from app.planning.robots import load_robot
    from tests.utils.example_robots import UR5, robot_file

    return load_robot(robot_file(UR5), sidecar=ROOT / "docs" / "examples" / "ur5.sidecar.yaml")


def _five(start: np.ndarray, goal: np.ndarray) -> dict[str, Any]:
    from app.planning import profiles

    n = 1001
    return {
        "quintic": profiles.quintic(start, goal, 1.0, n_samples=n),
        "cubic": profiles.cubic(start, goal, 1.0, n_samples=n),
        "trapezoidal": profiles.trapezoidal(start, goal, 1.0, n_samples=n),
        "s_curve": profiles.s_curve(start, goal, 1.0, n_samples=n),
        "minimum_jerk": profiles.minimum_jerk(start, goal, 1.0, n_samples=n),
    }


def _time(task: str, repeat: int) -> dict[str, Any]:
    from app.planning.safety import check_safety

    cold, warm = [], []
    report = None
    for _ in range(repeat):
        robot = _robot()
        if task == "default":
            start, goal = robot.default_start, robot.default_goal
        else:
            start, goal = np.radians(SAFE_START_DEG), np.radians(SAFE_GOAL_DEG)
        plan = _five(start, goal)
        t0 = time.perf_counter()
        report = check_safety(robot, plan)
        cold.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        check_safety(robot, plan)
        warm.append(time.perf_counter() - t0)
    assert report is not None
    return {
        "task": task,
        "ok": report.ok,
        "findings": len(report.findings),
        "pairs": dict(report.pairs),
        "cold_median_s": statistics.median(cold),
        "warm_median_s": statistics.median(warm),
        "cold_runs_s": [round(x, 4) for x in cold],
        "warm_runs_s": [round(x, 4) for x in warm],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs per task (median reported)")
    args = parser.parse_args()
    out = {
        "load_average_1min": os.getloadavg()[0],
        "target_s": 0.5,
        "results": [_time(task, args.repeat) for task in ("default", "safe")],
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
