"""The symbolic (CasADi) inverse dynamics equals Pinocchio's RNEA to round-off, for every kind of
robot the project loads: the built-ins with payload and armature, and a user URDF with an
unaligned axis, rotated placements, a continuous joint and a branch."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from app.planning.energy import MotorModel
from app.planning.robots import Payload, load_robot
from app.planning.symbolic import symbolic_chain

# A tree: base -> a (unaligned axis) -> b (rotated placement, continuous) -> tool; and a second
# branch base -> a -> side. Inertias are full (off-diagonal terms) so no axis is special.
USER_URDF = """<?xml version="1.0"?>
<robot name="tree">
  <link name="base"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="a"/>
    <origin xyz="0.1 -0.05 0.3" rpy="0.2 -0.1 0.4"/>
    <axis xyz="0.6 0.8 0"/>
    <limit lower="-3" upper="3" velocity="5" effort="300"/>
  </joint>
  <link name="a">
    <inertial><origin xyz="0.02 0.1 -0.03" rpy="0 0 0"/><mass value="3.5"/>
      <inertia ixx="0.05" ixy="0.004" ixz="-0.002" iyy="0.07" iyz="0.003" izz="0.04"/></inertial>
  </link>
  <joint name="j2" type="continuous">
    <parent link="a"/><child link="b"/>
    <origin xyz="0.0 0.35 0.05" rpy="-0.3 0.5 0.1"/>
    <axis xyz="0 0 -1"/>
    <limit velocity="6" effort="150"/>
  </joint>
  <link name="b">
    <inertial><origin xyz="0.15 0 0.01" rpy="0 0 0"/><mass value="2.0"/>
      <inertia ixx="0.01" ixy="0.001" ixz="0" iyy="0.03" iyz="-0.002" izz="0.025"/></inertial>
  </link>
  <joint name="j3" type="revolute">
    <parent link="b"/><child link="tool"/>
    <origin xyz="0.3 0.0 0.0" rpy="0 0 0"/>
    <axis xyz="0 -1 0"/>
    <limit lower="-2" upper="2" velocity="7" effort="60"/>
  </joint>
  <link name="tool">
    <inertial><origin xyz="0.05 0 0" rpy="0 0 0"/><mass value="0.8"/>
      <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.002"/></inertial>
  </link>
  <joint name="j4" type="revolute">
    <parent link="a"/><child link="side"/>
    <origin xyz="0.05 0.0 0.1" rpy="0.7 0 0"/>
    <axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" velocity="7" effort="60"/>
  </joint>
  <link name="side">
    <inertial><origin xyz="0 0.05 0" rpy="0 0 0"/><mass value="0.5"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
  </link>
</robot>
"""


def _motor(rotor: float) -> MotorModel:
    return MotorModel(100.0, 0.3, 1.0, rotor, 0.5, 1.0, 0.2)


def _robots(tmp_path: Path) -> list[object]:
    urdf = tmp_path / "tree.urdf"
    urdf.write_text(USER_URDF)
    # j4 branches off the arm: a robot's free joints form one chain (docs/robots.md), so it is
    # held at an angle, its body merged into link a off the joint axes
    user = load_robot(str(urdf), payload=1.7, locks={"j4": 0.7})
    user = dataclasses.replace(
        user,
        motors=tuple(_motor(1e-5 * (k + 1)) for k in range(user.n_joints)),
        payload=Payload.box(1.7, (0.2, 0.1, 0.05), (0.02, 0.01, 0.03)),
    )
    return [load_robot("human_arm_2dof"), load_robot("curtain_wall_6dof", payload=9.0), user]


def test_symbolic_rnea_equals_pinocchio_at_random_states(tmp_path: Path) -> None:
    """Same model (payload merged, armature on the diagonal), so the torques agree to 1e-9."""
    rng = np.random.default_rng(42)
    for robot in _robots(tmp_path):
        fn = symbolic_chain(robot).function()  # type: ignore[arg-type]
        dyn = robot.dynamics()  # type: ignore[attr-defined]
        assert np.any(robot.armature > 0) or robot.name == "human_arm_2dof"  # type: ignore[attr-defined]
        n = dyn.n_joints
        for _ in range(25):
            q, qd, qdd = rng.uniform(-3.0, 3.0, size=(3, n))
            expected = dyn.inverse_dynamics(q, qd, qdd)
            got = np.asarray(fn(q, qd, qdd), dtype=float).ravel()
            np.testing.assert_allclose(
                got, expected, rtol=0.0, atol=1e-9 * (1 + np.abs(expected).max())
            )


def test_symbolic_chain_reads_the_payload(tmp_path: Path) -> None:
    """A heavier payload changes the symbolic torques exactly as it changes Pinocchio's."""
    light, heavy = (
        load_robot("curtain_wall_6dof", payload=0.0),
        load_robot("curtain_wall_6dof", payload=20.0),
    )
    q = np.radians([10.0, 30.0, 60.0, 5.0, -20.0, 3.0])
    zero = np.zeros(6)
    diffs = []
    for robot in (light, heavy):
        tau = np.asarray(symbolic_chain(robot).function()(q, zero, zero), dtype=float).ravel()
        diffs.append(tau - robot.dynamics().inverse_dynamics(q, zero, zero))
        assert np.abs(diffs[-1]).max() < 1e-9
    a = np.asarray(symbolic_chain(light).function()(q, zero, zero), dtype=float).ravel()
    b = np.asarray(symbolic_chain(heavy).function()(q, zero, zero), dtype=float).ravel()
    assert abs(b[1] - a[1]) > 10.0  # 20 kg at the flange loads the shoulder


@pytest.mark.parametrize("name", ["human_arm_2dof", "curtain_wall_6dof"])
def test_symbolic_chain_is_cached_per_robot(name: str) -> None:
    robot = load_robot(name)
    assert symbolic_chain(robot) is symbolic_chain(robot)
