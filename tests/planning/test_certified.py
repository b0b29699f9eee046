"""Issue 25: the bound truly bounds, says what it obeys; one clear human-like peak; plain floors.

``BIOPLAN_BOUND_TASKS`` sets how many random tasks per robot the order test plans (default 2 in
the default run, to keep the suite's time; 5 or more for a closer look), ``BIOPLAN_BOUND_SEED``
their seed (default 25).
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest

from app.planning.energy import FLOOR_NOTES, NO_FLOOR, floors
from app.planning.evaluation import PlanningError, elbow_flexion_deg
from app.planning.human_constraints import (
    LIKENESS_POINTS,
    human_likeness_distance,
    template_speed_on_stroke,
)
from app.planning.human_template import HumanTemplate
from app.planning.jerk_limited import JerkLimitedError
from app.planning.methods import (
    BOUND_TOLERANCE,
    BoundViolation,
    bound_rules,
    rule_breach,
    share_of_achievable_pct,
)
from app.planning.optimal import PEAK_BAND_DEG, SolverError
from app.planning.planner import PlanResult, PlanTask, plan
from app.planning.robots import load_robot

ROBOTS = ("human_arm_2dof", "curtain_wall_6dof")
OBJECTIVES = ("tau_sq", "abs_work", "pos_work", "electrical_energy", "peak_power", "peak_torque")
N_TASKS = int(os.environ.get("BIOPLAN_BOUND_TASKS", "2"))
SEED = int(os.environ.get("BIOPLAN_BOUND_SEED", "25"))
#: Where the peak may sit on the fine grid, against the template angle [deg].
PEAK_ANGLE_TOLERANCE_DEG = 1.0


def _random_tasks(robot_name: str, seed: int) -> list[tuple[float, float, bool, str]]:
    rng = np.random.default_rng(seed)
    return [
        (
            float(rng.uniform(0.75, 3.0)),
            float(rng.uniform(0.0, 12.0)),
            bool(rng.random() < 0.5),
            str(rng.choice(OBJECTIVES)),
        )
        for _ in range(N_TASKS)
    ]


@pytest.mark.parametrize("robot_name", ROBOTS)
def test_bound_is_below_every_method_on_random_tasks(robot_name: str) -> None:
    """Lifting and lowering, 0.75-3 s, 0-12 kg, every objective (seeded): no method under the
    bound's rules is below it by more than round-off, and no share is above 100 %."""
    planned = 0
    for duration, payload, lowering, objective in _random_tasks(robot_name, seed=SEED):
        robot = load_robot(robot_name, payload=payload)
        task = PlanTask.default(robot)
        if lowering:
            task = PlanTask(task.goal, task.start)
        try:
            res = plan(
                robot, task=task, duration=duration, objective=objective, particles=8,
                iterations=10, report_samples=500,
                methods=("quintic", "paper", "human_optimal", "bound", "jerk_limited"),
            )  # fmt: skip
        except (PlanningError, JerkLimitedError) as exc:
            assert "infeasible" in str(exc) or "needs at least" in str(exc), exc
            continue
        except SolverError as exc:
            assert exc.infeasible, exc
            continue
        planned += 1
        values, bound = res.objective_values, res.objective_values["bound"]
        cert = res.methods["bound"].solver["certificate"]  # type: ignore[index]
        assert cert["beaten_by"] == []
        for name, value in values.items():
            if name not in cert["outside_rules"]:
                size = max(abs(bound), abs(values["quintic"]))
                assert value >= bound - BOUND_TOLERANCE * size, (name, objective)
        assert all(s <= 100.0 for s in res.share_of_achievable_pct.values() if not math.isnan(s))
        assert not [w for w in res.warnings if w.startswith("error")]
    assert planned >= 1


