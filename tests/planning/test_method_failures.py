"""Plans survive one method's failure; infeasible requests say what is feasible (issue 27).

Real robots from example-robot-data (Kinova j2s6s200, UR5). Independent references: the plan of
the failing method alone (its own error, raised as it is), ruckig's time-optimal duration (the
stated shortest duration solves and 1 % less does not), MuJoCo's ``mj_inverse`` for the static
torque of a payload no duration helps with, and the linear dependence of that torque on the
payload's mass (the stated heaviest payload is held, 1 % more is not).
"""

from __future__ import annotations

import math
import re

import mujoco
import numpy as np
import pytest

from app.cli import main
from app.planning.evaluation import PlanningError, PlanTask
from app.planning.jerk_limited import JerkLimitedError
from app.planning.methods import PaperInfeasible
from app.planning.planner import PlanFailed, plan
from app.planning.robots import Robot, load_robot
from app.planning.shortest_duration import rest_overload
from tests.utils.example_robots import UR5, robot_file

KINOVA = "kinova_description/robots/kinova.urdf"
#: A small PSO budget: the paper's method is not what these tests are about.
FAST = {"particles": 8, "iterations": 6, "report_samples": 300}


@pytest.fixture(scope="module")
def kinova() -> Robot:
    return load_robot(robot_file(KINOVA), payload=1.0)


@pytest.mark.slow
def test_kinova_at_6_s_keeps_every_method_that_succeeds(kinova: Robot) -> None:
    """Kinova's default task at 6 s: the paper's family (two quintics, elbow peak at 62 deg)
    breaks joint 3's 0.63 rad/s limit; the other methods are planned and compared anyway."""
    result = plan(
        kinova, duration=6.0, methods=("quintic", "paper", "human_optimal", "bound",
                                        "jerk_limited"), **FAST,
    )  # fmt: skip
    assert list(result.methods) == ["quintic", "human_optimal", "bound", "jerk_limited"]
    assert result.optimized is None and list(result.method_errors) == ["paper"]
    # The paper's own error, exactly as the paper's method alone raises it.
    with pytest.raises(PaperInfeasible) as alone:
        plan(kinova, duration=6.0, methods=("quintic", "paper"), **FAST)
    data = result.to_dict()
    failed = data["method_errors"]["paper"]
    assert failed["error"] == str(alone.value) and failed["kind"] == "infeasible"
    assert "paper" not in data["methods"] and data["conditions"]["failed_methods"] == ["paper"]
    assert any(w.startswith("paper failed: infeasible") for w in data["warnings"])
    # The comparison still works on what succeeded: shares, likeness, arrays.
    shares = result.share_of_achievable_pct
    assert shares["bound"] == pytest.approx(100.0) and 0.0 < shares["human_optimal"] <= 100.0
    assert set(result.human_likeness) == set(result.methods)
    assert "bound_q" in result.arrays() and "paper_q" not in result.arrays()
    for name in ("human_optimal", "bound", "jerk_limited"):
        assert not result.methods[name].evaluated.violations, name


def test_a_speed_limited_request_names_a_duration_that_solves(kinova: Robot) -> None:
    """At 1 s joint 3 must move 2.62 rad at 0.63 rad/s: the error names the joint and its
    limit, and a duration at which the plan was verified; ruckig's time-optimal move is the
    shortest jerk-limited one, so 1 % less fails and the stated one plans."""
    task = PlanTask.default(kinova)
    with pytest.raises(PlanningError) as info:
        plan(kinova, duration=1.0, methods=("quintic", "jerk_limited"))
    message = str(info.value)
    assert "\n" not in message and "joint 3 (j2s6s200_joint_3)" in message
    assert "speed limit is 0.628 rad/s" in message
    stated = float(re.search(r"at least ([0-9.]+) s \(verified", message).group(1))  # type: ignore[union-attr]
    # the mean-speed bound (stroke over limit) is only necessary: the verified one is above it
    lower = float(np.max(np.abs(task.goal - task.start) / kinova.qd_max))
    assert f"faster than {lower:.3f} s" in message and stated > lower
    result = plan(kinova, duration=stated, methods=("quintic", "jerk_limited"))
    assert not result.methods["jerk_limited"].evaluated.violations
    assert not result.method_errors
    # the only other method fails: its own error, as it is
    with pytest.raises(JerkLimitedError, match=r"jerk-limited profile .* needs at least"):
        plan(kinova, duration=0.99 * stated, methods=("quintic", "jerk_limited"))


