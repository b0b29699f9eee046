"""Onboarding that refuses to guess wrong (issue 27): branched robots, locks in one message,
limitless joints, sidecar effort and speed limits, MuJoCo's inertia rules.

Real robots from example-robot-data 6.0.0 (anymal-kinova, tiago_dual, tiago_pro, finger_edu,
UR5). Independent references: MuJoCo's ``mj_inverse`` against Pinocchio's reduced model
(``check_same_robot``) for every robot whose joints were locked; the URDF's own inertia tensors
for what MuJoCo compiled; the loader's one message parsed back into locks that then load.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from app.names import STANDARD_METHODS
from app.planning.planner import plan
from app.planning.robots import RobotError, load_robot
from app.planning.robots._consistency import check_same_robot
from app.planning.robots._loader import ROBOT_DIR
from app.planning.robots._urdf import parse_urdf
from tests.utils.example_robots import UR5, robot_file

ANYMAL_KINOVA = "anymal_b_simple_description/robots/anymal-kinova.urdf"
TIAGO_DUAL = "tiago_description/robots/tiago_dual.urdf"
TIAGO_PRO = "tiago_pro_description/robots/tiago_pro.urdf"
FINGER_EDU = "finger_edu_description/robots/finger_edu.urdf"
KINOVA_ARM = tuple(f"j2s6s200_joint_{i}" for i in range(1, 7))


def refusal(**kwargs: object) -> str:
    with pytest.raises(RobotError) as info:
        load_robot(**kwargs)  # type: ignore[arg-type]
    message = str(info.value)
    assert "\n" not in message and "expected" in message, message
    return message


def locks_asked(message: str, file: Path) -> dict[str, float]:
    """Every ``--lock NAME=VALUE`` of a refusal, at zero clipped into the joint's limits [SI]."""
    model = parse_urdf(file)
    names = re.findall(r"--lock ([^=\s]+)=VALUE", message)
    return {n: float(np.clip(0.0, model.joint(n).lower, model.joint(n).upper)) for n in names}


def test_a_legged_robot_is_refused_until_the_arm_base_is_named() -> None:
    """anymal-kinova: four legs and a Kinova arm on one trunk. Without a base link it was
    planned with shoulder = LF_HAA and elbow = RF_HAA (two hips); now it is refused, naming
    the branches and the arm's base link, and with it the arm alone is planned."""
    urdf = robot_file(ANYMAL_KINOVA)
    message = refusal(name_or_file=urdf)
    assert "branch into 5 chains" in message and "LF_HAA…LF_KFE" in message
    assert "--base-link" in message and "j2s6s200_link_base" in message
    # naming two hips as shoulder and elbow does not get around it
    assert "branch into" in refusal(name_or_file=urdf, shoulder_joint="LF_HAA",
                                    elbow_joint="RF_HAA")  # fmt: skip
    robot = load_robot(urdf, base_link="j2s6s200_link_base", payload=1.0)
    assert robot.joint_names == KINOVA_ARM
    assert (robot.shoulder_joint_name, robot.elbow_joint_name) == KINOVA_ARM[1:3]
    legs = {n for n in robot.all_joint_names if n[:2] in ("LF", "RF", "LH", "RH")}
    assert set(robot.locks) == legs and len(legs) == 12
    assert all(
        row["source"] == "off the arm (no effect on it)"
        for row in robot.parameters
        if str(row["name"]).startswith("lock.")
    )
    # the hips are not on the arm's chain: refused as roles
    assert "shoulder joint 'LF_HAA': it is locked" in refusal(
        name_or_file=urdf, base_link="j2s6s200_link_base", shoulder_joint="LF_HAA"
    )
    check_same_robot(robot)  # Pinocchio's reduced model vs MuJoCo with the legs welded
    # a base link that is not one, and a tip that is not below the base, are named
    assert "base_link 'trunk' is not a link" in refusal(name_or_file=urdf, base_link="trunk")
    assert "does not lie below base_link" in refusal(
        name_or_file=urdf, base_link="j2s6s200_link_base", tip_link="LF_HIP"
    )


def test_the_sidecar_names_the_base_link_too(tmp_path: Path) -> None:
    car = tmp_path / "anymal.yaml"
    car.write_text("base_link: j2s6s200_link_base\n")
    robot = load_robot(robot_file(ANYMAL_KINOVA), sidecar=car)
    assert robot.joint_names == KINOVA_ARM and robot.spec["base_link"] == "j2s6s200_link_base"


