"""Optimal control (CasADi + IPOPT): known optima, Pinocchio re-checks and properties.

Every solution is re-evaluated with the project's own Pinocchio dynamics and ``energy_metrics``
on a fine grid, independently of the transcription that produced it.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.errors import BioPlanError
from app.planning import shortest_duration
from app.planning.energy import MotorModel, energy_metrics
from app.planning.evaluation import PlanTask, evaluate_trajectory, phase_boundary_times
from app.planning.optimal import HumanSpec, SolverError, human_spec_peak, solve_optimal
from app.planning.planner import plan
from app.planning.robots import Robot, load_robot

# Two joints about the vertical axis (gravity does no work): with the shoulder held still, the
# elbow is a pure inertia, tau_2 = J qdd_2 with J = I_zz + m d^2 of link 2 about its axis.
SCARA = """<?xml version="1.0"?>
<robot name="scara">
  <link name="base"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="arm"/><origin xyz="0 0 0.5"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="10" effort="500"/>
  </joint>
  <link name="arm"><inertial><origin xyz="0.2 0 0"/><mass value="4"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial></link>
  <joint name="elbow" type="revolute">
    <parent link="arm"/><child link="fore"/><origin xyz="0.4 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="10" effort="500"/>
  </joint>
  <link name="fore"><inertial><origin xyz="0.15 0 0"/><mass value="2"/>
    <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial></link>
