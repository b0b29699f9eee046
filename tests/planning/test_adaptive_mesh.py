"""Non-uniform intervals and adaptive mesh refinement of the optimal control (issue 25, items 1
and 6).

Equal weights against the solver without weights; a graded mesh's solution re-evaluated with
Pinocchio on the report grid (limits kept, the objective the solver's); the adaptive refinement
of the human arm's bound against an independent solve on a much finer uniform mesh; bad
weights named in the error.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest

from app.errors import BioPlanError
from app.planning.evaluation import PlanTask, evaluate_trajectory
from app.planning.methods import (
    MethodResult,
    mesh_of,
    objective_value,
    refine_to_convergence,
    refined_mesh,
    run_optimal,
)
from app.planning.optimal import HumanSpec, solve_optimal
from app.planning.robots import load_robot

#: The issue's target: within 0.3 % of the mesh-converged optimum.
TARGET = 3e-3


def _arm() -> tuple[Any, PlanTask, HumanSpec]:
    robot = load_robot("human_arm_2dof")
    return robot, PlanTask.default(robot), HumanSpec("none", robot.elbow_joint)


def _peak_spec(robot: Any, task: PlanTask) -> HumanSpec:
    from app.planning.human_template import HumanTemplate
    from app.planning.methods import human_spec

    template = HumanTemplate()  # the paper's default: the elbow's speed peak at 62 deg
    e = robot.elbow_joint
    q_via = template.peak_joint_angle(float(task.start[e]), float(task.goal[e]))
    return human_spec("peak", robot, task, template, q_via)[0]


@pytest.mark.parametrize("human_kind", ["none", "peak"])
def test_equal_weights_give_the_solution_without_weights(human_kind: str) -> None:
    """Equal weights (any scale) and the default segment counts are today's mesh: the same
    optimum to 1e-9, the same node times."""
    robot, task, spec = _arm()
    if human_kind == "peak":
        spec = _peak_spec(robot, task)
    common: dict[str, Any] = {"objective": "tau_sq", "human": spec, "n_intervals": 40}
    plain = solve_optimal(robot, task.start, task.goal, 1.0, **common, end_grading=0)
    h = np.diff(plain.knots.t)
    # Today's segment counts, read off the solution (segments of equal intervals).
    joins = np.cumsum(plain.solver.segment_durations)[:-1]
    nodes = [int(np.argmin(np.abs(plain.knots.t - j))) for j in joins]
    counts = np.diff([0, *nodes, 40])
    weighted = solve_optimal(
        robot, task.start, task.goal, 1.0, **common,
        interval_weights=np.full(40, 3.0), segment_counts=counts,
    )  # fmt: skip
    assert weighted.solver.objective == pytest.approx(plain.solver.objective, rel=1e-9)
    np.testing.assert_allclose(weighted.knots.t, plain.knots.t, rtol=0, atol=1e-9)
    assert len(set(np.round(h[: counts[0]], 12))) == 1  # equal within a segment


@pytest.mark.parametrize("objective", ["tau_sq", "peak_power"])
def test_graded_mesh_keeps_every_limit_and_its_objective(objective: str) -> None:
    """A mesh graded towards both ends (intervals from 1/8 to 1 of the largest): the node
    times follow the weights; Pinocchio on the 1000-sample report grid finds no violation and
    the metric the solver minimised; and it beats the uniform mesh of as many intervals (the
    ends, where rest to rest kinks the optimum, are where the error sits)."""
    robot, task, spec = _arm()
    weights = np.array([1, 2, 4, 8, *[8] * 16, 8, 4, 2, 1], dtype=float)
    n = weights.size
    graded = solve_optimal(
        robot, task.start, task.goal, 1.0, objective=objective, human=spec, n_intervals=n,
        interval_weights=weights,
    )  # fmt: skip
    np.testing.assert_allclose(np.diff(graded.knots.t), weights / weights.sum(), atol=1e-9)
    ev = evaluate_trajectory(robot, graded.trajectory, task)
    assert ev.violations == ()
    tau_ratio = np.abs(ev.tau) / robot.tau_max
    assert tau_ratio.max() <= 1.0
    assert np.all(np.abs(graded.trajectory.qd) <= robot.qd_max * (1 + 1e-9))
    stroke = np.sign(task.goal - task.start)
    assert np.all(graded.trajectory.qd * stroke >= -1e-6 * robot.qd_max)  # no reversal
    value = objective_value(robot, ev, objective)
    assert value == pytest.approx(graded.solver.objective, rel=3e-3)
    uniform = solve_optimal(
        robot,
        task.start,
        task.goal,
        1.0,
        objective=objective,
        human=spec,
        n_intervals=n,
        end_grading=0,
    )
    assert value < objective_value(robot, evaluate_trajectory(robot, uniform.trajectory, task),
                                   objective)  # fmt: skip


def test_bad_weights_are_named() -> None:
    robot, task, spec = _arm()
    with pytest.raises(BioPlanError, match="interval_weights: expected 16 positive"):
        solve_optimal(robot, task.start, task.goal, 1.0, objective="tau_sq", human=spec,
                      n_intervals=16, interval_weights=np.ones(15))  # fmt: skip
    with pytest.raises(BioPlanError, match="interval_weights: expected 16 positive"):
        solve_optimal(robot, task.start, task.goal, 1.0, objective="tau_sq", human=spec,
                      n_intervals=16, interval_weights=np.r_[np.ones(15), 0.0])  # fmt: skip
    with pytest.raises(BioPlanError, match="segment_counts"):
        solve_optimal(robot, task.start, task.goal, 1.0, objective="tau_sq", human=spec,
                      n_intervals=16, segment_counts=(8, 8))  # fmt: skip
    shape = HumanSpec("shape", robot.elbow_joint, band=((0.0, 0.5, 1.0),) * 3, peak_time=0.5)
    graded = np.r_[np.ones(8), np.full(8, 2.0)]
    with pytest.raises(BioPlanError, match="'shape' human constraint needs equal intervals"):
        solve_optimal(robot, task.start, task.goal, 1.0, objective="tau_sq", human=shape,
                      n_intervals=16, interval_weights=graded)  # fmt: skip


@pytest.mark.parametrize("objective", ["tau_sq", "peak_power"])
def test_adaptive_bound_converges_below_a_finer_uniform_solve(objective: str) -> None:
    """From 16 intervals the bound refines adaptively until its error estimate is below the
    tolerance, on fewer intervals than the independent uniform 320-interval solve from the
    quintic, within 0.3 % of it or below it (the meshes are nested, so a lower bound value
    is the more accurate one; measured: peak power 97.2 W against the uniform 320's 97.5 W,
    whose error is the rest-to-rest ends'). Every mesh halves only some intervals, keeps
    every coarse node, and the bound's sequence never rises."""
    robot, task, spec = _arm()
    common: dict[str, Any] = {
        "name": "bound", "duration": 1.0, "objective": objective, "spec": spec,
        "no_reversal": True, "report_samples": 1000,
    }  # fmt: skip
    # Equal weights: refinement from today's equal mesh (graded ends are a fixed grading).
    coarse = run_optimal(robot, task, warm=None, n_intervals=16, interval_weights=[1.0] * 16,
                         **common)  # fmt: skip
    # One refinement step by hand: nested, and not a doubling.
    n, lengths, counts, split = refined_mesh(robot, coarse, objective, True, task)
    assert counts == (n,) and 16 < n < 32 and 0 < split < 16
    t, _ = mesh_of(coarse)
    fine_nodes = np.concatenate([[0.0], np.cumsum(lengths)])
    for node in t / t[-1]:
        assert np.min(np.abs(fine_nodes - node)) < 1e-9
    refined = refine_to_convergence(
        robot, task, coarse, duration=1.0, objective=objective, spec=spec, no_reversal=True,
        report_samples=1000, keep_lowest=True, adaptive=True,
    )  # fmt: skip
    assert isinstance(refined, MethodResult)
    conv = refined.solver["convergence"]
    assert conv["converged"] and conv["adaptive"], conv
    seq = conv["sequence"]
    values = [s["objective"] for s in seq]
    assert all(b <= a * (1 + 1e-6) for a, b in itertools.pairwise(values)), values
    assert any(s["smallest_interval"] < 0.5 * s["largest_interval"] for s in seq[1:])
    value = objective_value(robot, refined.evaluated, objective)
    assert value == pytest.approx(values[-1], rel=1e-12)
    assert refined.evaluated.violations == ()
    uniform = solve_optimal(robot, task.start, task.goal, 1.0, objective=objective, human=spec,
                            n_intervals=320, end_grading=0)  # fmt: skip
    fine = objective_value(robot, evaluate_trajectory(robot, uniform.trajectory, task), objective)
    assert conv["final_intervals"] < 320
    assert value <= fine * (1 + TARGET), (value, fine, conv)
    assert value >= fine * (1 - 2 * TARGET), (value, fine, conv)


def test_error_estimate_of_a_non_halving_sequence_is_the_geometric_tail() -> None:
    """Adaptive steps halve only some intervals, so the changes may shrink slower than by half:
    J = J* + C q^k with q = 2/3 has the tail d / (r − 1) = 2 d, larger than the last change d,
    and exact; with ``halving`` (uniform doubling) the same sequence falls back to d."""
    from app.planning.methods import mesh_error_estimate

    star, c, q = 100.0, 9.0, 2.0 / 3.0
    values = [star + c * q**k for k in range(3)]
    size = max(values[-2], values[-1])
    estimate, extrapolated = mesh_error_estimate(values, halving=False)
    assert extrapolated
    assert estimate == pytest.approx((values[-1] - star) / size, rel=1e-12)
    assert estimate == pytest.approx(2 * (values[-2] - values[-1]) / size, rel=1e-12)
    plain, extrapolated = mesh_error_estimate(values)
    assert not extrapolated and plain == pytest.approx((values[-2] - values[-1]) / size)
