"""Issue 26: Pareto fronts by optimal control, the shortest feasible duration, the best duration
inside a production cycle.

Checked against things the front does not compute itself: single-objective optima solved apart
(``plan(converge=True)`` and ``solve_optimal``), closed forms on a one-joint arm (the minimum-jerk
quintic, 720 Δ² / T⁵; the torque-limited bang-coast-bang time), ruckig's time-optimal duration.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from app.planning.evaluation import PlanningError, PlanTask, evaluate_trajectory
from app.planning.front import (
    Front,
    check_front_options,
    jerk_integral,
    pareto_front,
    shortest_duration,
    throughput,
)
from app.planning.jerk_limited import _calculate
from app.planning.methods import objective_value
from app.planning.optimal import PEAK_BAND_DEG, HumanSpec, solve_optimal
from app.planning.planner import plan
from app.planning.profiles import quintic
from app.planning.robots import Payload, Robot, load_robot
from app.planning.robots._chain import ChainLink, ChainSpec, urdf_text
from app.planning.robots._types import IDEAL_ACTUATOR

#: The one-joint arm: inertia about its (vertical) axis, stroke, speed and torque limits.
INERTIA, STROKE, SPEED, TORQUE = 0.5, 1.0, 2.0, 4.0


def one_joint_arm(folder: Path) -> Robot:
    """A rod turning about a vertical axis (no gravity torque): I = 0.25 + 1 kg x 0.5² =
    0.5 kg m². A heavy-duty hub joint below it is held still by the task (Pinocchio needs two
    joints), so the motion is the one joint's."""
    spec = ChainSpec(
        name="one_joint",
        base="base",
        links=(
            ChainLink("hub", "hub", (0, 0, 0), (0, 0, 1), -3, 3, SPEED, 1e3, 0.1, (0, 0, 0),
                      (1e-3, 1e-3, 1e-3, 0, 0, 0)),
            ChainLink("j", "arm", (0, 0, 0), (0, 0, 1), -3, 3, SPEED, TORQUE, 1.0, (0.5, 0, 0),
                      (0.01, 0.01, 0.25, 0, 0, 0)),
        ),
    )  # fmt: skip
    path = folder / "one_joint.urdf"
    path.write_text(urdf_text(spec))
    return Robot(
        name="one_joint", joint_names=("hub", "j"), urdf_path=path, mjcf_path=None,
        q_min=[-3, -3], q_max=[3, 3], qd_max=[SPEED, SPEED], tau_max=[1e3, TORQUE],
        motors=(IDEAL_ACTUATOR, IDEAL_ACTUATOR), payload=Payload.point(0.0), payload_body="arm",
        default_start=[0.0, 0.0], default_goal=[0.0, STROKE], shoulder_joint=0, elbow_joint=1,
    )  # fmt: skip


def _non_dominated(front: Front) -> None:
    a, b = front.a, front.b
    values = [(p.values[a], p.values[b]) for p in front.points]
    assert values == sorted(values, key=lambda v: v[0])  # sorted by A ...
    for (a0, b0), (a1, b1) in itertools.pairwise(values):
        assert a1 >= a0 and b1 <= b0 * (1 + 1e-6) + 1e-12  # ... so B falls: none dominates
    for p in front.points:
        assert not p.violations, p.violations
        # Converged to 0.1 %, or (the 6-DOF's tau_sq) still moving by less than 0.5 % at the
        # finest mesh: the evidence is stated either way.
        conv = p.convergence
        # The shortest duration's point sits on the edge of feasibility (the one-joint arm's
        # jerk there still moves 0.55 % from 160 to 320 intervals): its evidence is stated.
        assert conv["converged"] or conv["relative_change"] < 5e-3 or p.role == "duration end"
        assert conv["sequence"][-1]["n_intervals"] == conv["final_intervals"]


def test_the_options_are_checked_naming_the_option() -> None:
    with pytest.raises(PlanningError, match="unknown metric 'energy'"):
        check_front_options("tau_sq,energy", points=3, method="bound", duration=1.0)
    with pytest.raises(PlanningError, match="the same metric twice"):
        check_front_options("jerk,jerk", points=3, method="bound", duration=1.0)
    with pytest.raises(PlanningError, match="--points 1"):
        check_front_options("jerk,tau_sq", points=1, method="bound", duration=1.0)
    with pytest.raises(PlanningError, match="--duration is fixed"):
        check_front_options("duration,tau_sq", points=3, method="bound", duration=1.0)
    assert check_front_options("tau_sq, duration", points=2, method="bound", duration=None) == (
        "tau_sq",
        "duration",
    )


def test_jerk_integral_is_exact_on_the_quintic() -> None:
    """∫ q⃛² dt of the minimum-jerk quintic is 720 Δ² / T⁵ (Δ = 1 rad, T = 1.3 s)."""
    tr = quintic(np.zeros(1), np.ones(1), 1.3, n_samples=4001)
    assert jerk_integral(tr) == pytest.approx(720 / 1.3**5, rel=1e-5)


