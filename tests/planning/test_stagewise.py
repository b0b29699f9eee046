"""The stage-wise transcription (issue 25, item 6): the project's bound, in fatrop's order.

Checked against the project's own IPOPT transcription (``optimal.solve_optimal``, variables
ordered node by node, another solver) at the same mesh, and re-evaluated with Pinocchio on the
fine report grid.
"""

from __future__ import annotations

import numpy as np
import pytest

from app.errors import BioPlanError
from app.planning.evaluation import PlanTask, evaluate_trajectory
from app.planning.methods import objective_value
from app.planning.optimal import HumanSpec, OptimalResult, solve_optimal
from app.planning.profiles import time_grid
from app.planning.robots import Robot, load_robot
from benchmarks.stagewise_problem import StagewiseResult, solve_stagewise

N = 20


@pytest.fixture(scope="module")
def arm() -> Robot:
    return load_robot("human_arm_2dof", payload=12.0)


def _project(robot: Robot, objective: str) -> OptimalResult:
    task = PlanTask.default(robot)
    return solve_optimal(
        robot, task.start, task.goal, 1.0, objective=objective,
        human=HumanSpec("none", robot.elbow_joint), n_intervals=N, explain=False,
        end_grading=0,  # the stage-wise NLP's equal intervals
    )  # fmt: skip


def _stagewise(robot: Robot, objective: str, solver: str) -> StagewiseResult:
    task = PlanTask.default(robot)
    return solve_stagewise(
        robot, task.start, task.goal, 1.0, objective=objective, n_intervals=N, solver=solver
    )


@pytest.mark.parametrize(
    ("objective", "solver"),
    [("tau_sq", "fatrop"), ("tau_sq", "ipopt"), ("peak_power", "ipopt")],
)
def test_stagewise_optimum_is_the_projects_bound(arm: Robot, objective: str, solver: str) -> None:
    ref = _project(arm, objective)
    res = _stagewise(arm, objective, solver)
    assert res.objective == pytest.approx(ref.solver.objective, rel=1e-3)
    # The same trajectory family and optimum: the node states agree, not only the value.
    assert np.allclose(res.knots.q, ref.knots.q, atol=1e-3)
    assert np.allclose(res.knots.t, ref.knots.t)
    # Rest to rest at the task's ends.
    task = PlanTask.default(arm)
    assert np.allclose(res.knots.q[[0, -1]], [task.start, task.goal], atol=1e-9)
    assert np.allclose(res.knots.qd[[0, -1]], 0.0, atol=1e-9)
    # Pinocchio on the fine grid: within the limits, the metric where the solver put it.
    ev = evaluate_trajectory(arm, res.knots.sample(time_grid(1.0, 1000)), task)
    assert ev.violations == ()
    assert objective_value(arm, ev, objective) == pytest.approx(res.objective, rel=2e-3)


def test_stagewise_structure_is_stage_by_stage(arm: Robot) -> None:
    res = _stagewise(arm, "peak_power", "ipopt")
    # Two moving joints: (q, qd, qdd) per joint plus the epigraph state; the jerk per joint.
    assert (res.sizes["nx"], res.sizes["nu"], res.sizes["N"]) == (7, 2, N)
    assert res.sizes["variables"] == N * (7 + 2) + 7


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({"objective": "abs_work"}, "stage-wise objective 'abs_work'"),
        ({"objective": "tau_sq", "solver": "snopt"}, "unknown stage-wise solver 'snopt'"),
        ({"objective": "tau_sq", "n_intervals": 4}, "n_intervals must be >= 8, got 4"),
        ({"objective": "peak_power", "epigraph": "max"}, "unknown epigraph 'max'"),
    ],
)
def test_stagewise_bad_options_are_named(
    arm: Robot, kwargs: dict[str, object], expected: str
) -> None:
    task = PlanTask.default(arm)
    with pytest.raises(BioPlanError, match=expected):
        solve_stagewise(arm, task.start, task.goal, 1.0, **kwargs)  # type: ignore[arg-type]
