"""The viewer shows what the planner plans: UR5, UR10 and Panda (fingers locked) with meshes.

Each robot is planned, simulated in MuJoCo (through MuJoCo's own URDF compiler), prepared for
the viewer with its meshes, and exported, end to end. The payload path the viewer computes is
checked against Pinocchio's forward kinematics of the planner's robot (an independent chain).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.planning import load_robot
from app.planning.export import export_bytes, plan_motion
from app.simulation import simulate_comparison
from app.viewer.comparison import comparison_from_arrays
from app.viewer.scene import PreparedComparison
from tests.utils.example_robots import PANDA, PANDA_LOCKS, UR5, UR10, robot_file

CASES = {
    "ur5": (UR5, None, 2.0),
    "ur10": (UR10, None, 2.5),
    "panda": (PANDA, PANDA_LOCKS, 3.0),
}


@pytest.mark.parametrize("name", list(CASES))
def test_plan_simulate_view_and_export(name: str, tmp_path: Path) -> None:
    relative, locks, duration = CASES[name]
    robot = load_robot(robot_file(relative), payload=1.0, locks=locks)
    result = simulate_comparison(robot, duration=duration, particles=10, iterations=8, seed=0)
    assert result.standard.tracking_max.max() < 1e-3  # MuJoCo follows the plan
    assert result.to_dict()["standard"]["electrical_energy"] is None  # not modelled
    comparison = comparison_from_arrays(
        "plan", 1, result.plan.arrays(), result.plan.to_dict(), robot
    )
    prepared = PreparedComparison(comparison, urdf_path=robot.urdf_path, locks=robot.locks)
    assert len(prepared.meshes) >= 7 and all(m.faces.size for m in prepared.meshes)
    # the payload path drawn by the viewer = Pinocchio's end effector of the planned motion
    q = result.plan.optimized.trajectory.q
    ee = robot.dynamics().end_effector_position(q)
    np.testing.assert_allclose(prepared.payload_path["optimized"], ee, atol=1e-9)
    motion = plan_motion(result.plan, robot)
    # These robots' default tasks are in contact (app.planning.safety, issue 27): exported
    # on request, which the file records.
    data = json.loads(export_bytes(motion, "json", rate=100.0, robot=robot, allow_unsafe=True))
    assert data["joint_names"] == list(robot.joint_names)
    np.testing.assert_allclose(data["q"][-1], result.plan.task.goal, atol=1e-12)


def test_locked_fingers_are_drawn_at_their_lock() -> None:
    robot = load_robot(robot_file(PANDA), locks=PANDA_LOCKS)
    t = np.linspace(0.0, 1.0, 5)
    q = np.tile(robot.default_start, (5, 1))
    arrays: dict[str, Any] = {"t": t}
    for label in ("standard", "optimized"):
        arrays |= {f"{label}_{k}": q for k in ("q", "qd", "qdd", "tau")}
        arrays |= {f"{label}_power": np.zeros(5), f"{label}_energy": np.zeros(5)}
    result = {"conditions": {"start_deg": [0.0] * 7, "goal_deg": [0.0, 20.0, 0, -150, 0, 0, 0]}}
    comparison = comparison_from_arrays("plan", 2, arrays, result, robot)
    held = PreparedComparison(comparison, urdf_path=robot.urdf_path, locks=robot.locks)
    closed = PreparedComparison(comparison, urdf_path=robot.urdf_path)
    finger = held.joint_position["standard"]["panda_finger_joint1"][0]
    shut = closed.joint_position["standard"]["panda_finger_joint1"][0]
    assert np.linalg.norm(finger - shut) == pytest.approx(0.02, abs=1e-12)