def test_share_is_never_above_100_pct() -> None:
    assert share_of_achievable_pct(10.0, 8.0, 5.0) == pytest.approx(40.0)
    # On the bound within round-off: exactly 100.
    assert share_of_achievable_pct(10.0, 5.0 * (1 - 1e-7), 5.0) == 100.0
    with pytest.raises(BoundViolation, match="does not bound"):
        share_of_achievable_pct(10.0, 4.9, 5.0)
    assert math.isnan(share_of_achievable_pct(10.0, 9.99, 9.999))  # nothing to achieve


@pytest.fixture(scope="module")
def human_bounds() -> PlanResult:
    robot = load_robot("human_arm_2dof")
    return plan(
        robot, objective="tau_sq", particles=8, iterations=10,
        methods=("quintic", "paper", "bound", "bound_unrestricted"),
    )  # fmt: skip


def test_unrestricted_bound_is_below_the_task_bound_and_says_its_rules(
    human_bounds: PlanResult,
) -> None:
    values = human_bounds.objective_values
    assert values["bound_unrestricted"] <= values["bound"] * (1 + BOUND_TOLERANCE)
    d = json.loads(json.dumps(human_bounds.to_dict(), allow_nan=False))
    task_rules = d["methods"]["bound"]["rules"]
    free_rules = d["methods"]["bound_unrestricted"]["rules"]
    assert task_rules["rest_to_rest"] and free_rules["rest_to_rest"]
    assert task_rules["monotone_joints"] == ["shoulder_flexion", "elbow_flexion"] or (
        len(task_rules["monotone_joints"]) == 2
    )
    assert not task_rules["reversal_allowed"] and free_rules["reversal_allowed"]
    assert free_rules["monotone_joints"] == [] and free_rules["held_joints"] == []
    assert "joint torque" in task_rules["limits"]
    solver = d["methods"]["bound"]["solver"]
    assert solver["multistart"] >= 1 and len(solver["starts"]) >= solver["multistart"]
    assert d["share_of_achievable_pct"]["bound_unrestricted"] is None
    assert d["share_of_achievable_pct"]["bound"] == 100.0


def test_rules_name_the_held_joints_of_the_6dof_task() -> None:
    robot = load_robot("curtain_wall_6dof")
    task = PlanTask.default(robot)
    rules = bound_rules(robot.joint_names, task, no_reversal=True)
    moving = np.abs(task.goal - task.start) > 0
    assert len(rules.monotone_joints) == int(moving.sum())
    assert len(rules.held_joints) == int((~moving).sum()) > 0
    assert bound_rules(robot.joint_names, task, no_reversal=False).reversal_allowed


def test_a_reversing_motion_is_outside_the_task_bound_rules(human_bounds: PlanResult) -> None:
    robot = load_robot("human_arm_2dof")
    rules = bound_rules(robot.joint_names, human_bounds.task, no_reversal=True)
    free = human_bounds.methods["bound_unrestricted"].evaluated
    quintic = human_bounds.methods["quintic"].evaluated
    assert rule_breach(robot, human_bounds.task, quintic, rules) is None
    why = rule_breach(robot, human_bounds.task, free, rules)
    if why is not None:  # the unrestricted optimum swings the shoulder back on this task
        assert "against its stroke" in why


def _bell(res: PlanResult) -> tuple[float, float, float, float]:
    """(1 %-band width [deg], peak flexion [deg], worst rise/fall breach [rad/s²]) of the
    human-like optimum's elbow speed on the fine grid."""
    ev = res.methods["human_optimal"].evaluated
    tr, e = ev.trajectory, res.elbow_joint
    direction = np.sign(res.task.goal[e] - res.task.start[e])
    speed = direction * tr.qd[:, e]
    flex = elbow_flexion_deg(tr.q[:, e], res.task, e)
    k = int(np.argmax(speed))
    band = flex[speed >= 0.99 * speed[k]]
    acc = direction * tr.qdd[:, e]
    return (
        float(band.max() - band.min()),
        float(flex[k]),
        float(-acc[:k].min()),
        float(acc[k + 1 :].max()),
    )