def test_front_on_the_2dof_is_non_dominated_with_the_single_objective_optima_at_its_ends() -> None:
    robot = load_robot("human_arm_2dof", payload=5.0)
    front = pareto_front(robot, objectives="tau_sq,jerk", duration=1.0, points=3)
    _non_dominated(front)
    assert len(front.points) == 3 and front.knee == 1
    assert front.points[0].role == "A end" and front.points[-1].role == "B end"
    # A jerk axis keeps equal intervals (graded ends would put the tau_sq end's jerk in pieces).
    assert all(p.convergence["end_grading"] == 0 for p in front.points)
    # The tau_sq end against the converged bound of plan() on tau_sq.
    alone = plan(
        robot, duration=1.0, objective="tau_sq", methods=["quintic", "bound"], converge=True
    )
    assert front.points[0].values["tau_sq"] == pytest.approx(
        alone.objective_values["bound"], rel=5e-3
    )
    # The jerk end against a fine-mesh jerk solve from the quintic.
    task = PlanTask.default(robot)
    fine = solve_optimal(
        robot, task.start, task.goal, 1.0, objective="jerk",
        human=HumanSpec("none", robot.elbow_joint), n_intervals=160,
    )  # fmt: skip
    assert front.points[-1].values["jerk"] == pytest.approx(
        jerk_integral(fine.trajectory), rel=5e-3
    )
    # The interior point keeps its bound and lies strictly between the ends.
    mid = front.points[1]
    assert mid.epsilon is not None and mid.values["jerk"] <= mid.epsilon * (1 + 2e-3)
    d = front.to_dict()
    assert d["knee"] == "p1" and [p["knee"] for p in d["points"]] == [False, True, False]
    assert {"tau_sq", "abs_work", "peak_power", "jerk", "duration", "peak_torques"} <= set(
        d["points"][1]
    )


def test_an_end_beaten_by_its_neighbour_on_a_coarse_tolerance_is_replaced_and_said() -> None:
    """Found on the page: on a coarse tolerance the abs_work end's own solve was dominated by
    its neighbour and dropped, leaving a front without an "A end". The neighbour is the best
    known abs_work optimum: it is marked as the end, and the note says why."""
    robot = load_robot("human_arm_2dof")
    front = pareto_front(
        robot, objectives="abs_work,peak_torque", duration=1.0, points=3, n_intervals=8,
        tolerance=0.05,
    )  # fmt: skip
    assert front.points[0].role == "A end" and front.points[-1].role == "B end"
    # Without a jerk axis every point's mesh has graded ends (L = 5 on 8 intervals).
    assert all(p.convergence["end_grading"] == 5 for p in front.points)
    ends = front.to_dict()["ends"]
    assert ends["abs_work"] == min(p.values["abs_work"] for p in front.points)
    for drop in front.dropped:
        if "dominated" in drop["why"] and drop["epsilon"] is None:  # an end's own solve
            assert any("now the A end" in n or "now the B end" in n for n in front.notes)


def test_human_optimal_front_is_more_human_like_than_the_bound_front() -> None:
    """--method changes the result: the human-like front puts the elbow's speed peak at the
    template's 62 deg of flexion (within the constraint's band) and costs more at its ends."""
    robot = load_robot("human_arm_2dof", payload=5.0)
    bound = pareto_front(robot, objectives="tau_sq,jerk", duration=1.0, points=2, tolerance=1e-2)
    human = pareto_front(
        robot, objectives="tau_sq,jerk", duration=1.0, points=2, tolerance=1e-2,
        method="human_optimal",
    )  # fmt: skip
    _non_dominated(human)
    assert human.points[0].values["tau_sq"] >= bound.points[0].values["tau_sq"] * (1 - 1e-3)
    for p in human.points:
        assert abs(p.evaluated.peak_velocity_angle_deg - 62.0) <= PEAK_BAND_DEG
    assert abs(bound.points[0].evaluated.peak_velocity_angle_deg - 62.0) > PEAK_BAND_DEG
    assert any("human-like" in r for r in human.rules)


@pytest.mark.slow
def test_front_on_the_6dof_is_non_dominated_with_the_single_objective_optima_at_its_ends() -> None:
    robot = load_robot("curtain_wall_6dof", payload=4.0)
    front = pareto_front(robot, objectives="tau_sq,jerk", duration=1.0, points=3)
    _non_dominated(front)
    alone = plan(
        robot, duration=1.0, objective="tau_sq", methods=["quintic", "bound"], converge=True
    )
    assert front.points[0].values["tau_sq"] == pytest.approx(
        alone.objective_values["bound"], rel=5e-3
    )
    task = PlanTask.default(robot)
    fine = solve_optimal(
        robot, task.start, task.goal, 1.0, objective="jerk",
        human=HumanSpec("none", robot.elbow_joint), n_intervals=160,
    )  # fmt: skip
    assert front.points[-1].values["jerk"] == pytest.approx(
        jerk_integral(fine.trajectory), rel=5e-3
    )


