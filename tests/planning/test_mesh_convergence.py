"""Converged optimal-control results (issue 25, items 1 and 6).

The error estimate against closed-form sequences; converged values against independent solves on
a much finer mesh from the quintic (not from the refinement chain); the per-point dynamics
compiled to C against the interpreted one and against Pinocchio; a refined mesh warm-started
from the coarser optimum against the same mesh solved cold.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from app.planning import jit_cache, optimal
from app.planning.evaluation import PlanTask, evaluate_trajectory
from app.planning.methods import (
    MethodResult,
    human_spec,
    mesh_error_estimate,
    objective_value,
    run_optimal,
)
from app.planning.optimal import HumanSpec, solve_optimal
from app.planning.planner import plan
from app.planning.profiles import quintic
from app.planning.robots import load_robot

#: The issue's target: within 0.3 % of the mesh-converged optimum.
TARGET = 3e-3


@pytest.mark.parametrize("order", [1, 2])
def test_error_estimate_is_exact_on_power_law_sequences(order: int) -> None:
    """J(N) = J* + C / N^p on N, 2N, 4N: Richardson's estimate of the last value's error is
    exact for first and second order."""
    star, c = 100.0, 500.0
    values = [star + c / n**order for n in (20, 40, 80)]
    estimate, extrapolated = mesh_error_estimate(values)
    size = max(abs(values[-2]), abs(values[-1]))
    assert extrapolated
    assert estimate == pytest.approx(abs(values[-1] - star) / size, rel=1e-12)


def test_error_estimate_is_conservative_or_the_last_change() -> None:
    # Third order: the ratio 8 is capped at 4 (second order), so the estimate is above the error.
    values = [100.0 + 500.0 / n**3 for n in (20, 40, 80)]
    estimate, extrapolated = mesh_error_estimate(values)
    assert extrapolated and estimate > abs(values[-1] - 100.0) / values[-2]
    # Changes that do not shrink by half (slower than first order, or oscillating): the last
    # change, never less.
    for seq in ([110.0, 105.0, 101.0], [110.0, 100.0, 104.0]):
        estimate, extrapolated = mesh_error_estimate(seq)
        assert not extrapolated
        assert estimate == pytest.approx(abs(seq[2] - seq[1]) / max(seq[1], seq[2]))
    assert mesh_error_estimate([110.0, 100.0]) == (pytest.approx(10.0 / 110.0), False)
    assert math.isnan(mesh_error_estimate([1.0])[0])


def _fine(
    robot_name: str,
    objective: str,
    n_intervals: int,
    spec: HumanSpec | None,
    end_grading: int | None = None,
) -> float:
    """An independent solve from the quintic on ``n_intervals`` (graded ends: ``end_grading``,
    None = the default for that mesh), on the plan's report grid."""
    robot = load_robot(robot_name)
    task = PlanTask.default(robot)
    human = spec or HumanSpec("none", robot.elbow_joint)
    sol = solve_optimal(
        robot, task.start, task.goal, 1.0, objective=objective, human=human,
        n_intervals=n_intervals, end_grading=end_grading,
    )  # fmt: skip
    return objective_value(robot, evaluate_trajectory(robot, sol.trajectory, task), objective)


@pytest.mark.parametrize(
    ("robot_name", "objective"),
    [
        ("human_arm_2dof", "tau_sq"),
        ("human_arm_2dof", "abs_work"),
        ("human_arm_2dof", "pos_work"),
        ("human_arm_2dof", "electrical_energy"),
        ("curtain_wall_6dof", "electrical_energy"),
    ],
)
def test_converged_bound_is_within_the_target_of_a_much_finer_solve(
    robot_name: str, objective: str
) -> None:
    """From a coarse 16-interval mesh, the bound refines until converged; an independent solve
    on four times the final mesh agrees within 0.3 %, and the stated error estimate is
    honest (the distance to the finer solve is within it, plus the finer solve's own error)."""
    res = plan(
        load_robot(robot_name), objective=objective, particles=6, iterations=4,
        methods=("quintic", "bound"), n_intervals=16, converge=True,
    )  # fmt: skip
    conv = res.to_dict()["methods"]["bound"]["solver"]["convergence"]
    assert conv["converged"], conv
    value = res.objective_values["bound"]
    fine = _fine(robot_name, objective, 4 * conv["final_intervals"], None)
    assert abs(value - fine) / abs(fine) <= TARGET, (value, fine, conv)
    # The finer mesh is nested in no coarser one here (another start), but a bound on more
    # intervals is lower up to the solver's tolerance.
    assert fine <= value * (1 + 1e-4)
    assert abs(value - fine) / abs(fine) <= 2 * max(conv["error_estimate"], 1e-4)