def test_every_lock_needed_is_asked_for_in_one_message() -> None:
    """tiago_pro's right arm: the torso lift places its base and the gripper's six joints
    (one actuated, five mimics) ride on it; one refusal names all seven, and locking exactly
    those loads the arm (it used to ask one joint at a time)."""
    urdf = robot_file(TIAGO_PRO)
    chain = {"base_link": "torso_lift_link", "tip_link": "arm_right_7_link"}
    message = refusal(name_or_file=urdf, **chain)
    locks = locks_asked(message, urdf)
    assert "torso_lift_joint" in locks and "gripper_right_finger_joint" in locks
    assert "places the arm's base link 'torso_lift_link'" in message
    assert "carried by the arm off its chain" in message and "in one go" in message
    assert len(locks) == 7
    robot = load_robot(urdf, locks=locks, payload=0.5, **chain)
    assert robot.joint_names == tuple(f"arm_right_{i}_joint" for i in range(1, 8))


@pytest.mark.slow
def test_tiago_dual_plans_with_its_casters_locked() -> None:
    """tiago_dual's casters have no <limit>: they can be locked (any value) although they
    cannot be left free; with the torso and the right hand locked as asked, the right arm
    plans, and MuJoCo (casters, left arm, head welded) agrees with Pinocchio's reduced model."""
    urdf = robot_file(TIAGO_DUAL)
    model = parse_urdf(urdf)
    casters = {j.name: 0.0 for j in model.joints if j.name.startswith("caster")}
    assert len(casters) == 8 and not any(model.joint(n).limited for n in casters)
    chain = {"base_link": "torso_lift_link", "tip_link": "arm_right_7_link"}
    asked = locks_asked(refusal(name_or_file=urdf, locks=casters, **chain), urdf)
    assert "torso_lift_joint" in asked and not set(asked) & set(casters)
    locks = {**casters, **asked, "caster_front_left_1_joint": 2.5}  # any angle, no limits
    robot = load_robot(urdf, locks=locks, payload=1.0, **chain)
    assert robot.joint_names == tuple(f"arm_right_{i}_joint" for i in range(1, 8))
    assert robot.locks["caster_front_left_1_joint"] == 2.5
    check_same_robot(robot)
    result = plan(robot, duration=2.0, methods=("quintic", "jerk_limited"))
    assert list(result.methods) == ["quintic", "jerk_limited"] and not result.method_errors
    # a free joint without limits is refused with the lock that fixes it
    message = refusal(name_or_file=urdf, **chain)
    assert "joint 'caster_front_right_1_joint' has no <limit>" not in message  # off the arm
    assert "torso_lift_joint" in message


def _mjcf_without_force_limits(folder: Path) -> Path:
    text = (ROBOT_DIR / "curtain_wall_6dof.xml").read_text()
    text = re.sub(r' actuatorfrcrange="[^"]*"', "", text)
    text = re.sub(r"<actuator>.*?</actuator>", "", text, flags=re.S)
    path = folder / "arm.xml"
    path.write_text(text)
    return path


@pytest.mark.slow
def test_an_mjcf_with_sidecar_limits_plans_with_the_default_methods(tmp_path: Path) -> None:
    """An MJCF without actuatorfrcrange (like dm_control's Jaco) had no way to get effort
    limits, and an MJCF has no speed limits, so jerk_limited failed by default; the sidecar's
    ``effort_limits`` and ``velocity_limits`` fill both, and every default method plans."""
    mjcf = _mjcf_without_force_limits(tmp_path)
    message = refusal(name_or_file=mjcf)
    assert "arm.xml: joint(s) j1_base_yaw" in message and "effort_limits" in message
    builtin = load_robot("curtain_wall_6dof")
    names = builtin.joint_names
    car = tmp_path / "arm.yaml"
    car.write_text(
        "effort_limits:\n"
        + "".join(f"  {n}: {t:g}\n" for n, t in zip(names, builtin.tau_max, strict=True))
        + "velocity_limits:\n"
        + "".join(f"  {n}: 4.0\n" for n in names)
    )
    robot = load_robot(mjcf, sidecar=car, payload=4.0)
    np.testing.assert_array_equal(robot.tau_max, builtin.tau_max)
    np.testing.assert_array_equal(robot.qd_max, np.full(6, 4.0))
    result = plan(
        robot, duration=1.5, methods=STANDARD_METHODS, particles=10, iterations=10,
        report_samples=300, n_intervals=20,
    )  # fmt: skip
    assert {"quintic", "jerk_limited", "human_optimal", "bound"} <= set(result.methods)
    assert not any("finite speed limit" in f.error for f in result.method_errors.values())
    # the effort limits are the ones the plan keeps: halving one changes the robot
    car.write_text(car.read_text().replace("j2_shoulder_pitch: 350", "j2_shoulder_pitch: 175"))
    assert load_robot(mjcf, sidecar=car).tau_max[1] == 175.0


