"""Fixtures: one small plan and one small simulation of each built-in robot, computed once."""

from __future__ import annotations

from typing import Any

import pytest

from app.viewer.comparison import Comparison, comparison_from_arrays


@pytest.fixture(scope="session")
def plan_result() -> Any:
    from app.planning import load_robot, plan

    robot = load_robot("curtain_wall_6dof")
    return robot, plan(robot, duration=1.0, particles=12, iterations=15, seed=1)


@pytest.fixture(scope="session")
def simulation_result() -> Any:
    from app.planning import load_robot
    from app.simulation import simulate_comparison

    robot = load_robot("curtain_wall_6dof", payload=6.0)
    return robot, simulate_comparison(robot, duration=1.2, particles=10, iterations=10, seed=2)


@pytest.fixture(scope="session")
def plan_comparison(plan_result: Any) -> Comparison:
    robot, result = plan_result
    return comparison_from_arrays("plan", 7, result.arrays(), result.to_dict(), robot)


@pytest.fixture(scope="session")
def simulation_comparison(simulation_result: Any) -> Comparison:
    robot, result = simulation_result
    return comparison_from_arrays("simulation", 9, result.arrays(), result.to_dict(), robot)
