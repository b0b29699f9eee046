"""Issue 26 item 3: actuators that can say no.

A torque–speed envelope and an RMS torque limit per joint: the optimal control obeys them as
constraints (checked here on a case built to hit them, against the envelope's closed form and
an RMS computed from Pinocchio's torques), every plan reports each joint's margins, violations
are named, and a user robot's sidecar carries them.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from app.errors import BioPlanError
from app.planning.actuators import (
    BUILT_IN,
    ENVELOPE_MARGIN,
    ActuatorEnvelope,
    ActuatorLimits,
    actuator_limits,
    actuator_report,
)
from app.planning.evaluation import EvaluatedTrajectory, PlanTask, evaluate_trajectory
from app.planning.optimal import ExtraConstraints, HumanSpec, OptimalResult, solve_optimal
from app.planning.planner import plan
from app.planning.robots import Robot, RobotError, load_robot
from app.planning.robots._sidecar import read_sidecar

ROBOTS_DIR = Path(__file__).resolve().parents[2] / "app" / "planning" / "robots"


def _tight_elbow(robot: Robot, *, corner: float, top: float, rms: float = 1e3) -> ActuatorLimits:
    """The human arm with an elbow whose torque falls off above ``corner`` rad/s."""
    shoulder = ActuatorEnvelope(100.0, 10.0, 20.0, 10.0, 1e3, 10.0, "test")
    elbow = ActuatorEnvelope(80.0, corner, top, corner, rms, 10.0, "test")
    return ActuatorLimits(tuple(robot.joint_names), (shoulder, elbow))


def _solve(
    robot: Robot, limits: ActuatorLimits | None
) -> tuple[EvaluatedTrajectory, OptimalResult]:
    task = PlanTask.default(robot)
    extra = None if limits is None else ExtraConstraints(actuators=limits)
    res = solve_optimal(
        robot, task.start, task.goal, 1.0, objective="tau_sq",
        human=HumanSpec("none", robot.elbow_joint), n_intervals=40, extra=extra,
    )  # fmt: skip
    return evaluate_trajectory(robot, res.trajectory, task), res


def test_the_envelope_binds_on_a_case_built_to_hit_it() -> None:
    """The free tau_sq optimum needs more elbow torque at speed than an actuator whose torque
    falls from 80 Nm at 2 rad/s to 0 at 7 rad/s gives; constrained, it stays inside, touching
    the line (the closed form τ_peak (ω_max − |q̇|) / (ω_max − ω_c), evaluated here on
    Pinocchio's torques), and pays for it in tau_sq."""
    robot = load_robot("human_arm_2dof", payload=12.0)
    limits = _tight_elbow(robot, corner=2.0, top=7.0)
    free, free_res = _solve(robot, None)
    _, violations = actuator_report(robot, free, limits)
    assert (
        violations and "torque-speed envelope" in violations[0] and "elbow_flexion" in violations[0]
    )
    held, held_res = _solve(robot, limits)
    w = np.abs(held.trajectory.qd[:, 1])
    available = 80.0 * np.clip((7.0 - w) / (7.0 - 2.0), 0.0, 1.0)
    use = np.abs(held.tau[:, 1]) / available
    slack = available - np.abs(held.tau[:, 1])  # [Nm]
    assert slack.min() >= 0.0  # inside, between the evaluation points too
    # Binding: on the line but for the margin the solver keeps below it (1 % of 80 Nm).
    assert slack.min() <= 1.2 * ENVELOPE_MARGIN * 80.0
    margins, none = actuator_report(robot, held, limits)
    assert not none
    assert margins["joints"]["elbow_flexion"]["margins"]["envelope"] == pytest.approx(
        1.0 - use.max(), abs=1e-9
    )
    assert held_res.solver.objective > free_res.solver.objective * 1.001


def test_the_rms_limit_binds_on_a_case_built_to_hit_it() -> None:
    """An elbow RMS limit below the free optimum's: constrained, the RMS over the 10 s cycle
    (the motion, then the goal pose held; computed here from Pinocchio's torques) is on it."""
    robot = load_robot("human_arm_2dof", payload=12.0)
    free, _ = _solve(robot, None)
    task = PlanTask.default(robot)
    zero = np.zeros((1, 2))
    hold = abs(robot.dynamics().inverse_dynamics(task.goal[None, :], zero, zero)[0, 1])

    def rms(ev: EvaluatedTrajectory) -> float:
        heat = np.trapezoid(ev.tau[:, 1] ** 2, ev.trajectory.t) + hold**2 * 9.0
        return math.sqrt(heat / 10.0)

    limit = 0.97 * rms(free)
    limits = _tight_elbow(robot, corner=20.0, top=30.0, rms=limit)
    _, violations = actuator_report(robot, free, limits)
    assert any("RMS torque" in v for v in violations)
    held, _ = _solve(robot, limits)
    assert rms(held) == pytest.approx(limit * (1 - 2e-3), rel=2e-3)


def test_every_plan_reports_margins_and_the_constrained_methods_obey() -> None:
    """plan(): margins for every method and joint; the quintic breaks the tight envelope and is
    named in the warnings; the bound and human_optimal are re-solved inside it."""
    robot = load_robot("human_arm_2dof", payload=12.0)
    robot._cache[("actuator_limits",)] = _tight_elbow(robot, corner=2.0, top=7.0)
    res = plan(robot, duration=1.0, objective="tau_sq", methods=["quintic", "bound"], safety=False)
    report = res.to_dict()["actuators"]
    assert set(report["methods"]) == {"quintic", "bound"}
    for name in ("quintic", "bound"):
        assert set(report["methods"][name]["joints"]) == {"shoulder_flexion", "elbow_flexion"}
    assert report["methods"]["quintic"]["joints"]["elbow_flexion"]["margins"]["envelope"] < 0
    assert any(w.startswith("quintic: joint elbow_flexion") for w in res.warnings)
    assert report["methods"]["bound"]["joints"]["elbow_flexion"]["margins"]["envelope"] > -2e-3
    assert res.methods["bound"].solver["actuators"]["constrained"] is True


def test_built_in_robots_have_plausible_limits_their_default_plans_keep() -> None:
    for name, mass in (("curtain_wall_6dof", 4.0), ("human_arm_2dof", 12.0)):
        robot = load_robot(name, payload=mass)
        limits = actuator_limits(robot)
        assert limits is not None and limits.envelopes == BUILT_IN[name]
        for env, tau_max in zip(limits.envelopes, robot.tau_max, strict=True):
            assert env is not None and env.source
            assert env.peak_torque == pytest.approx(tau_max)
            assert 0 < env.corner_speed < env.max_speed and env.rms_torque < env.peak_torque
        res = plan(robot, duration=1.0, methods=["quintic", "jerk_limited"], safety=False)
        assert not [w for w in res.warnings if "actuator" in w or "RMS" in w], res.warnings
        assert res.to_dict()["actuators"]["methods"]["quintic"]["joints"]


def _user_arm(tmp_path: Path, actuators: str) -> Path:
    shutil.copy(ROBOTS_DIR / "human_arm_2dof.urdf", tmp_path / "arm.urdf")
    motors = "".join(
        f"  {j}: {{gear_ratio: 100, torque_constant: 0.1, winding_resistance: 0.5}}\n"
        for j in ("shoulder_flexion", "elbow_flexion")
    )
    sidecar = tmp_path / "arm.yaml"
    sidecar.write_text("motors:\n" + motors + "actuators:\n" + actuators)
    return sidecar


def test_a_sidecar_gives_a_user_robot_its_envelope_with_the_corner_from_the_bus(
    tmp_path: Path,
) -> None:
    """bus_voltage: ω_c = (V − R i_p) / (k_t N) with i_p = τ_peak / (N k_t); ω_max = V / (k_t N)."""
    sidecar = _user_arm(
        tmp_path,
        "  elbow_flexion: {peak_torque: 60, rated_speed: 4, bus_voltage: 48, rms_torque: 25,"
        " duty_cycle: 6}\n",
    )
    robot = load_robot(tmp_path / "arm.urdf", sidecar=sidecar)
    limits = actuator_limits(robot)
    assert limits is not None
    shoulder, elbow = limits.envelopes
    assert shoulder is None and elbow is not None
    k = 0.1 * 100
    assert elbow.corner_speed == pytest.approx((48 - 0.5 * 60 / k) / k)
    assert elbow.max_speed == pytest.approx(48 / k)
    assert elbow.duty_cycle == 6 and "arm.yaml" in elbow.source


@pytest.mark.parametrize(
    "block, says",
    [
        ("  elbow_flexion: {peak_torque: 60, rated_speed: 4, rms_torque: 25, duty_cycle: 6, "
         "max_speed: 8, torque: 3}\n", "unknown field actuators.elbow_flexion.torque"),
        ("  elbow_flexion: {peak_torque: -60, rated_speed: 4, rms_torque: 25, duty_cycle: 6, "
         "max_speed: 8, corner_speed: 2}\n", "actuators.elbow_flexion.peak_torque"),
    ],
)  # fmt: skip
def test_bad_actuator_fields_are_refused_naming_them(tmp_path: Path, block: str, says: str) -> None:
    sidecar = _user_arm(tmp_path, block)
    with pytest.raises(RobotError, match=says.replace(".", r"\.")):
        read_sidecar(sidecar)


def test_an_envelope_without_a_corner_is_refused_naming_it(tmp_path: Path) -> None:
    sidecar = _user_arm(
        tmp_path,
        "  elbow_flexion: {peak_torque: 60, rated_speed: 4, max_speed: 8, rms_torque: 25,"
        " duty_cycle: 6}\n",
    )
    robot = load_robot(tmp_path / "arm.urdf", sidecar=sidecar)
    with pytest.raises(BioPlanError, match=r"actuators\.elbow_flexion lacks corner_speed"):
        actuator_limits(robot)