def test_mujoco_inertia_it_refuses_is_repaired_and_said(tmp_path: Path) -> None:
    """finger_edu's lower link is a thin rod (principal inertias 0, 1.2e-4, 1.2e-4 kg m^2):
    MuJoCo refused it ("inertia must have positive eigenvalues", naming a cache file). Its
    MuJoCo copy now raises the zero to 1e-6 of the largest, the robot's parameters say so, and
    MuJoCo's dynamics still agree with Pinocchio's."""
    urdf = robot_file(FINGER_EDU)
    robot = load_robot(urdf, payload=0.0)
    repairs = [r for r in robot.parameters if r["name"] == "mujoco inertia repair"]
    assert len(repairs) == 1 and str(repairs[0]["value"]).startswith("finger_lower_link:")
    model = robot.mujoco_model(armature=False)
    inertia = sorted(model.body("finger_lower_link").inertia)
    assert inertia[0] == pytest.approx(1e-6 * inertia[2], rel=1e-3)
    assert inertia[1:] == pytest.approx([1.2e-4, 1.2e-4], rel=1e-6)  # the file's own
    check_same_robot(robot)
    # A user MJCF MuJoCo cannot compile is named, with the reason and the fix.
    bad = tmp_path / "bad.xml"
    bad.write_text(
        '<mujoco><worldbody><body name="a"><joint name="j1" type="hinge" axis="0 1 0" '
        'actuatorfrcrange="-5 5"/><inertial pos="0 0 0" mass="1" fullinertia="1 1 -1 0 0 0"/>'
        '<body name="b" pos="0.3 0 0"><joint name="j2" type="hinge" axis="0 1 0" '
        'actuatorfrcrange="-5 5"/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>'
        "</body></body></worldbody></mujoco>"
    )
    message = refusal(name_or_file=bad)
    assert message.startswith("bad.xml: MuJoCo cannot compile it (") and "inertia" in message
    assert "A + B >= C" in message and "fix its <inertial>" in message


def test_the_ur5_meshes_are_listed_when_missing(tmp_path: Path) -> None:
    """UR5's URDF names 14 meshes (7 visual, 7 collision) by package:// paths: found beside
    example-robot-data, none when the URDF is copied alone."""
    from app.planning.robots import missing_meshes

    assert missing_meshes(load_robot(robot_file(UR5))) == []
    alone = tmp_path / "ur5.urdf"
    alone.write_bytes(robot_file(UR5).read_bytes())
    missing = missing_meshes(load_robot(alone))
    assert len(missing) == 14 == len(set(parse_urdf(alone).meshes))
    assert missing[0].endswith("ur5/visual/base.dae")


def test_the_cli_base_link_and_tip_link_options(capsys: pytest.CaptureFixture[str]) -> None:
    """``--base-link`` turns anymal-kinova's refusal (exit 2) into the arm's plan; ``--tip-link``
    below a base that is not its ancestor is refused naming both."""
    import json

    from app.cli import main

    args = ["plan", "--robot", str(robot_file(ANYMAL_KINOVA)), "--method", "quintic,jerk_limited",
            "--duration", "5", "--json"]  # fmt: skip
    assert main(args) == 2
    assert "--base-link" in capsys.readouterr().err
    assert main([*args, "--base-link", "j2s6s200_link_base"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["joint_names"] == list(KINOVA_ARM) and "jerk_limited" in data["methods"]
    tip = ["--base-link", "j2s6s200_link_base", "--tip-link", "LF_SHANK"]
    assert main([*args, *tip]) == 2
    assert "tip_link 'LF_SHANK' does not lie below base_link" in capsys.readouterr().err


def test_the_viewer_says_which_meshes_it_could_not_find(tmp_path: Path) -> None:
    """The viewer's prepared scene names the UR5's 7 visual meshes when the URDF is alone, and
    none beside example-robot-data (where they are found and drawn)."""
    from app.viewer.comparison import comparison_from_arrays
    from app.viewer.scene import PreparedComparison

    alone = tmp_path / "ur5.urdf"
    alone.write_bytes(robot_file(UR5).read_bytes())
    for urdf, expected in ((alone, 7), (robot_file(UR5), 0)):
        robot = load_robot(urdf)
        result = plan(robot, duration=1.5, methods=("quintic", "jerk_limited"), report_samples=50)
        comparison = comparison_from_arrays(
            "plan", 1, result.arrays(), result.to_dict(), robot, urdf=urdf.read_text()
        )
        prepared = PreparedComparison(comparison, urdf_path=urdf)
        assert len(prepared.missing_meshes) == expected, urdf
        assert all("/visual/" in m for m in prepared.missing_meshes)
        assert (len(prepared.meshes) > 0) == (expected == 0)
