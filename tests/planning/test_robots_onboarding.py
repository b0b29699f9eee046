"""Onboarding real third-party arms (example-robot-data): roles, locks, sidecars, model pairs.

Independent references: Pinocchio's *full* model (fingers held with zero velocity) for the
reduced model of a locked robot; MuJoCo's ``mj_inverse`` on its own URDF compile for the welded
joints; the built-in robot's hand-written URDF for a URDF generated from an MJCF; the closed
form N^2 J_m qdd for the armature a sidecar adds.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from app.planning.energy import NOT_MODELLED
from app.planning.robots import (
    RobotError,
    load_robot,
    load_robot_spec,
    locks_from_display,
    read_sidecar,
)
from app.planning.robots._consistency import check_same_robot
from app.planning.robots._loader import ROBOT_DIR
from tests.utils.example_robots import PANDA, PANDA_LOCKS, UR5, UR10, robot_file

SIDECAR = Path(__file__).resolve().parents[2] / "docs" / "examples" / "ur5.sidecar.yaml"


def one_line(exc: pytest.ExceptionInfo[BaseException]) -> str:
    message = str(exc.value)
    assert "\n" not in message and "expected" in message, message
    return message


def test_ur5_and_ur10_load_with_their_pitch_pair_and_no_motor_model() -> None:
    for relative in (UR5, UR10):
        robot = load_robot(robot_file(relative), payload=2.0)
        assert robot.joint_names[:3] == ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint")
        # UR's shoulder_lift and elbow are the first parallel horizontal axes a link apart.
        assert (robot.shoulder_joint_name, robot.elbow_joint_name) == (
            "shoulder_lift_joint",
            "elbow_joint",
        )
        assert not robot.motors_modelled and all(m is NOT_MODELLED for m in robot.motors)
        assert robot.parameter("shoulder/elbow").startswith("first two parallel")
        # The URDF-only robot is simulated through MuJoCo's own URDF compiler.
        model = robot.mujoco_model()
        assert [model.joint(i).name for i in range(model.njnt)] == list(robot.joint_names)


def test_panda_needs_its_fingers_locked_and_then_uses_joints_2_and_4() -> None:
    panda = robot_file(PANDA)
    with pytest.raises(RobotError) as info:
        load_robot(panda)
    assert "'panda_finger_joint1' is prismatic" in one_line(info)
    assert "--lock panda_finger_joint1=VALUE" in str(info.value)
    robot = load_robot(panda, locks=PANDA_LOCKS)
    assert robot.joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))
    # finger 2 mimics finger 1 and follows its lock (multiplier 1, offset 0)
    assert robot.locks == {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}
    assert len(robot.all_joint_names) == 9
    assert (robot.shoulder_joint_name, robot.elbow_joint_name) == ("panda_joint2", "panda_joint4")
    # joint 4's range is [-176, -4] deg: the elbow stroke goes the way there is room
    start, goal = np.degrees(robot.default_start[3]), np.degrees(robot.default_goal[3])
    assert start == pytest.approx(-4.9992, abs=1e-3) and goal == pytest.approx(start - 150.0)


def test_reduced_model_equals_the_full_model_with_fingers_held() -> None:
    panda = robot_file(PANDA)
    robot = load_robot(panda, locks=PANDA_LOCKS, payload=0.0)
    import pinocchio as pin

    full = pin.buildModelFromUrdf(str(panda))  # 9 joints, fingers free
    data = full.createData()
    names = list(full.names[1:])
    index = [names.index(n) for n in robot.joint_names]
    fingers = [names.index(n) for n in robot.locks]
    rng = np.random.default_rng(4)
    q, qd, qdd = (rng.uniform(-1.0, 1.0, size=(6, 7)) for _ in range(3))
    tau = robot.dynamics().inverse_dynamics(q, qd, qdd)
    for k in range(6):
        q_full, v_full, a_full = np.zeros(9), np.zeros(9), np.zeros(9)
        q_full[index], q_full[fingers] = q[k], 0.02
        v_full[index], a_full[index] = qd[k], qdd[k]
        tau_full = pin.rnea(full, data, q_full, v_full, a_full)[index]
        np.testing.assert_allclose(tau[k], tau_full, rtol=1e-10, atol=1e-10)


def test_welded_joints_in_mujoco_match_pinocchios_reduced_model() -> None:
    # A prismatic lock (Panda's fingers) and a revolute one away from zero (UR5's wrist 3):
    # MuJoCo's model with the joints removed and the bodies re-posed must agree with
    # Pinocchio's buildReducedModel at random states (rnea vs mj_inverse, see _consistency).
    check_same_robot(load_robot(robot_file(PANDA), locks=PANDA_LOCKS, payload=1.0))
    ur5 = load_robot(robot_file(UR5), locks={"wrist_3_joint": math.radians(30.0)}, payload=1.5)
    assert ur5.payload_body == "wrist_2_link"
    check_same_robot(ur5)


def test_joint_roles_by_name_and_their_errors() -> None:
    ur5 = robot_file(UR5)
    robot = load_robot(ur5, shoulder_joint="shoulder_pan_joint", elbow_joint="wrist_1_joint")
    assert (robot.shoulder_joint, robot.elbow_joint) == (0, 3)
    assert robot.parameter("shoulder/elbow") == "given"
    with pytest.raises(RobotError) as info:
        load_robot(ur5, elbow_joint="elbow")
    message = one_line(info)
    assert "elbow joint 'elbow': no such free joint" in message
    assert "shoulder_pan_joint, shoulder_lift_joint, elbow_joint" in message
    with pytest.raises(RobotError) as info:
        load_robot(ur5, elbow_joint="wrist_3_joint", locks={"wrist_3_joint": 0.0})
    assert "it is locked" in one_line(info)


def test_lock_errors_name_the_joint() -> None:
    ur5 = robot_file(UR5)
    with pytest.raises(RobotError) as info:
        load_robot(ur5, locks={"gripper": 0.0})
    assert "cannot lock 'gripper'" in one_line(info) and "wrist_3_joint" in str(info.value)
    with pytest.raises(RobotError) as info:
        locks_from_display(ur5, {"gripper": 1.0})
    assert "cannot lock 'gripper'" in one_line(info)
    with pytest.raises(RobotError) as info:
        load_robot(robot_file(PANDA), locks={"panda_finger_joint1": 0.5})
    assert "lock panda_finger_joint1=0.5 m" in one_line(info) and "[0, 0.04] m" in str(info.value)
    assert locks_from_display(ur5, {"wrist_3_joint": 90.0}) == {"wrist_3_joint": math.pi / 2}
    assert locks_from_display(robot_file(PANDA), {"panda_finger_joint1": 0.01}) == {
        "panda_finger_joint1": 0.01
    }


def test_a_urdf_without_moving_joints_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "statue.urdf"
    path.write_text(
        '<?xml version="1.0" encoding="utf-8"?><robot name="statue"><link name="a"/>'
        '<link name="b"/><joint name="j" type="fixed"><parent link="a"/><child link="b"/>'
        "</joint></robot>"
    )
    with pytest.raises(RobotError) as info:
        load_robot(path)
    assert one_line(info).startswith("statue.urdf: no moving joint (every joint is fixed)")


def _saved_mjcf(urdf: Path, target: Path) -> Path:
    """The MJCF MuJoCo writes for ``urdf`` (its own URDF compiler): the same robot, as MJCF."""
    from app.planning.robots._user import mujoco_ready_urdf

    model = mujoco.MjModel.from_xml_path(str(mujoco_ready_urdf(urdf)))
    mujoco.mj_saveLastXML(str(target), model)
    return target


def test_a_matching_urdf_mjcf_pair_is_accepted(tmp_path: Path) -> None:
    ur5 = robot_file(UR5)
    robot = load_robot(ur5, mjcf=_saved_mjcf(ur5, tmp_path / "ur5.xml"), payload=1.0)
    assert "checked against the URDF" in str(robot.parameter("simulation model"))


def test_a_mismatched_urdf_mjcf_pair_is_refused_naming_the_joint(tmp_path: Path) -> None:
    ur5 = robot_file(UR5)
    # UR10's MJCF has every joint name of the UR5 (the names-only check accepted it).
    other = _saved_mjcf(robot_file(UR10), tmp_path / "ur10.xml")
    with pytest.raises(RobotError) as info:
        load_robot(ur5, mjcf=other)
    message = one_line(info)
    assert message.startswith("URDF and MJCF disagree: joint 'shoulder_pan_joint' carries")
    # One flipped axis in an otherwise identical MJCF: refused naming exactly that joint.
    text = _saved_mjcf(ur5, tmp_path / "same.xml").read_text()
    start = text.index('name="elbow_joint"')
    end = text.index("/>", start)
    joint = text[start:end]
    assert 'axis="0 1 0"' in joint
    flipped = tmp_path / "flipped.xml"
    flipped.write_text(text[:start] + joint.replace('axis="0 1 0"', 'axis="0 -1 0"') + text[end:])
    with pytest.raises(RobotError) as info:
        load_robot(ur5, mjcf=flipped)
    assert "joint 'elbow_joint' turns about" in one_line(info)


def test_an_mjcf_alone_gets_a_generated_urdf_with_the_same_dynamics() -> None:
    builtin = load_robot("curtain_wall_6dof", payload=4.0)
    alone = load_robot(ROBOT_DIR / "curtain_wall_6dof.xml", payload=4.0)
    assert alone.joint_names == builtin.joint_names
    assert alone.urdf_path != builtin.urdf_path and alone.mjcf_path == builtin.mjcf_path
    np.testing.assert_allclose(alone.tau_max, builtin.tau_max)  # from actuatorfrcrange
    np.testing.assert_allclose(alone.q_min, builtin.q_min)
    assert np.all(np.isinf(alone.qd_max))  # an MJCF has no speed limits
    rng = np.random.default_rng(9)
    q, qd, qdd = (rng.uniform(-1.0, 1.0, size=(5, 6)) for _ in range(3))
    # payload shapes differ (box vs point) only in the payload; compare without it
    a = load_robot(ROBOT_DIR / "curtain_wall_6dof.xml", payload=0.0).dynamics(armature=False)
    b = load_robot("curtain_wall_6dof", payload=0.0).dynamics(armature=False)
    np.testing.assert_allclose(
        a.inverse_dynamics(q, qd, qdd), b.inverse_dynamics(q, qd, qdd), rtol=1e-9, atol=1e-9
    )
    assert load_robot_spec(alone.spec).urdf_path == alone.urdf_path


def test_the_documented_ur5_sidecar(tmp_path: Path) -> None:
    ur5 = robot_file(UR5)
    robot = load_robot(ur5, sidecar=SIDECAR)
    car = read_sidecar(SIDECAR)
    assert robot.motors_modelled and robot.locks == {"wrist_3_joint": 0.0}
    assert robot.payload.mass == 3.0 and robot.payload_body == "wrist_3_link"
    assert robot.qd_max[0] == 3.14 and robot.motors[0] == car.motors["shoulder_pan_joint"]
    # the flag wins over the sidecar
    assert load_robot(ur5, sidecar=SIDECAR, payload=1.0).payload.mass == 1.0
    # the armature N^2 J_m is added to each joint: tau difference = N^2 J_m qdd exactly
    bare = load_robot(ur5, sidecar=SIDECAR).dynamics(armature=False)
    q = np.zeros((1, 5))
    qdd = np.array([[1.0, -2.0, 0.5, 3.0, -1.0]])
    diff = robot.dynamics().inverse_dynamics(q, q, qdd) - bare.inverse_dynamics(q, q, qdd)
    expected = np.array([101**2 * 6e-5] * 3 + [101**2 * 1.5e-5] * 2) * qdd
    np.testing.assert_allclose(diff, expected, rtol=1e-9)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        ("gear_ratio: 101\n    torque_constant: 0.13", "motors.shoulder_pan_joint.gear_ratio"),
        ("robot: ur5", "robot is 'ur10' but ur5_robot.urdf is 'ur5'"),
        ("payload:", "unknown field payloads"),
        ("shoulder_pan_joint: 3.14", "velocity_limits.shoulder_pan_joint is -1"),
        ("wrist_2_joint: *size1", "no motor for joint 'wrist_2_joint'"),
    ],
)
def test_sidecar_errors_name_the_field(tmp_path: Path, edit: str, message: str) -> None:
    text = SIDECAR.read_text()
    replacement = {
        "gear_ratio: 101\n    torque_constant: 0.13": "gear_ratio: -101\n    torque_constant: 0.13",
        "robot: ur5": "robot: ur10",
        "payload:": "payloads:",
        "shoulder_pan_joint: 3.14": "shoulder_pan_joint: -1",
        "wrist_2_joint: *size1": "",
    }[edit]
    assert edit in text
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace(edit, replacement, 1))
    with pytest.raises(RobotError) as info:
        load_robot(robot_file(UR5), sidecar=bad)
    assert message in one_line(info)
    assert str(info.value).startswith("bad.yaml: ") or "ur5_robot.urdf" in str(info.value)


def test_a_negative_gear_ratio_says_what_was_expected(tmp_path: Path) -> None:
    bad = tmp_path / "neg.yaml"
    bad.write_text("motors:\n  j: {gear_ratio: -50, torque_constant: 0.1, winding_resistance: 1}\n")
    with pytest.raises(RobotError) as info:
        read_sidecar(bad)
    assert one_line(info) == "neg.yaml: motors.j.gear_ratio is -50: expected a number >= 1"


def test_electrical_metrics_are_not_modelled_without_motors() -> None:
    from app.cli._common import metrics_table
    from app.errors import BioPlanError
    from app.jsonsafe import json_safe
    from app.planning import plan
    from app.planning.energy import electrical_power, energy_metrics, improvement_pct

    robot = load_robot(robot_file(UR5), payload=1.0)
    t = np.linspace(0.0, 1.0, 11)
    qd = np.ones((11, 6))
    tau = np.full((11, 6), 2.0)
    metrics = energy_metrics(t, qd, tau, motors=robot.motors)
    assert math.isnan(metrics.electrical_energy) and metrics.abs_work == pytest.approx(12.0)
    assert json_safe(metrics.to_dict())["electrical_energy"] is None
    assert math.isnan(improvement_pct(metrics, metrics)["electrical_energy"])  # never "+100 %"
    assert np.isnan(electrical_power(qd, tau, robot.motors)).all()
    table = metrics_table([("quintic", json_safe(metrics.to_dict()))], {"delta_potential": 0.0,
                          "min_peak_power": 0.0})  # fmt: skip
    assert "not modelled" in table
    with pytest.raises(BioPlanError, match="electrical_energy needs a motor model"):
        plan(robot, duration=2.0, objective="electrical_energy", particles=4, iterations=2)
