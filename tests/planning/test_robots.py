"""Built-in robots, their files and parameter tables, user URDFs and load errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from app.planning.dynamics import PinocchioDynamics
from app.planning.energy import NOT_MODELLED, MotorModel
from app.planning.robots import (
    BUILTIN_ROBOTS,
    IDEAL_ACTUATOR,
    Payload,
    Robot,
    RobotError,
    builtin_files,
    human_arm_segments,
    load_robot,
    segment_masses,
)
from app.planning.robots.__main__ import parameters_json

ROBOT_DIR = Path(__file__).resolve().parents[2] / "app" / "planning" / "robots"


# -- shipped files --------------------------------------------------------------------------------


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_shipped_files_equal_generated(name: str) -> None:
    urdf, mjcf = builtin_files(name)
    assert (ROBOT_DIR / f"{name}.urdf").read_text() == urdf
    assert (ROBOT_DIR / f"{name}.xml").read_text() == mjcf
    assert (ROBOT_DIR / f"{name}.parameters.json").read_text() == parameters_json(name)
    robot = load_robot(name)
    assert robot.urdf_path == ROBOT_DIR / f"{name}.urdf"
    assert robot.mjcf_path == ROBOT_DIR / f"{name}.xml"


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_urdf_and_mjcf_describe_the_same_bodies(name: str) -> None:
    """Same joints, limits, masses, centres of mass and inertias in both files."""
    import pinocchio as pin

    robot = load_robot(name, payload=0.0)
    model = pin.buildModelFromUrdf(str(robot.urdf_path))
    mj = mujoco.MjModel.from_xml_path(str(robot.mjcf_path))
    assert [mj.joint(i).name for i in range(mj.njnt)] == list(model.names[1:])
    # MJCF in radians: the hinge ranges equal the URDF's limits (degrees would be converted).
    np.testing.assert_allclose(mj.jnt_range[:, 0], model.lowerPositionLimit, atol=1e-12)
    np.testing.assert_allclose(mj.jnt_range[:, 1], model.upperPositionLimit, atol=1e-12)
    np.testing.assert_allclose(mj.jnt_actfrcrange[:, 1], model.effortLimit, atol=1e-12)
    assert mj.opt.timestep == 0.001
    assert np.all(mj.geom_contype == 0) and np.all(mj.geom_conaffinity == 0)
    for joint_id in range(1, model.njoints):
        body = mj.body(mj.jnt_bodyid[joint_id - 1])
        inertia = model.inertias[joint_id]
        assert body.mass[0] == pytest.approx(inertia.mass, rel=1e-12)
        np.testing.assert_allclose(body.ipos, inertia.lever, atol=1e-12)
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, body.iquat)
        rot_m = rot.reshape(3, 3)
        np.testing.assert_allclose(
            rot_m @ np.diag(body.inertia) @ rot_m.T, inertia.inertia, atol=1e-12
        )
    # no armature, damping or friction baked into the file
    assert not mj.dof_armature.any() and not mj.dof_damping.any()
    assert not mj.dof_frictionloss.any()


def test_parameter_tables_have_sources() -> None:
    for name in BUILTIN_ROBOTS:
        rows = json.loads(parameters_json(name))
        assert rows
        for row in rows:
            assert set(row) == {"name", "value", "unit", "source"}
            assert str(row["source"]).strip(), row


# -- human arm: de Leva ---------------------------------------------------------------------------


@pytest.mark.parametrize(("sex", "body_mass"), [("male", 75.0), ("female", 61.9), ("male", 102.0)])
def test_de_leva_segments_sum_to_body_mass(sex: str, body_mass: float) -> None:
    masses = segment_masses(body_mass, sex=sex)
    assert len(masses) == 14  # head, trunk and six segments on each side
    assert sum(masses.values()) == pytest.approx(body_mass, rel=2e-4)


def test_the_robot_cache_is_bounded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 14: every distinct subject wrote two files to the cache, never cleaned. Now the
    least recently used go first and the cache keeps at most ``CACHE_MAX_FILES``."""
    from app.planning.robots import _cache

    monkeypatch.setenv("BIOPLAN_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(_cache, "CACHE_MAX_FILES", 6)
    first = load_robot("human_arm_2dof", body_mass=60.0)
    for mass in (61.0, 62.0):
        load_robot("human_arm_2dof", body_mass=mass)
    again = load_robot("human_arm_2dof", body_mass=60.0)  # a hit: now the most recent
    assert again.urdf_path == first.urdf_path
    for mass in (63.0, 64.0):
        load_robot("human_arm_2dof", body_mass=mass)
    files = sorted(p.name for p in (tmp_path / "robots").iterdir())
    assert len(files) == 6, files
    assert first.urdf_path.is_file()  # used recently, kept
    newest = load_robot("human_arm_2dof", body_mass=64.0)
    assert newest.urdf_path.is_file() and newest.mjcf_path is not None
    assert newest.mjcf_path.is_file()


def test_human_arm_scales_with_the_subject(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Masses from the URDF are de Leva's fractions of body mass; lengths scale with height."""
    import pinocchio as pin

    monkeypatch.setenv("BIOPLAN_CACHE_DIR", str(tmp_path))
    robot = load_robot("human_arm_2dof", body_mass=90.0, body_height=1.90, sex="male")
    assert robot.urdf_path.parent == tmp_path / "robots"
    assert robot.mjcf_path is not None and robot.mjcf_path.parent == tmp_path / "robots"
    model = pin.buildModelFromUrdf(str(robot.urdf_path))
    # de Leva (1996) male: upper arm 2.71 %, forearm 1.62 %, hand 0.61 % of body mass.
    assert model.inertias[1].mass == pytest.approx(0.0271 * 90.0, rel=1e-5)
    assert model.inertias[2].mass == pytest.approx((0.0162 + 0.0061) * 90.0, rel=1e-5)
    # Upper arm 281.7 mm at 1.741 m stature.
    elbow = model.jointPlacements[2].translation
    assert -elbow[2] == pytest.approx(0.2817 * 1.90 / 1.741, rel=1e-5)
    # Forearm + hand by the parallel-axis theorem, about the transverse (y) axis.
    lf, lh = 0.2689 * 1.90 / 1.741, 0.0862 * 1.90 / 1.741
    mf, mh = 0.0162 * 90.0, 0.0061 * 90.0
    cf, ch = 0.4574 * lf, lf + 0.79 * lh
    c2 = (mf * cf + mh * ch) / (mf + mh)
    iyy = (
        mf * (0.265 * lf) ** 2 + mh * (0.513 * lh) ** 2 + mf * (cf - c2) ** 2 + mh * (ch - c2) ** 2
    )
    assert -model.inertias[2].lever[2] == pytest.approx(c2, rel=1e-5)
    assert model.inertias[2].inertia[1, 1] == pytest.approx(iyy, rel=1e-5)
    # the payload sits at the grip, at the hand's centre of mass
    np.testing.assert_allclose(robot.payload.com, [0.0, 0.0, -ch], rtol=1e-5)
    # the same subject loads the same cached files
    again = load_robot("human_arm_2dof", body_mass=90.0, body_height=1.90)
    assert again.urdf_path == robot.urdf_path
    assert not list(ROBOT_DIR.glob("human_arm_2dof-*"))  # nothing written beside the package


def test_female_table_differs() -> None:
    male = human_arm_segments(65.0, 1.70, sex="male")
    female = human_arm_segments(65.0, 1.70, sex="female")
    assert female.m1 == pytest.approx(0.0255 * 65.0, rel=1e-5)
    assert male.m1 == pytest.approx(0.0271 * 65.0, rel=1e-5)
    assert female.l1 == pytest.approx(0.2751 * 1.70 / 1.735, rel=1e-5)


def test_human_defaults(tmp_path: Path) -> None:
    robot = load_robot("human_arm_2dof")
    assert robot.payload.mass == 12.0
    assert robot.motors == (IDEAL_ACTUATOR, IDEAL_ACTUATOR)
    assert robot.armature.tolist() == [0.0, 0.0]
    np.testing.assert_allclose(np.degrees(robot.default_goal), [20.0, 150.0])
    assert (robot.shoulder_joint, robot.elbow_joint) == (0, 1)
    assert robot.joint_names == ("shoulder_flexion", "elbow_flexion")


# -- curtain-wall robot ----------------------------------------------------------------------------


def quintic_peaks(robot: Robot, duration: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, duration, 3001)
    s = t / duration
    delta = robot.default_goal - robot.default_start
    q = robot.default_start + np.outer(10 * s**3 - 15 * s**4 + 6 * s**5, delta)
    qd = np.outer((30 * s**2 - 60 * s**3 + 30 * s**4) / duration, delta)
    qdd = np.outer((60 * s - 180 * s**2 + 120 * s**3) / duration**2, delta)
    tau = robot.dynamics().inverse_dynamics(q, qd, qdd)
    return np.abs(tau).max(axis=0), np.abs(qd).max(axis=0)


def test_curtain_wall_default_task_feasibility() -> None:
    robot = load_robot("curtain_wall_6dof")
    assert robot.payload.mass == 4.0
    assert (robot.shoulder_joint, robot.elbow_joint) == (1, 2)
    np.testing.assert_allclose(np.degrees(robot.default_goal), [0, 20, 150, 0, 0, 0])
    tau, qd = quintic_peaks(robot, 1.0)
    assert np.all(tau <= 0.8 * robot.tau_max) and np.all(qd <= robot.qd_max)
    tau, qd = quintic_peaks(robot, 0.3)
    assert np.any(tau > robot.tau_max) and np.any(qd > robot.qd_max)


def test_curtain_wall_geometry_and_motors() -> None:
    robot = load_robot("curtain_wall_6dof")
    dyn = robot.dynamics()
    hand0 = dyn.end_effector_position(robot.default_start)
    hand1 = dyn.end_effector_position(robot.default_goal)
    # hanging: the panel centre is 0.495 + 0.45 + wrist + flange + 0.07 below the shoulder
    shoulder = np.array([0.15, 0.0, 1.3])
    assert hand0[0] == pytest.approx(shoulder[0]) and hand0[2] < shoulder[2] - 0.945
    assert hand1[2] > hand0[2] + 0.5 and hand1[0] > hand0[0]  # the curl lifts forward and up
    for motor in robot.motors:
        assert 100.0 <= motor.gear_ratio <= 160.0
        assert motor.rotor_inertia > 0 and motor.viscous_friction > 0
        assert motor.coulomb_friction > 0 and 0 <= motor.regen_efficiency <= 1
    np.testing.assert_allclose(
        robot.armature, [m.gear_ratio**2 * m.rotor_inertia for m in robot.motors]
    )
    assert np.all(robot.qd_max[3:] > robot.qd_max[:3].max() - 1e-9)


# -- Robot / Payload behaviour ---------------------------------------------------------------------


def test_dynamics_cached_and_payload_changes() -> None:
    robot = load_robot("curtain_wall_6dof")
    assert robot.dynamics() is robot.dynamics()
    assert robot.dynamics(armature=False) is not robot.dynamics()
    heavier = robot.with_payload(8.0)
    assert heavier.payload.mass == 8.0 and robot.payload.mass == 4.0
    np.testing.assert_allclose(heavier.payload.inertia, 2.0 * robot.payload.inertia)
    q = np.zeros(6)
    q[1] = math.pi / 2
    zero = np.zeros(6)
    extra = heavier.dynamics().inverse_dynamics(q, zero, zero) - robot.dynamics().inverse_dynamics(
        q, zero, zero
    )
    # 4 kg more at the panel centre, 0.495 + 0.45 + 0.1 + 0.08 + 0.07 m in front of J2
    assert extra[1] == pytest.approx(4.0 * 9.81 * 1.195, rel=1e-12)
    assert robot.with_payload(0.0).payload.mass == 0.0


def test_payload_validation() -> None:
    box = Payload.box(4.0, (0.5, 0.4, 0.02))
    assert box.inertia[2, 2] == pytest.approx(4.0 / 12 * (0.25 + 0.16))
    with pytest.raises(RobotError, match="payload mass is -1"):
        Payload.point(-1.0)
    with pytest.raises(RobotError, match="not symmetric"):
        Payload(mass=1.0, com=np.zeros(3), inertia=np.triu(np.ones((3, 3))), size=np.zeros(3))
    with pytest.raises(RobotError, match=r"payload com has shape \(2,\)"):
        Payload.point(1.0, (0.0, 0.0))


# -- user URDFs and errors ---------------------------------------------------------------------


def test_user_urdf_round_trip_with_mjcf() -> None:
    """The curtain-wall files loaded as a user robot: same joints, limits, and MuJoCo agrees."""
    builtin = load_robot("curtain_wall_6dof")
    user = load_robot(builtin.urdf_path, mjcf=builtin.mjcf_path, payload=3.0)
    assert user.joint_names == builtin.joint_names
    np.testing.assert_array_equal(user.q_min, builtin.q_min)
    np.testing.assert_array_equal(user.tau_max, builtin.tau_max)
    np.testing.assert_array_equal(user.qd_max, builtin.qd_max)
    assert user.payload_body == "flange" and user.payload.mass == 3.0
    assert all(m == NOT_MODELLED for m in user.motors) and not user.motors_modelled
    np.testing.assert_allclose(np.degrees(user.default_goal), [0, 20, 150, 0, 0, 0])
    model = user.mujoco_model()
    data = mujoco.MjData(model)
    rng = np.random.default_rng(11)
    q, qd, qdd = rng.uniform(user.q_min, user.q_max), rng.normal(size=6), rng.normal(size=6)
    data.qpos[:], data.qvel[:], data.qacc[:] = q, qd, qdd
    mujoco.mj_inverse(model, data)
    np.testing.assert_allclose(
        user.dynamics().inverse_dynamics(q, qd, qdd), data.qfrc_inverse, atol=1e-8
    )


GOOD = """<robot name="mini">
  <link name="base"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" velocity="2" effort="30"/></joint>
  <link name="a"><inertial><mass value="1"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="j2" type="{kind}"><parent link="a"/><child link="b"/><origin xyz="0 0 -0.3"/>
    <axis xyz="0 1 0"/>{limit}</joint>
  <link name="b"><inertial><origin xyz="0 0 -0.1"/><mass value="1"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="tool" type="fixed"><parent link="b"/><child link="tool0"/>
    <origin xyz="0.05 0 -0.2"/></joint>
  <link name="tool0"/>
</robot>
"""
LIMIT = '<limit lower="0" upper="2.5" velocity="3" effort="20"/>'


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_user_urdf_with_continuous_joint(tmp_path: Path) -> None:
    path = write(tmp_path, "mini.urdf", GOOD.format(kind="continuous", limit=LIMIT))
    robot = load_robot(path, payload=2.0)
    assert robot.name == "mini" and robot.joint_names == ("j1", "j2")
    assert robot.q_min[1] == -math.inf and robot.q_max[1] == math.inf
    assert (robot.shoulder_joint, robot.elbow_joint) == (0, 1)
    np.testing.assert_allclose(robot.default_goal, np.radians([20.0, 150.0]))
    revolute = load_robot(write(tmp_path, "rev.urdf", GOOD.format(kind="revolute", limit=LIMIT)))
    np.testing.assert_allclose(revolute.default_goal, [math.radians(20.0), 2.5])  # clipped
    assert revolute.payload.mass == 0.0
    assert robot.payload_body == "b"
    # No MJCF: MuJoCo's own URDF compiler builds the simulation model from the URDF.
    model = robot.mujoco_model()
    assert [model.joint(i).name for i in range(model.njnt)] == ["j1", "j2"]


def one_line_error(target: str | Path, **kwargs: object) -> str:
    with pytest.raises(RobotError) as info:
        load_robot(target, **kwargs)  # type: ignore[arg-type]
    message = str(info.value)
    assert "\n" not in message and "expected" in message
    return message


def test_load_errors_are_one_line(tmp_path: Path) -> None:
    message = one_line_error("ur5e_arm")
    assert "unknown robot 'ur5e_arm'" in message and "curtain_wall_6dof" in message

    assert one_line_error(tmp_path / "absent.urdf").startswith("absent.urdf: no such file")

    bad = write(tmp_path, "bad.urdf", "<robot name='x'><link name='a'></robot>")
    message = one_line_error(bad)
    assert message.startswith("bad.urdf: not well-formed XML at line 1")

    no_limit = write(tmp_path, "nolimit.urdf", GOOD.format(kind="revolute", limit=""))
    assert one_line_error(no_limit).startswith("nolimit.urdf: joint 'j2' has no <limit>")

    partial = write(
        tmp_path, "partial.urdf", GOOD.format(kind="revolute", limit='<limit lower="0"/>')
    )
    assert "joint 'j2' <limit> lacks 'upper'" in one_line_error(partial)

    prismatic = write(tmp_path, "slide.urdf", GOOD.format(kind="prismatic", limit=LIMIT))
    assert "joint 'j2' is prismatic (a gripper?): expected it locked" in one_line_error(prismatic)

    wrong_root = write(tmp_path, "root.urdf", "<sdf version='1.6'/>")
    assert "root element is <sdf>: expected <robot>" in one_line_error(wrong_root)

    orphan = write(
        tmp_path, "orphan.urdf", GOOD.format(kind="revolute", limit=LIMIT).replace('"b"/>', '"c"/>')
    )
    assert "child link 'c' is not defined" in one_line_error(orphan)

    good = write(tmp_path, "good.urdf", GOOD.format(kind="revolute", limit=LIMIT))
    mismatch = write(tmp_path, "other.xml", Path(ROBOT_DIR / "human_arm_2dof.xml").read_text())
    assert "no joint 'j1': expected the URDF's joints" in one_line_error(good, mjcf=mismatch)
    broken = write(tmp_path, "broken.xml", "<mujoco><worldbody><body></mujoco>")
    assert one_line_error(good, mjcf=broken).startswith("broken.xml: ")

    assert "expected 20-250 kg" in one_line_error("human_arm_2dof", body_mass=5.0)
    assert "expected 'male' or 'female'" in one_line_error("human_arm_2dof", sex="x")
    assert "expected a finite mass" in one_line_error("curtain_wall_6dof", payload=-2.0)
    assert "expected them only with a robot file" in one_line_error(
        "curtain_wall_6dof", mjcf=mismatch
    )


def test_pinocchio_dynamics_errors(tmp_path: Path) -> None:
    with pytest.raises(RobotError, match="no link 'hand'"):
        PinocchioDynamics(ROBOT_DIR / "curtain_wall_6dof.urdf", payload_body="hand")
    with pytest.raises(ValueError, match="armature"):
        PinocchioDynamics(ROBOT_DIR / "human_arm_2dof.urdf", armature=[1.0])


def test_motor_model_is_the_shared_type() -> None:
    assert all(isinstance(m, MotorModel) for m in load_robot("curtain_wall_6dof").motors)


def test_payload_on_a_fixed_link(tmp_path: Path) -> None:
    """A payload on a fixed child link equals the same payload placed on its parent."""
    path = write(tmp_path, "mini.urdf", GOOD.format(kind="revolute", limit=LIMIT))
    box = Payload.box(3.0, (0.3, 0.2, 0.1), (0.0, 0.0, -0.05))
    on_tool = PinocchioDynamics(path, payload=box, payload_body="tool0")
    moved = Payload(mass=3.0, com=np.array([0.05, 0.0, -0.25]), inertia=box.inertia, size=box.size)
    on_b = PinocchioDynamics(path, payload=moved, payload_body="b")
    rng = np.random.default_rng(13)
    q, qd, qdd = (rng.normal(size=(30, 2)) for _ in range(3))
    np.testing.assert_allclose(
        on_tool.inverse_dynamics(q, qd, qdd), on_b.inverse_dynamics(q, qd, qdd), atol=1e-12
    )
    np.testing.assert_allclose(
        on_tool.end_effector_position(q), on_b.end_effector_position(q), atol=1e-12
    )
    assert on_tool.payload_body == "tool0"