def test_human_optimal_carries_honest_evidence_on_the_2dof_tau_sq() -> None:
    """``human_optimal`` carries the same evidence. On equal intervals its peak rule made the
    refinement slow (measured: 2330, 1903, 1856, 1840, 1827 on 20 ... 320 intervals: the
    segment joins kink the optimum); should it not converge, the result must say so, with the
    last change as its error estimate, and report the finest mesh's value."""
    robot = load_robot("human_arm_2dof")
    res = plan(
        robot, objective="tau_sq", particles=6, iterations=4,
        methods=("quintic", "paper", "human_optimal"), n_intervals=20, converge=True,
    )  # fmt: skip
    conv = res.to_dict()["methods"]["human_optimal"]["solver"]["convergence"]
    seq = conv["sequence"]
    values = [s["objective"] for s in seq]
    assert [s["n_intervals"] for s in seq] == [20 * 2**i for i in range(len(seq))]
    estimate, _ = mesh_error_estimate(values)
    assert conv["error_estimate"] == pytest.approx(estimate, rel=1e-12)
    assert conv["converged"] == (estimate < conv["tolerance"])
    if not conv["converged"]:
        assert seq[-1]["n_intervals"] == 320  # refined up to the limit
    # Not a bound: the finest mesh's value is reported, whether or not it is the lowest.
    assert res.objective_values["human_optimal"] == pytest.approx(values[-1], rel=1e-12)
    # Against an independent solve with the same constraint on the final mesh from the quintic:
    # the same optimum within the stated error estimate.
    task = PlanTask.default(robot)
    e = robot.elbow_joint
    q_via = res.template.peak_joint_angle(float(task.start[e]), float(task.goal[e]))
    spec, _ = human_spec("peak", robot, task, res.template, q_via)
    # The same mesh: the refinement keeps its first mesh's graded ends.
    grading = res.methods["human_optimal"].solver["end_grading"]
    again = _fine("human_arm_2dof", "tau_sq", conv["final_intervals"], spec, grading)
    assert abs(values[-1] - again) / again <= max(conv["error_estimate"], TARGET)


def test_compiled_dynamics_give_the_interpreted_optimum(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """From :data:`optimal.COMPILE_FROM_POINTS` points the per-point dynamics is compiled to C:
    the same optimum and iterations as interpreted, its torques are Pinocchio's, and nothing is
    written to the working directory (CasADi's default for its C sources and libraries)."""
    monkeypatch.chdir(tmp_path)
    optimal._COMPILED.clear()
    arm = load_robot("human_arm_2dof")
    arm_task = PlanTask.default(arm)

    def solve() -> optimal.OptimalResult:
        return solve_optimal(
            arm, arm_task.start, arm_task.goal, 1.0, objective="tau_sq",
            human=HumanSpec("none", arm.elbow_joint), n_intervals=320,
        )  # fmt: skip

    optimal._SOLVERS.clear()
    compiled = solve()  # 320 intervals x 5 points: compiled
    assert "reduced_dynamics_c" in {f.name() for f in optimal._COMPILED.values()}
    monkeypatch.setenv(jit_cache.CACHE_ENV, "off")  # no cache: compiled from the threshold only
    monkeypatch.setattr(optimal, "COMPILE_FROM_POINTS", 10**9)
    optimal._SOLVERS.clear()
    interpreted = solve()
    optimal._SOLVERS.clear()
    assert compiled.solver.objective == pytest.approx(interpreted.solver.objective, rel=1e-9)
    assert compiled.solver.iterations == interpreted.solver.iterations
    # The compiled function itself against Pinocchio's RNEA at random states (free joints of
    # the 6-DOF arm; the held ones folded in at their start angles).
    robot = load_robot("curtain_wall_6dof")
    task = PlanTask.default(robot)
    spec = HumanSpec("none", robot.elbow_joint)
    warm = quintic(task.start, task.goal, 1.0, n_samples=51)
    problem = optimal._problem(robot, task.start, task.goal, 1.0, "tau_sq", spec, warm, 40, True)
    fn = optimal._compiled(problem)
    assert fn.name() == "reduced_dynamics_c"
    free = list(problem.free)
    rng = np.random.default_rng(3)
    dyn = robot.dynamics()
    for _ in range(5):
        q, qd, qdd = task.start.copy(), np.zeros(robot.n_joints), np.zeros(robot.n_joints)
        q[free] += rng.uniform(-0.5, 0.5, len(free))
        qd[free], qdd[free] = rng.normal(size=len(free)), rng.normal(size=len(free))
        got = np.asarray(fn(q[free], qd[free], qdd[free])).ravel()
        want = dyn.inverse_dynamics(q[None], qd[None], qdd[None])[0]
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
    assert list(tmp_path.iterdir()) == []


def test_refined_mesh_from_the_coarser_optimum_is_the_cold_optimum() -> None:
    """``near_optimum`` (a small initial barrier parameter from the coarser optimum) reaches
    the optimum of the same mesh solved from the quintic."""
    robot = load_robot("human_arm_2dof")
    task = PlanTask.default(robot)
    spec = HumanSpec("none", robot.elbow_joint)
    common = {"name": "bound", "duration": 1.0, "objective": "peak_power", "spec": spec,
              "no_reversal": True, "report_samples": 1000}  # fmt: skip
    coarse = run_optimal(robot, task, warm=None, n_intervals=40, **common)  # type: ignore[arg-type]
    warm = run_optimal(robot, task, warm=coarse, n_intervals=80, near_optimum=True, **common)  # type: ignore[arg-type]
    cold = run_optimal(robot, task, warm=None, n_intervals=80, **common)  # type: ignore[arg-type]
    assert isinstance(warm, MethodResult)
    a = objective_value(robot, warm.evaluated, "peak_power")
    b = objective_value(robot, cold.evaluated, "peak_power")
    # Peak power has nearby local optima on one mesh (measured 98.945 vs 98.928 W here): the
    # same optimum within the refinement's tolerance, and below the coarser one.
    assert a == pytest.approx(b, rel=1e-3)
    assert a < objective_value(robot, coarse.evaluated, "peak_power")
