"""Batched URDF kinematics against Pinocchio (link placements) and yourdfpy (joint transforms)."""

from __future__ import annotations

import numpy as np
import pytest

from app.planning.robots import BUILTIN_ROBOTS, load_robot
from app.viewer.kinematics import (
    KinematicsError,
    UrdfChain,
    axis_angle_matrices,
    load_urdf,
    matrices_to_wxyz,
)

TWO_LINK = """<?xml version="1.0"?>
<robot name="two_link">
  <link name="base"/>
  <joint name="slide" type="prismatic">
    <parent link="base"/><child link="carriage"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" velocity="1" effort="1"/>
  </joint>
  <link name="carriage"/>
  <joint name="turn" type="continuous">
    <parent link="carriage"/><child link="arm"/>
    <origin xyz="0 0 0.2" rpy="0 0 0"/><axis xyz="0 0 1"/>
  </joint>
  <link name="arm"/>
  <joint name="tool" type="fixed">
    <parent link="arm"/><child link="tip"/>
    <origin xyz="0.5 0 0" rpy="0 0 0"/>
  </joint>
  <link name="tip"/>
</robot>
"""


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_link_poses_match_pinocchio(name: str) -> None:
    import pinocchio as pin

    robot = load_robot(name)
    chain = UrdfChain.from_source(robot.urdf_path)
    model = pin.buildModelFromUrdf(str(robot.urdf_path))
    data = model.createData()
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.5, 1.5, size=(7, len(robot.joint_names)))
    poses = chain.link_poses(q, robot.joint_names)
    for k in range(len(q)):
        # Pinocchio orders its configuration by its own joint order: map by name.
        q_pin = np.zeros(model.nq)
        for i, joint in enumerate(robot.joint_names):
            q_pin[model.idx_qs[model.getJointId(joint)]] = q[k, i]
        pin.framesForwardKinematics(model, data, q_pin)
        for link in chain.links:
            ref = data.oMf[model.getFrameId(link)].homogeneous
            np.testing.assert_allclose(poses[link][k], ref, atol=1e-12)


def test_joint_transforms_match_yourdfpy() -> None:
    robot = load_robot("curtain_wall_6dof")
    urdf = load_urdf(robot.urdf_path, meshes=True)
    chain = UrdfChain(urdf)
    q = np.random.default_rng(0).uniform(-2.0, 2.0, size=(5, 6))
    local = chain.joint_transforms(q, robot.joint_names)
    for k in range(5):
        urdf.update_cfg(dict(zip(robot.joint_names, q[k], strict=True)))
        for joint in urdf.joint_map.values():
            ref = urdf.get_transform(joint.child, joint.parent)
            np.testing.assert_allclose(local[joint.name][k], ref, atol=1e-12)


def test_prismatic_continuous_and_fixed_joints_in_closed_form() -> None:
    chain = UrdfChain.from_source(TWO_LINK)
    assert chain.root == "base"
    assert chain.link_path("tip") == ["base", "carriage", "arm", "tip"]
    x, theta = 0.3, np.pi / 3
    tip = chain.link_poses(np.array([[x, theta]]), ["slide", "turn"])["tip"][0]
    # Tip = slide along x by 0.3, up 0.3 in all, then 0.5 along the turned x axis.
    expected = [x + 0.5 * np.cos(theta), 0.5 * np.sin(theta), 0.3]
    np.testing.assert_allclose(tip[:3, 3], expected, atol=1e-12)
    # A joint not named stays at zero.
    tip0 = chain.link_poses(np.array([[x]]), ["slide"])["tip"][0]
    np.testing.assert_allclose(tip0[:3, 3], [x + 0.5, 0.0, 0.3], atol=1e-12)


def test_quaternions_match_scipy() -> None:
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(1)
    rots = Rotation.random(200, random_state=rng)
    # Include the near-180-degree rotations where the trace-based formula is unstable.
    extra = Rotation.from_rotvec(np.array([[np.pi, 0, 0], [0, np.pi - 1e-9, 0], [0, 0, -np.pi]]))
    mats = np.concatenate([rots.as_matrix(), extra.as_matrix()])
    wxyz = matrices_to_wxyz(mats)
    xyzw = Rotation.from_matrix(mats).as_quat()
    ref = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    ref *= np.where(ref[:, :1] < 0, -1.0, 1.0)
    # q and -q are the same rotation; at w = 0 either sign is right.
    same = np.minimum(np.abs(wxyz - ref).max(axis=1), np.abs(wxyz + ref).max(axis=1))
    assert same.max() < 1e-9
    np.testing.assert_allclose(np.linalg.norm(wxyz, axis=1), 1.0, atol=1e-12)


