"""Graded ends of the optimal control's mesh (issue 25, item 1): every segment's first and last
interval cut into halving pieces, where rest to rest and the human rule's joins kink the optimum.

Checked against the equal-interval mesh four times as fine: both trajectories are re-evaluated
with Pinocchio on the report grid, so the lower value is the better feasible motion of the same
problem, whatever the solver's own quadrature says.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from app.errors import BioPlanError
from app.planning.evaluation import PlanTask, evaluate_trajectory
from app.planning.human_template import HumanTemplate
from app.planning.methods import human_spec, objective_value
from app.planning.optimal import END_GRADING, HumanSpec, report_resolved_grading, solve_optimal
from app.planning.robots import load_robot

LEVELS = 5


def _arm() -> tuple[Any, PlanTask]:
    robot = load_robot("human_arm_2dof")
    return robot, PlanTask.default(robot)


def _peak(robot: Any, task: PlanTask) -> HumanSpec:
    e = robot.elbow_joint
    q_via = HumanTemplate().peak_joint_angle(float(task.start[e]), float(task.goal[e]))
    return human_spec("peak", robot, task, HumanTemplate(), q_via)[0]


def _value(robot: Any, task: PlanTask, result: Any, objective: str) -> float:
    evaluated = evaluate_trajectory(robot, result.trajectory, task)
    assert evaluated.violations == ()
    return objective_value(robot, evaluated, objective)


def test_the_mesh_is_graded_nested_and_reports_its_size() -> None:
    """N = 16 with L = 5: 16 + 10 intervals, the end pieces 1/32 ... 1/2 of 1/16 s, N reported
    as asked; the 32-interval graded mesh keeps every node of the 16-interval one (a report grid
    of 2001 samples resolves L = 5 on both)."""
    robot, task = _arm()
    spec = HumanSpec("none", robot.elbow_joint)
    meshes = {}
    for n in (16, 32):
        out = solve_optimal(robot, task.start, task.goal, 1.0, objective="tau_sq", human=spec,
                            n_intervals=n, end_grading=LEVELS, report_samples=2001)  # fmt: skip
        assert out.solver.n_intervals == n and out.solver.end_grading == LEVELS
        meshes[n] = out.knots.t
    h = np.diff(meshes[16])
    assert h.size == 16 + 2 * LEVELS
    pieces = np.array([2.0**-LEVELS, *(2.0 ** -np.arange(LEVELS, 0, -1))]) / 16
    np.testing.assert_allclose(h[: LEVELS + 1], pieces, atol=1e-12)
    np.testing.assert_allclose(h[-LEVELS - 1 :], pieces[::-1], atol=1e-12)
    np.testing.assert_allclose(h[LEVELS + 1 : -LEVELS - 1], 1 / 16, atol=1e-12)
    fine = meshes[32]
    assert all(np.min(np.abs(fine - node)) < 1e-12 for node in meshes[16])


@pytest.mark.parametrize(
    ("kind", "objective"), [("none", "peak_power"), ("peak", "tau_sq")]
)  # fmt: skip
def test_graded_ends_beat_equal_intervals_four_times_as_fine(kind: str, objective: str) -> None:
    """40 graded intervals, as a plan solves them by default (L = 4 on the 1000-sample report
    grid), give a better feasible motion than 160 equal ones: the bound's peak power and the
    human-like optimum's `tau_sq`, whose peak rule kinks the optimum at its segment joins
    (measured with L = 5: 97.6 against 97.9 W; 1817 against 1840, at 40 equal intervals 1920)."""
    robot, task = _arm()
    spec = HumanSpec("none", robot.elbow_joint) if kind == "none" else _peak(robot, task)
    common: dict[str, Any] = {"objective": objective, "human": spec}
    graded = solve_optimal(robot, task.start, task.goal, 1.0, n_intervals=40, **common)
    equal = solve_optimal(robot, task.start, task.goal, 1.0, n_intervals=160, end_grading=0,
                          **common)  # fmt: skip
    assert graded.solver.end_grading == 4 and equal.solver.end_grading == 0
    assert _value(robot, task, graded, objective) < _value(robot, task, equal, objective)


def test_the_grading_is_as_fine_as_the_report_grid_resolves() -> None:
    """L = END_GRADING (5) by default, capped so the finest piece (2^-L of T / N) spans at least
    one step of the report grid (T / (samples - 1)): a plan on N or on 2N intervals has the same
    finest piece, and the meshes are nested. (A refinement keeps its first mesh's L instead:
    tests/planning/test_converge_option.py.) 0 asks for equal intervals."""
    assert END_GRADING == LEVELS
    assert [report_resolved_grading(LEVELS, n, 1000) for n in (16, 40, 80, 160, 320, 640)] == [
        5,
        4,
        3,
        2,
        1,
        0,
    ]
    assert report_resolved_grading(LEVELS, 40, 300) == 2
    assert report_resolved_grading(2, 8, 10**4) == 2  # never above the levels asked for
    robot, task = _arm()
    spec = HumanSpec("none", robot.elbow_joint)
    for samples, levels in ((1000, 5), (200, 3)):
        out = solve_optimal(robot, task.start, task.goal, 1.0, objective="tau_sq", human=spec,
                            n_intervals=16, report_samples=samples)  # fmt: skip
        assert out.solver.end_grading == levels
        h = np.diff(out.knots.t)
        assert h.size == 16 + 2 * levels and h.min() >= 1.0 / (samples - 1) - 1e-12
    coarse, fine = (
        solve_optimal(robot, task.start, task.goal, 1.0, objective="tau_sq", human=spec,
                      n_intervals=n).knots.t
        for n in (40, 80)
    )  # fmt: skip
    assert np.diff(coarse).min() == pytest.approx(np.diff(fine).min(), rel=1e-9)
    assert all(np.min(np.abs(fine - node)) < 1e-12 for node in coarse)


def test_equal_intervals_on_request_and_bad_grading_is_named() -> None:
    robot, task = _arm()
    spec = HumanSpec("none", robot.elbow_joint)
    plain = solve_optimal(robot, task.start, task.goal, 1.0, objective="tau_sq", human=spec,
                          n_intervals=16, end_grading=0)  # fmt: skip
    assert plain.solver.end_grading == 0 and np.ptp(np.diff(plain.knots.t)) < 1e-12
    for bad in (-1, 13):
        with pytest.raises(BioPlanError, match=f"end_grading must be 0 .* got {bad}"):
            solve_optimal(robot, task.start, task.goal, 1.0, objective="tau_sq", human=spec,
                          n_intervals=16, end_grading=bad)  # fmt: skip


def test_a_work_objective_at_its_floor_stays_within_the_bound_tolerance() -> None:
    """Found when graded ends became the default: on the human arm's `abs_work` (a lift, whose
    floor |ΔPE| every good plan reaches) the human-like optimum's net work on the report grid
    missed ΔPE by 1.5e-3 J, its `abs_work` fell that much below the bound's, and the plan called
    the bound "not a bound" and gave no share. The measured integration error of every method
    (net work against ΔPE, an independent closed quantity) lies within the bound tolerance, and
    the plan has no bound error."""
    from app.planning.methods import BOUND_TOLERANCE
    from app.planning.planner import plan

    robot = load_robot("human_arm_2dof")
    res = plan(robot, objective="abs_work", seed=0,
               methods=("quintic", "paper", "human_optimal", "bound"))  # fmt: skip
    floors = res.floors
    for name, method in res.methods.items():
        ev = method.evaluated
        net = float(np.trapezoid(np.sum(ev.tau * ev.trajectory.qd, axis=-1), ev.trajectory.t))
        assert abs(net - floors.delta_potential) <= BOUND_TOLERANCE * floors.abs_work, name
    assert (res.methods["human_optimal"].solver or {})["end_grading"] > 0
    assert not [w for w in res.warnings if w.startswith("error")], res.warnings
    assert res.share_of_achievable_pct["human_optimal"] == pytest.approx(100.0, abs=0.5)