@pytest.mark.parametrize("robot_name", ROBOTS)
@pytest.mark.parametrize("objective", ["abs_work", "peak_power"])
def test_human_optimal_has_one_clear_peak_at_the_template_angle(
    robot_name: str, objective: str
) -> None:
    res = plan(
        load_robot(robot_name), objective=objective, particles=8, iterations=10,
        methods=("quintic", "paper", "human_optimal"),
    )  # fmt: skip
    width, peak, rise_breach, fall_breach = _bell(res)
    assert width <= 10.0 and width <= 2 * PEAK_BAND_DEG + 0.1
    assert abs(peak - res.target_peak_angle_deg) <= PEAK_ANGLE_TOLERANCE_DEG
    scale = float(np.abs(res.methods["human_optimal"].trajectory.qdd).max())
    assert rise_breach <= 1e-6 * scale and fall_breach <= 1e-6 * scale
    assert "one elbow-speed peak" in res.to_dict()["methods"]["human_optimal"]["rules"]["human"]


def test_human_likeness_is_reported_for_every_method(human_bounds: PlanResult) -> None:
    d = human_bounds.to_dict()
    for m in d["methods"].values():
        assert 0.0 <= m["human_likeness"] <= 1.0
    assert "root-mean-square" in d["human_likeness_reference"]
    # A quintic is a minimum-jerk bell: against a template peaking mid-stroke it scores ~0.
    task = human_bounds.task
    tr = human_bounds.methods["quintic"].trajectory
    e = human_bounds.elbow_joint
    q0, q1 = float(task.start[e]), float(task.goal[e])
    mid = HumanTemplate(peak_velocity_angle_deg=75.0)
    reference, source = template_speed_on_stroke(mid, q0, q1)
    assert reference.shape == (LIKENESS_POINTS,) and "minimum-jerk" in source
    assert human_likeness_distance(tr.q[:, e], tr.qd[:, e], q0, q1, reference) < 5e-3
    early = HumanTemplate(peak_velocity_angle_deg=45.0)
    far, _ = template_speed_on_stroke(early, q0, q1)
    assert human_likeness_distance(tr.q[:, e], tr.qd[:, e], q0, q1, far) > 0.05


def test_floors_say_no_floor_plainly(human_bounds: PlanResult) -> None:
    fl = floors(3.0, 1.0).to_dict()
    for name in NO_FLOOR:
        assert fl[name] is None and FLOOR_NOTES[name] == "no floor"
    assert "loose" in FLOOR_NOTES["peak_power"] and "bound" in FLOOR_NOTES["peak_power"]
    d = human_bounds.to_dict()
    assert d["floors"]["tau_sq"] is None and d["floor_notes"]["tau_sq"] == "no floor"


def test_cli_floors_line_says_no_floor(human_bounds: PlanResult) -> None:
    from app.cli._common import floors_line

    line = floors_line(human_bounds.to_dict()["floors"])
    assert "no floor" in line and "loose" in line


def test_converge_refines_the_bound_with_its_evidence() -> None:
    """On request, the bound is refined on 2N, 4N, ... intervals until its objective moves by
    under 0.1 %; the sequence is in the result, and refining never raises the bound."""
    res = plan(
        load_robot("human_arm_2dof"), objective="tau_sq", particles=6, iterations=5,
        methods=("quintic", "bound"), n_intervals=20, converge=True,
    )  # fmt: skip
    conv = res.to_dict()["methods"]["bound"]["solver"]["convergence"]
    seq = [s for s in conv["sequence"] if "objective" in s]
    assert [s["n_intervals"] for s in seq][:2] == [20, 40]
    assert conv["converged"] and conv["relative_change"] < 1e-3
    assert res.objective_values["bound"] <= seq[0]["objective"]
    assert conv["final_intervals"] == res.methods["bound"].solver["n_intervals"]  # type: ignore[index]