def test_axis_angle_is_a_rotation_about_the_axis() -> None:
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    r = axis_angle_matrices(axis, np.array([0.7]))[0]
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(r @ axis, axis, atol=1e-12)
    assert np.isclose(np.trace(r), 1.0 + 2.0 * np.cos(0.7))


def test_bad_input_is_named() -> None:
    chain = UrdfChain.from_source(TWO_LINK)
    with pytest.raises(KinematicsError, match=r"shape \(4, 3\): expected \(T, 2\)"):
        chain.link_poses(np.zeros((4, 3)), ["slide", "turn"])
    with pytest.raises(KinematicsError, match=r"\['tool'\] are not movable joints"):
        chain.link_poses(np.zeros((2, 1)), ["tool"])
    with pytest.raises(KinematicsError, match="NaN"):
        chain.link_poses(np.array([[np.nan, 0.0]]), ["slide", "turn"])
    with pytest.raises(KinematicsError, match="unknown link 'hand'"):
        chain.link_path("hand")
    with pytest.raises(KinematicsError, match="URDF file not found"):
        load_urdf("/nonexistent/robot.urdf")
    with pytest.raises(KinematicsError, match="not a readable URDF"):
        load_urdf("<robot><joint></robot>")


# --- third-party URDFs: encoding declarations, meshes, package:// paths -----------------------


def test_urdf_text_with_an_encoding_declaration_loads() -> None:
    from tests.utils.example_robots import UR5, robot_file

    path = robot_file(UR5)
    text = path.read_text(encoding="utf-8")
    assert text.startswith('<?xml version="1.0" encoding="utf-8"?>')
    for source in (text, path.read_bytes(), path):
        urdf = load_urdf(source)
        assert "elbow_joint" in urdf.joint_map


def test_ur5_kinematics_match_pinocchio() -> None:
    import pinocchio as pin

    from tests.utils.example_robots import UR5, robot_file

    path = robot_file(UR5)
    chain = UrdfChain.from_source(path.read_text(encoding="utf-8"))
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    names = list(model.names[1:])
    q = np.random.default_rng(5).uniform(-3.0, 3.0, size=(4, len(names)))
    poses = chain.link_poses(q, names)
    for k in range(len(q)):
        pin.framesForwardKinematics(model, data, q[k])
        for link in ("forearm_link", "wrist_3_link", "tool0"):
            ref = data.oMf[model.getFrameId(link)].homogeneous
            np.testing.assert_allclose(poses[link][k], ref, atol=1e-12)


def test_package_meshes_are_found_next_to_the_file_and_confined_on_request() -> None:
    from tests.utils.example_robots import UR5, robot_file, robots_dir

    path = robot_file(UR5)
    urdf = load_urdf(path, meshes=True)
    names = set(urdf.scene.geometry)
    assert {"base.dae", "forearm.dae", "wrist3.dae"} <= {n.split("_")[0] for n in names}
    # text has no folder: package:// paths resolve only through package_dirs
    text = path.read_text(encoding="utf-8")
    assert not load_urdf(text, meshes=True).scene.geometry
    share = robots_dir().parent.parent  # the folder that holds example-robot-data/
    assert load_urdf(text, meshes=True, package_dirs=[share]).scene.geometry
    # confined to an unrelated folder: no mesh is read, the robot still loads
    confined = load_urdf(path, meshes=True, allowed_roots=[path.parent / "nowhere"])
    assert not confined.scene.geometry and "elbow_joint" in confined.joint_map


def test_a_broken_urdf_is_one_line() -> None:
    with pytest.raises(KinematicsError) as info:
        load_urdf(b"<?xml version='1.0' encoding='utf-8'?><robot name='x'><link></robot>")
    assert "\n" not in str(info.value) and "not a readable URDF" in str(info.value)
