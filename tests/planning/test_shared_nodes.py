"""Each node of the optimal control's mesh is evaluated once (issue 25, item 6).

An interval's end is the next interval's start: the same state, so the same torque, power and
limit rows. Evaluating it once removes those duplicate rows (1/9 of the evaluation points on
the peak objectives, 1/5 on the others) without changing the problem: the optimum must be the
one the duplicated rows give. Metrics of the jerk, which jumps at a node, keep both sides, and
their value is checked against the knots' own jerk.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from app.planning import optimal
from app.planning.evaluation import PlanTask
from app.planning.human_template import HumanTemplate
from app.planning.methods import human_spec
from app.planning.optimal import HumanSpec, solve_optimal
from app.planning.profiles import quintic
from app.planning.robots import load_robot

N = 16


def _arm() -> tuple[Any, PlanTask]:
    robot = load_robot("human_arm_2dof", payload=12.0)
    return robot, PlanTask.default(robot)


def _spec(robot: Any, task: PlanTask, kind: str) -> HumanSpec:
    if kind == "none":
        return HumanSpec("none", robot.elbow_joint)
    e = robot.elbow_joint
    q_via = HumanTemplate().peak_joint_angle(float(task.start[e]), float(task.goal[e]))
    return human_spec("peak", robot, task, HumanTemplate(), q_via)[0]


def _solve(robot: Any, task: PlanTask, objective: str, spec: HumanSpec) -> Any:
    return solve_optimal(robot, task.start, task.goal, 1.0, objective=objective, human=spec,
                         n_intervals=N)  # fmt: skip


def _rows(robot: Any, task: PlanTask, objective: str, spec: HumanSpec) -> tuple[int, int]:
    """Constraint rows of the NLP this problem builds (graded ends off), and its intervals."""
    warm = quintic(task.start, task.goal, 1.0, n_samples=201)
    problem = optimal._problem(robot, task.start, task.goal, 1.0, objective, spec, warm, N, True,
                               None, None, 0)  # fmt: skip
    nlp, _, _ = optimal._nlp(problem, warm)
    return int(nlp["g"].shape[0]), problem.n_intervals


@pytest.mark.parametrize(
    ("objective", "kind"),
    [("tau_sq", "none"), ("peak_power", "none"), ("tau_sq", "peak"), ("abs_work", "none")],
)
def test_one_point_per_node_gives_the_same_optimum_with_fewer_rows(
    monkeypatch: pytest.MonkeyPatch, objective: str, kind: str
) -> None:
    robot, task = _arm()
    spec = _spec(robot, task, kind)
    monkeypatch.setattr(optimal, "SHARE_NODES", False)
    rows_twice, intervals = _rows(robot, task, objective, spec)
    twice = _solve(robot, task, objective, spec)
    monkeypatch.setattr(optimal, "SHARE_NODES", True)
    rows_once, _ = _rows(robot, task, objective, spec)
    once = _solve(robot, task, objective, spec)
    # Every interior node carried its rows twice: the same number at each of them.
    assert rows_once < rows_twice
    assert (rows_twice - rows_once) % (intervals - 1) == 0
    assert once.solver.objective == pytest.approx(twice.solver.objective, rel=1e-6)
    np.testing.assert_allclose(once.knots.q, twice.knots.q, atol=1e-4)


@pytest.mark.parametrize("objective", ["jerk", "torque_change"])
def test_jerk_metrics_keep_both_sides_of_a_node(
    monkeypatch: pytest.MonkeyPatch, objective: str
) -> None:
    robot, task = _arm()
    spec = _spec(robot, task, "none")
    monkeypatch.setattr(optimal, "SHARE_NODES", True)
    rows, _ = _rows(robot, task, objective, spec)
    monkeypatch.setattr(optimal, "SHARE_NODES", False)
    assert _rows(robot, task, objective, spec)[0] == rows


def test_the_jerk_objective_is_the_knots_own_jerk() -> None:
    """∫ |q⃛|² dt of the constant-jerk pieces, from the returned knots: the solver's value."""
    robot, task = _arm()
    out = _solve(robot, task, "jerk", _spec(robot, task, "none"))
    h = np.diff(out.knots.t)
    jerk = np.diff(out.knots.qdd, axis=0) / h[:, None]
    assert out.solver.objective == pytest.approx(float(np.sum(h * np.sum(jerk**2, axis=1))),
                                                 rel=1e-9)  # fmt: skip
