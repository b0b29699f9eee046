"""b1-z1 (example-robot-data): a quadruped carrying a Z1 arm with a gripper (issue 27, item 2).

Its URDF names a fixed joint like the link it carries (``gripperStator``), which Pinocchio turned
into "several frames match" as soon as joints were locked with the gripper on the arm's chain.
Independent references: MuJoCo's ``mj_inverse`` on its own compile of the file with the legs
welded (``check_same_robot``), and the original file itself (the copy differs by the renamed
joint only).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from app.planning.planner import plan
from app.planning.robots import RobotError, load_robot
from app.planning.robots._consistency import check_same_robot
from tests.utils.example_robots import robot_file

B1_Z1 = "b1_description/urdf/b1-z1.urdf"
ARM = ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6")


def _tree(path: Path) -> tuple[list[tuple[str | None, ...]], list[str | None]]:
    root = ET.parse(path).getroot()
    joints = [
        (j.get("name"), j.get("type"), j.find("parent").get("link"), j.find("child").get("link"))  # type: ignore[union-attr]
        for j in root.findall("joint")
    ]
    return joints, [link.get("name") for link in root.findall("link")]


def test_b1_z1_is_refused_until_the_arm_base_is_named_then_loads_with_its_gripper() -> None:
    urdf = robot_file(B1_Z1)
    with pytest.raises(RobotError) as info:
        load_robot(urdf)
    message = str(info.value)
    assert "branch into 5 chains" in message and "--base-link" in message and "link00" in message
    # The arm with its gripper joint on the chain: this is what failed on the duplicate name.
    robot = load_robot(urdf, base_link="link00", tip_link="gripperMover", payload=0.5)
    assert robot.joint_names == (*ARM, "jointGripper")
    assert (robot.shoulder_joint_name, robot.elbow_joint_name) == ("joint2", "joint3")
    assert len(robot.locks) == 12 and all(n[:2] in ("FR", "FL", "RR", "RL") for n in robot.locks)
    rows = [r for r in robot.parameters if r["name"] == "renamed fixed joint"]
    assert [r["value"] for r in rows] == ["gripperStator -> gripperStator_fixed"]
    # The copy Pinocchio and MuJoCo read is the file with that one joint renamed.
    (orig_joints, orig_links), (copy_joints, copy_links) = _tree(urdf), _tree(robot.urdf_path)
    assert copy_links == orig_links
    renamed = [(a, b) for a, b in zip(orig_joints, copy_joints, strict=True) if a != b]
    assert renamed == [
        (
            ("gripperStator", "fixed", "link06", "gripperStator"),
            ("gripperStator_fixed", "fixed", "link06", "gripperStator"),
        )
    ]
    check_same_robot(robot)  # Pinocchio's reduced model vs MuJoCo with the legs welded
    # The mesh references still resolve (made absolute in the copy).
    meshes = [m.get("filename") for m in ET.parse(robot.urdf_path).getroot().iter("mesh")]
    assert meshes and all(Path(str(m)).is_absolute() and Path(str(m)).is_file() for m in meshes)


def test_b1_z1_arm_plans_and_its_safety_is_checked() -> None:
    urdf = robot_file(B1_Z1)
    robot = load_robot(urdf, base_link="link00", locks={"jointGripper": 0.0}, payload=0.5)
    assert robot.joint_names == ARM
    result = plan(robot, duration=2.0, methods=("quintic", "jerk_limited"), report_samples=200)
    assert list(result.methods) == ["quintic", "jerk_limited"]
    assert not result.method_errors
    # The collision meshes were found through the copy: checked, not "not checked".
    assert result.safety.to_dict()["checked"] is True