def test_when_every_other_method_fails_the_clearest_error_leads(kinova: Robot) -> None:
    """At 4.3 s (above the mean-speed bound, below ruckig's 4.467 s) the jerk-limited move and
    the paper's family both fail: the error leads with the one that names a duration and lists
    the other; the duration it names plans."""
    with pytest.raises(PlanFailed) as info:
        plan(kinova, duration=4.3, methods=("quintic", "paper", "jerk_limited"), **FAST)
    message = str(info.value)
    assert message.startswith("no method but the quintic succeeded: jerk_limited: infeasible")
    assert "(also failed: paper: infeasible" in message and "\n" not in message
    assert set(info.value.failures) == {"paper", "jerk_limited"}
    needed = float(re.search(r"needs at least ([0-9.]+) s", message).group(1))  # type: ignore[union-attr]
    ok = plan(kinova, duration=needed, methods=("quintic", "paper", "jerk_limited"), **FAST)
    assert "jerk_limited" in ok.methods


def test_a_payload_no_joint_can_hold_says_no_duration_helps() -> None:
    """5000 kg on a UR5: the shoulder cannot hold it still at the start, where every motion
    begins at rest; the torque named is MuJoCo's static torque there, and the heaviest payload
    named is held (1 % more is not)."""
    ur5 = load_robot(robot_file(UR5), payload=5000.0)
    with pytest.raises(PlanningError) as info:
        plan(ur5, duration=1.0, methods=("quintic", "paper"), **FAST)
    message = str(info.value)
    assert "no duration helps" in message and "longer duration" not in message
    model = ur5.mujoco_model(armature=False)
    data = mujoco.MjData(model)
    data.qpos[:] = PlanTask.default(ur5).start
    mujoco.mj_inverse(model, data)
    j = ur5.joint_names.index("shoulder_lift_joint")
    assert f"needs {abs(data.qfrc_inverse[j]):.1f} Nm at joint shoulder_lift_joint" in message
    heaviest = float(re.search(r"at most ([0-9.]+) kg", message).group(1))  # type: ignore[union-attr]
    task = PlanTask.default(ur5)
    assert rest_overload(ur5.with_payload(0.99 * heaviest), task.start, task.goal) == ""
    assert "no duration helps" in rest_overload(
        ur5.with_payload(1.01 * heaviest), task.start, task.goal
    )
    # Only the quintic asked for: nothing keeps torque limits, the plan still reports it.
    assert math.isfinite(plan(ur5, duration=1.0, methods=("quintic",)).objective_values["quintic"])


def test_the_cli_names_the_failed_method_and_the_lowering(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """UR5's default task lowers the arm (ΔPE < 0, the sum of every method's net work); the
    human output says so and names a failed method (the paper's, on a tiny seeded PSO budget:
    its family breaks the elbow's 3.15 rad/s limit)."""
    ur5 = robot_file(UR5)
    args = ["plan", "--robot", str(ur5), "--method", "quintic,jerk_limited,paper",
            "--particles", "6", "--iterations", "4", "--duration", "1.2"]  # fmt: skip
    code = main(args)
    out = capsys.readouterr().out
    assert code == 0, out
    robot = load_robot(ur5)
    result = plan(robot, duration=1.2, methods=("quintic",))
    net = float(np.trapezoid(np.sum(result.standard.tau * result.standard.trajectory.qd, axis=1),
                             result.standard.trajectory.t))  # fmt: skip
    delta = result.to_dict()["task"]["delta_pe_j"]
    assert delta < 0 and result.to_dict()["task"]["lifts"] is False
    assert net == pytest.approx(delta, rel=1e-3)
    assert f"task: lowers the robot and payload (ΔPE {delta:+.2f} J)" in out
    assert "failed: paper (infeasible, see warnings)" in out
    assert "warning: paper failed: infeasible" in out and "jerk_limited" in out