def test_duration_front_of_a_one_joint_arm_follows_the_closed_forms(tmp_path: Path) -> None:
    """Minimum jerk in T seconds is the quintic, 720 Δ² / T⁵, wherever the quintic keeps the
    limits (T >= 1.875 Δ / v and I · 5.77 Δ / T² <= τ_max); the shortest duration is the
    bang-coast-bang time Δ / v + v / a with a = τ_max / I (0.75 s), from above (q̈ must ramp
    over an interval of the mesh)."""
    robot = one_joint_arm(tmp_path)
    front = pareto_front(robot, objectives="jerk,duration", points=3, max_duration=2.25)
    _non_dominated(front)
    a = TORQUE / INERTIA
    closed = STROKE / SPEED + SPEED / a
    shortest = front.shortest_duration
    assert shortest is not None
    assert closed <= shortest.duration <= closed * 1.04
    assert front.points[-1].values["duration"] == pytest.approx(shortest.duration, rel=1e-9)
    quintic_ok = [p for p in front.points if p.values["duration"] >= 1.875 * STROKE / SPEED]
    assert len(quintic_ok) == 2
    for p in quintic_ok:
        t = p.values["duration"]
        assert p.values["jerk"] == pytest.approx(720 * STROKE**2 / t**5, rel=5e-3)
    # --max-duration changes the front: the jerk end is at the longest duration.
    assert front.points[0].values["duration"] == pytest.approx(2.25)


def test_shortest_duration_matches_ruckig_without_torque_limits() -> None:
    """With the controller's velocity, acceleration and jerk limits and no torque limit, the
    shortest duration is ruckig's time-optimal one, from above (a constant-jerk mesh cannot
    switch exactly where ruckig does)."""
    robot = load_robot("human_arm_2dof", payload=5.0)
    free = dataclasses.replace(robot, tau_max=np.full(2, 1e6))
    task = PlanTask.default(free)
    ruckig = float(_calculate(free, task.start, task.goal, None).duration)  # type: ignore[attr-defined]
    # No actuator envelopes either (the built-in arm's would cap the torque at speed).
    found = shortest_duration(free, task, controller_limits=True, actuators=None)
    assert ruckig * (1 - 1e-6) <= found.duration <= ruckig * 1.01
    assert "joint jerk" in found.rules
    # Without the controller limits it is shorter: those limits are what binds.
    assert shortest_duration(free, task, actuators=None).duration < 0.9 * ruckig


def test_throughput_picks_a_duration_that_beats_the_quintic_per_cycle() -> None:
    """tau_sq per cycle: the motion plus the static torques squared over the hold. The quintic
    of the whole free time is evaluated here independently; the optimum is no worse than the
    quintic and a longer dwell (less free time) cannot lower it."""
    robot = load_robot("human_arm_2dof", payload=5.0)
    task = PlanTask.default(robot)
    res = throughput(
        robot, objective="tau_sq", cycle_rate=1800, dwell=0.5, points=3,
        tolerance=5e-2, n_intervals=16,
        actuators=None,  # the envelopes would solve the shortest motions twice (kept lazily)
    )  # fmt: skip
    cycle = 2.0
    assert res.cycle == pytest.approx(cycle)
    assert res.shortest_duration <= res.duration <= cycle - 0.5 + 1e-9
    q = quintic(task.start, task.goal, cycle - 0.5, n_samples=1000)
    ev = evaluate_trajectory(robot, q, task)
    zero = np.zeros((1, 2))
    hold = np.sum(robot.dynamics().inverse_dynamics(task.goal[None, :], zero, zero) ** 2) * 0.5
    assert res.quintic_per_cycle == pytest.approx(
        objective_value(robot, ev, "tau_sq") + hold, rel=1e-6
    )
    assert res.per_cycle <= min(v for _, v in res.scanned) + 1e-9
    assert res.saving_pct > 0 and res.per_cycle < res.quintic_per_cycle
    longer = throughput(
        robot, objective="tau_sq", cycle_rate=1800, dwell=1.0, points=3,
        tolerance=5e-2, n_intervals=16,
        actuators=None,  # the envelopes would solve the shortest motions twice (kept lazily)
    )  # fmt: skip
    assert longer.duration <= 1.0 + 1e-9 and longer.quintic_duration == pytest.approx(1.0)
    assert longer.per_cycle != pytest.approx(res.per_cycle, rel=1e-4)
    with pytest.raises(PlanningError, match="--cycle-rate"):
        throughput(robot, objective="tau_sq", cycle_rate=36000, dwell=0.0)
    with pytest.raises(PlanningError, match="--dwell"):
        throughput(robot, objective="tau_sq", cycle_rate=100, dwell=-1.0)
    assert math.isfinite(res.saving_pct)