</robot>
"""
SCARA_J = 0.02 + 2.0 * 0.15**2  # [kg m^2]


@pytest.fixture(scope="module")
def scara(tmp_path_factory: pytest.TempPathFactory) -> Robot:
    path = tmp_path_factory.mktemp("scara") / "scara.urdf"
    path.write_text(SCARA)
    return load_robot(str(path), payload=0.0)


@pytest.fixture(scope="module")
def human() -> Robot:
    return load_robot("human_arm_2dof")


@pytest.fixture(scope="module")
def human_tau_sq(human: Robot) -> object:
    return plan(
        human, objective="tau_sq", methods=("quintic", "paper", "human_optimal", "bound"),
        particles=20, iterations=40,
    )  # fmt: skip


def _peak_power(robot: Robot, n_intervals: int, end_grading: int = 0) -> float:
    task = PlanTask(np.zeros(2), np.array([0.0, 2.0]))
    sol = solve_optimal(
        robot, task.start, task.goal, 1.0, objective="peak_power",
        human=HumanSpec("none", 1), n_intervals=n_intervals, end_grading=end_grading,
    )  # fmt: skip
    return sol.solver.objective


def test_peak_power_of_a_pure_inertia_approaches_the_constant_power_bound(scara: Robot) -> None:
    """Rest to rest over D in T with |J q̈ q̇| <= P: the kinetic energy can grow at most as P t
    and must fall at most as fast, so the fastest coverage is KE = P t up to T/2 and mirrored:
    q̇ = sqrt(2 P t / J), D = 2 ∫_0^{T/2} q̇ dt = (4/3) sqrt(2 P / J) (T/2)^{3/2}, hence the
    infimum P* = (9/4) J D² / T³. It needs an infinite acceleration at t = 0, so no finite
    transcription reaches it: with a piecewise-linear acceleration the start and stop each lose
    O(h), so on equal intervals the optimum lies above P* by an excess proportional to 1/N,
    halving as N doubles. Graded ends (the default) cut the end intervals into halving pieces
    where that O(h) sits: 40 graded intervals come closer than 80 equal ones, by far."""
    bound = 9.0 / 4.0 * SCARA_J * 2.0**2 / 1.0**3
    excess = {n: _peak_power(scara, n) / bound - 1.0 for n in (40, 80)}
    assert 0.0 < excess[80] < excess[40]
    assert 0.4 < excess[80] / excess[40] < 0.6
    assert excess[80] < 0.09
    graded = _peak_power(scara, 40, end_grading=4) / bound - 1.0
    assert 0.0 < graded < 0.5 * excess[80]


def test_bound_abs_work_reaches_the_lift_floor(human: Robot) -> None:
    """A monotone lift can do no negative work at all (the paper's plan does so): then
    abs_work = pos_work = ΔPE, the floor. The bound must reach it."""
    result = plan(human, objective="abs_work", methods=("quintic", "bound"))
    bound = result.methods["bound"].evaluated.metrics
    floor = result.floors.abs_work
    assert floor <= bound.abs_work * (1 + 1e-6)
    assert bound.abs_work <= floor * 1.0005


def test_bound_below_human_optimal_and_paper(human_tau_sq: object) -> None:
    """The bound is below both human-like methods. The paper's plan is no longer above the
    human-like optimum: its elbow speed stays within 1 % of its peak over more flexion than the
    ``peak`` constraint's one clear peak allows (at most 8 deg), so it lies outside that set."""
    values = human_tau_sq.objective_values  # type: ignore[attr-defined]
    tol = 1e-5 * values["bound"]
    assert values["bound"] <= values["human_optimal"] + tol
    assert values["bound"] <= values["paper"] + tol
    assert values["paper"] < values["quintic"]
    shares = human_tau_sq.share_of_achievable_pct  # type: ignore[attr-defined]
    assert shares["bound"] == 100.0
    assert 0.0 < shares["paper"] <= 100.0 and 0.0 < shares["human_optimal"] <= 100.0


def test_human_peak_holds_on_the_fine_grid(human_tau_sq: object) -> None:
    """Nowhere on the 1000-sample grid is the elbow faster than where it passes 62 deg: the
    elbow's state there is a node of the solution (the peak segment's join), read exactly."""
    ev = human_tau_sq.methods["human_optimal"].evaluated  # type: ignore[attr-defined]
    tr = ev.trajectory
    assert tr.knots is not None
    _, q_nodes, qd_nodes, _ = tr.knots
    at = int(np.argmin(np.abs(q_nodes[:, 1] - math.radians(62.0))))
    assert q_nodes[at, 1] == pytest.approx(math.radians(62.0), abs=1e-6)
    speed = tr.qd[:, 1]
    assert speed.max() <= qd_nodes[at, 1] * (1 + 1e-6)
    lo, hi = ev.peak_velocity_span_deg
    assert lo <= 62.0 + 0.5 <= hi + 1.0


def test_solution_re_evaluated_on_a_fine_grid_keeps_limits_and_objective(
    human: Robot, human_tau_sq: object
) -> None:
    for name in ("human_optimal", "bound"):
        m = human_tau_sq.methods[name]  # type: ignore[attr-defined]
        assert not m.evaluated.violations
        fine = m.evaluated.metrics.tau_sq
        assert fine == pytest.approx(m.solver["objective"], rel=5e-3)
        q = m.trajectory.q
        assert np.all(q >= human.q_min - 1e-9) and np.all(q <= human.q_max + 1e-9)


def test_two_initial_guesses_reach_the_same_optimum(human: Robot, human_tau_sq: object) -> None:
    task = PlanTask.default(human)
    from_quintic = solve_optimal(
        human, task.start, task.goal, 1.0, objective="tau_sq", human=HumanSpec("none", 1)
    )
    from_paper = human_tau_sq.methods["bound"].solver["objective"]  # type: ignore[attr-defined]
    assert from_quintic.solver.warm_start == "quintic"
    assert from_quintic.solver.objective == pytest.approx(from_paper, rel=1e-3)


def test_phase_shares_hold_on_the_fine_grid(human: Robot) -> None:
    result = plan(
        human, objective="tau_sq", methods=("quintic", "human_optimal", "bound"),
        human_constraint="phases",
    )  # fmt: skip
    shares = result.phase_shares
    assert shares is not None and "triangular" in shares.source
    ev = result.methods["human_optimal"].evaluated
    t_ab, t_bc = phase_boundary_times(ev.trajectory, 1, result.task, result.phase_bounds_deg)
    got = np.array([t_ab, t_bc - t_ab, 1.0 - t_bc])
    for value, (lo, hi) in zip(got, shares.bounds, strict=True):
        assert lo - 2e-3 <= value <= hi + 2e-3
    bound = result.methods["bound"].evaluated
    t_ab_b, _ = phase_boundary_times(bound.trajectory, 1, result.task, result.phase_bounds_deg)
    assert not shares.bounds[0][0] <= t_ab_b <= shares.bounds[0][1]  # the constraint binds


def test_electrical_objective_is_exact_with_friction_and_regeneration(human: Robot) -> None:
    """p± slacks give ∫ max(P, 0) − η max(−P, 0) exactly: the solver's value equals the energy
    module's on the fine grid, and a lowering motion regenerates (negative energy)."""
    motors = (MotorModel(50.0, 0.2, 0.5, 2e-5, 0.8, 1.5, 0.6),) * 2
    robot = dataclasses.replace(human, motors=motors)
    task = PlanTask(np.radians([20.0, 150.0]), np.zeros(2))  # lowering
    sol = solve_optimal(
        robot, task.start, task.goal, 1.0, objective="electrical_energy",
        human=HumanSpec("none", 1),
    )  # fmt: skip
    tr = sol.trajectory
    tau = robot.dynamics().inverse_dynamics(tr.q, tr.qd, tr.qdd)
    fine = energy_metrics(tr.t, tr.qd, tau, motors=motors).electrical_energy
    assert fine == pytest.approx(sol.solver.objective, rel=5e-3, abs=0.05)


def test_lowering_no_method_below_its_floor(human: Robot) -> None:
    task = PlanTask(np.radians([20.0, 150.0]), np.radians([0.0, 10.0]))
    result = plan(
        human, task=task, objective="abs_work",
        methods=("quintic", "paper", "human_optimal", "bound", "jerk_limited"),
        particles=16, iterations=30,
    )  # fmt: skip
    fl = result.floors
    assert fl.delta_potential < 0 and fl.abs_work == -fl.delta_potential
    assert fl.peak_power == pytest.approx(fl.abs_work / 1.0)
    for m in result.methods.values():
        metrics = m.evaluated.metrics
        assert metrics.abs_work >= fl.abs_work * (1 - 1e-4)
        assert metrics.peak_power >= fl.peak_power * (1 - 1e-4)
        assert metrics.pos_work >= fl.pos_work - 1e-6
    assert result.methods["bound"].evaluated.metrics.abs_work <= fl.abs_work * 1.001


def test_friction_floor_is_below_every_method_and_tight(tmp_path: Path) -> None:
    """Curtain wall, with friction: the electrical floor (ΔPE + friction work no motion avoids)
    lies below every method, and the electrical bound comes within 10 % of it."""
    robot = load_robot("curtain_wall_6dof")
    result = plan(robot, objective="electrical_energy", methods=("quintic", "bound"))
    fl = result.floors
    assert fl.friction_energy > 0 and fl.electrical_energy > fl.delta_potential
    for m in result.methods.values():
        assert m.evaluated.metrics.electrical_energy >= fl.electrical_energy
    assert result.methods["bound"].evaluated.metrics.electrical_energy <= 1.1 * fl.electrical_energy


def test_infeasible_request_is_a_one_line_error(human: Robot) -> None:
    heavy = human.with_payload(60.0)
    with pytest.raises(SolverError, match=r"infeasible.*torque limits") as info:
        plan(heavy, duration=0.6, methods=("quintic", "bound"))
    assert "\n" not in str(info.value)
    # 60 kg in the hand is more than the elbow can hold still half-way: no duration helps, and
    # the message says where, which joint and how much (checked against Pinocchio's torque).
    task = PlanTask.default(heavy)
    path = task.start + np.linspace(0, 1, 101)[:, None] * (task.goal - task.start)
    static = np.abs(heavy.dynamics().inverse_dynamics(path, 0 * path, 0 * path))[:, 1]
    assert static.max() > heavy.tau_max[1] > static[-1]
    assert "no duration up to 9.6 s is feasible" in str(info.value)
    assert f"needs {static.max():.1f} Nm at joint {heavy.joint_names[1]}, above its 80 Nm" in str(
        info.value
    )


def test_infeasible_request_names_the_shortest_feasible_duration(
    tmp_path: Path, scara: Robot
) -> None:
    """The SCARA's elbow alone, torque-limited to 1 Nm, moving D = 2 rad rest to rest: a pure
    inertia J, so the time-optimal motion is bang-bang, q̈ = ±τ/J, and T* = 2 sqrt(D J / τ)
    (0.721 s). The transcription's acceleration is continuous and piecewise linear, so it needs
    a little longer, O(1/N): the reported shortest duration lies in [T*, 1.06 T*], is solvable,
    and Pinocchio's torques of that solution stay within the limit."""
    weak = tmp_path / "weak.urdf"
    weak.write_text(SCARA.replace('effort="500"/>\n  </joint>\n  <link name="fore"',
                                  'effort="1"/>\n  </joint>\n  <link name="fore"'))  # fmt: skip
    robot = load_robot(str(weak), payload=0.0)
    assert robot.tau_max[1] == 1.0 and robot.tau_max[0] == 500.0
    t_star = 2.0 * math.sqrt(2.0 * SCARA_J / 1.0)
    start, goal = np.zeros(2), np.array([0.0, 2.0])
    with pytest.raises(SolverError, match="torque limit of joint elbow") as info:
        solve_optimal(robot, start, goal, 0.5, objective="abs_work", human=HumanSpec("none", 1))
    assert info.value.infeasible and "\n" not in str(info.value)
    shortest = float(re.search(r"at least ([0-9.]+) s", str(info.value)).group(1))  # type: ignore[union-attr]
    assert t_star <= shortest <= 1.06 * t_star
    feasible = solve_optimal(robot, start, goal, shortest, objective="tau_sq",
                             human=HumanSpec("none", 1))  # fmt: skip
    ev = evaluate_trajectory(robot, feasible.trajectory, PlanTask(start, goal))
    assert not ev.violations
    assert np.abs(ev.tau[:, 1]).max() <= 1.0 + 1e-3
    # The same request with the stock 500 Nm elbow solves: the error was the limit, not the task.
    solve_optimal(scara, start, goal, 0.5, objective="abs_work", human=HumanSpec("none", 1))


def test_the_search_probes_with_capped_warm_started_solves(
    tmp_path: Path, scara: Robot, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Found when a sweep cell took a minute to fail: proving one near-boundary duration
    infeasible took IPOPT 30 s. Every probe of the search is capped at PROBE_ITERATIONS, and each
    one after the first feasible starts from the nearest longer solved motion sped up; the
    hint is still a duration the search solved (the pure-inertia case above, [T*, 1.06 T*])."""
    weak = tmp_path / "weak.urdf"
    weak.write_text(SCARA.replace('effort="500"/>\n  </joint>\n  <link name="fore"',
                                  'effort="1"/>\n  </joint>\n  <link name="fore"'))  # fmt: skip
    robot = load_robot(str(weak), payload=0.0)
    probes: list[tuple[float, object, object, bool]] = []  # duration, cap, warm start, solved
    real = shortest_duration.solve_optimal

    def recorded(*args: Any, **kwargs: Any) -> Any:
        entry = (float(args[3]), kwargs.get("max_iterations"), kwargs.get("warm_start_name"))
        try:
            result = real(*args, **kwargs)
        except SolverError:
            probes.append((*entry, False))
            raise
        probes.append((*entry, True))
        return result

    monkeypatch.setattr(shortest_duration, "solve_optimal", recorded)
    found = shortest_duration.shortest_feasible_duration(
        robot, np.zeros(2), np.array([0.0, 2.0]), 0.5, human=HumanSpec("none", 1),
        n_intervals=40, no_reversal=True,
    )  # fmt: skip
    t_star = 2.0 * math.sqrt(2.0 * SCARA_J / 1.0)
    assert found.duration is not None and t_star <= found.duration <= 1.06 * t_star
    assert len(probes) == found.solves >= 5 and any(not ok for *_, ok in probes)
    assert all(cap == shortest_duration.PROBE_ITERATIONS for _, cap, _, _ in probes)
    for i, (t, _, warm, _) in enumerate(probes):
        longer_solved = any(ok and u > t for u, _, _, ok in probes[:i])
        assert warm == ("longer probe" if longer_solved else "quintic"), (i, t, warm)


def test_max_iterations_caps_ipopt(human: Robot) -> None:
    """``max_iterations`` stops IPOPT there: a solve that needs more raises a not-converged
    (not infeasible) error, the same solve uncapped succeeds, and a cap below 1 is refused."""
    task = PlanTask.default(human)
    spec = human_spec_peak(1, math.radians(62.0))
    full = solve_optimal(human, task.start, task.goal, 1.0, objective="tau_sq", human=spec)
    assert full.solver.iterations > 3
    with pytest.raises(SolverError, match="Maximum_Iterations_Exceeded") as info:
        solve_optimal(human, task.start, task.goal, 1.0, objective="tau_sq", human=spec,
                      max_iterations=3)  # fmt: skip
    assert not info.value.infeasible
    capped = solve_optimal(human, task.start, task.goal, 1.0, objective="tau_sq", human=spec,
                           max_iterations=full.solver.iterations)  # fmt: skip
    assert capped.solver.objective == pytest.approx(full.solver.objective, rel=1e-9)
    with pytest.raises(BioPlanError, match="max_iterations must be >= 1, got 0"):
        solve_optimal(human, task.start, task.goal, 1.0, objective="tau_sq", human=spec,
                      max_iterations=0)  # fmt: skip


def test_no_reversal_keeps_still_joints_still_and_can_be_lifted(human: Robot) -> None:
    """With reversal allowed the shoulder may swing back first; the optimum can only improve."""
    task = PlanTask(np.zeros(2), np.radians([0.0, 150.0]))
    kept = solve_optimal(human, task.start, task.goal, 1.0, objective="tau_sq",
                         human=HumanSpec("none", 1))  # fmt: skip
    free = solve_optimal(human, task.start, task.goal, 1.0, objective="tau_sq",
                         human=HumanSpec("none", 1), no_reversal=False)  # fmt: skip
    assert np.all(kept.trajectory.q[:, 0] == 0.0)
    assert np.abs(free.trajectory.q[:, 0]).max() > 1e-3
    assert free.solver.objective < kept.solver.objective


def test_reused_solver_structure_solves_other_numbers(human: Robot) -> None:
    """The second solve reuses the first one's IPOPT structure with another duration; the
    re-evaluated objective still matches the solver's."""
    task = PlanTask.default(human)
    for duration in (1.0, 1.3):
        sol = solve_optimal(human, task.start, task.goal, duration, objective="tau_sq",
                            human=human_spec_peak(1, math.radians(62.0)))  # fmt: skip
        ev = evaluate_trajectory(human, sol.trajectory, task)
        assert ev.trajectory.t[-1] == pytest.approx(duration)
        assert ev.metrics.tau_sq == pytest.approx(sol.solver.objective, rel=5e-3)
