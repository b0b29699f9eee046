"""MUMPS's fill-reducing ordering (``ipopt.mumps_pivot_order``) changes the speed of the KKT
factorisations, never the optimum: approximate minimum degree (BioPlan's choice) and MUMPS's
automatic choice reach the same peak-power bound (issue 25, item 6)."""

from __future__ import annotations

import pytest

from app.planning import optimal
from app.planning.evaluation import PlanTask
from app.planning.optimal import HumanSpec, solve_optimal
from app.planning.robots import load_robot


@pytest.mark.parametrize("robot_name", ["human_arm_2dof", "curtain_wall_6dof"])
def test_the_ordering_changes_no_optimum(monkeypatch: pytest.MonkeyPatch, robot_name: str) -> None:
    robot = load_robot(robot_name)
    task = PlanTask.default(robot)
    spec = HumanSpec("none", robot.elbow_joint)
    assert optimal._IPOPT_OPTIONS["ipopt.mumps_pivot_order"] == 0  # the default
    values = {}
    for order in (0, 7):
        monkeypatch.setattr(optimal, "_SOLVERS", {})  # built solvers keep their options
        monkeypatch.setitem(optimal._IPOPT_OPTIONS, "ipopt.mumps_pivot_order", order)
        out = solve_optimal(robot, task.start, task.goal, 1.0, objective="peak_power",
                            human=spec, n_intervals=80)  # fmt: skip
        values[order] = out.solver.objective
    # IPOPT stops within its tolerance of the same point: measured 2e-6 apart on the 6-DOF arm.
    assert values[0] == pytest.approx(values[7], rel=1e-5)
