"""Inverse dynamics: closed form vs Pinocchio vs MuJoCo, energy balance, closed-form spot checks."""

from __future__ import annotations

import math
import pickle
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.integrate import simpson

from app.planning.dynamics import Dynamics, PinocchioDynamics, PlanarArm2DOF
from app.planning.robots import Payload, Robot, human_arm_segments, load_robot

G = 9.81


@pytest.fixture(scope="module")
def human() -> Robot:
    return load_robot("human_arm_2dof")


@pytest.fixture(scope="module")
def wall() -> Robot:
    return load_robot("curtain_wall_6dof")


def random_states(
    robot: Robot, count: int, seed: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    rng = np.random.default_rng(seed)
    n = robot.n_joints
    lo = np.where(np.isfinite(robot.q_min), robot.q_min, -math.pi)
    hi = np.where(np.isfinite(robot.q_max), robot.q_max, math.pi)
    q = rng.uniform(lo, hi, size=(count, n))
    qd = rng.uniform(-1.0, 1.0, size=(count, n)) * robot.qd_max
    qdd = rng.normal(scale=20.0, size=(count, n))
    return q, qd, qdd


# -- closed form vs Pinocchio -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("subject", "payload"),
    [({}, None), ({"body_mass": 58.0, "body_height": 1.62, "sex": "female"}, 5.0)],
)
def test_planar_closed_form_matches_pinocchio(
    subject: dict[str, Any], payload: float | None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("BIOPLAN_CACHE_DIR", str(tmp_path))
    robot = load_robot("human_arm_2dof", payload=payload, **subject)
    closed = PlanarArm2DOF.from_robot(robot)
    pinned = robot.dynamics()
    q, qd, qdd = random_states(robot, 500, seed=1)

    np.testing.assert_allclose(
        closed.inverse_dynamics(q, qd, qdd), pinned.inverse_dynamics(q, qd, qdd), rtol=0, atol=1e-9
    )
    np.testing.assert_allclose(closed.mass_matrix(q), pinned.mass_matrix(q), rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        closed.kinetic_energy(q, qd), pinned.kinetic_energy(q, qd), rtol=0, atol=1e-9
    )
    pe_closed, pe_pin = closed.potential_energy(q), pinned.potential_energy(q)
    np.testing.assert_allclose(pe_closed - pe_closed[0], pe_pin - pe_pin[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        closed.end_effector_position(q), pinned.end_effector_position(q), rtol=0, atol=1e-9
    )
    # The payload matters: without it the torques differ by far more than the tolerance.
    bare = PlanarArm2DOF.from_robot(robot.with_payload(0.0))
    assert np.abs(bare.inverse_dynamics(q, qd, qdd) - closed.inverse_dynamics(q, qd, qdd)).max() > 1


def test_static_gravity_torque_closed_form(human: Robot) -> None:
    """Arm horizontal forward, q = (90 deg, 0): a pendulum's g * sum(m * lever arm)."""
    s = human_arm_segments(75.0, 1.75, sex="male")
    mp = human.payload.mass
    expected = np.array(
        [
            G * (s.m1 * s.lc1 + s.m2 * (s.l1 + s.lc2) + mp * (s.l1 + s.l2)),
            G * (s.m2 * s.lc2 + mp * s.l2),
        ]
    )
    q = np.array([math.pi / 2, 0.0])
    zero = np.zeros(2)
    for dyn in (PlanarArm2DOF.from_robot(human), human.dynamics()):
        np.testing.assert_allclose(dyn.inverse_dynamics(q, zero, zero), expected, rtol=1e-12)
        # Hanging straight down needs no torque.
        np.testing.assert_allclose(dyn.inverse_dynamics(zero, zero, zero), zero, atol=1e-12)
        # Sign convention: q1 = 90 deg puts the hand forward at shoulder height, q2 = 90 deg
        # (arm hanging) points the forearm forward.
        np.testing.assert_allclose(
            dyn.end_effector_position(q), [s.l1 + s.l2, 0.0, 0.0], atol=1e-12
        )
        np.testing.assert_allclose(
            dyn.end_effector_position([0.0, math.pi / 2]), [s.l2, 0.0, -s.l1], atol=1e-12
        )


def test_curtain_wall_static_torques_from_parameter_table(wall: Robot) -> None:
    """Arm stretched forward (J2 = 90 deg): J2 and J3 hold g * sum(m * horizontal lever)."""
    row: dict[str, Any] = {str(r["name"]): r["value"] for r in wall.parameters}
    links = ["upper_arm", "forearm", "wrist_1", "wrist_2", "flange"]
    joints = ["j3_elbow_pitch", "j4_wrist_roll", "j5_wrist_pitch", "j6_wrist_roll"]
    # distance of each link's joint from J2 along the (straight) arm
    starts = [0.0]
    for joint in joints:
        starts.append(starts[-1] - row[f"{joint}.origin"][2])
    levers = [start - row[f"{link}.com"][2] for start, link in zip(starts, links, strict=True)]
    masses = [row[f"{link}.mass"] for link in links]
    payload_lever = starts[-1] - row["payload.com"][2]
    mp = wall.payload.mass
    tau_j2 = G * (sum(m * x for m, x in zip(masses, levers, strict=True)) + mp * payload_lever)
    tau_j3 = G * (
        sum(m * (x - starts[1]) for m, x in zip(masses[1:], levers[1:], strict=True))
        + mp * (payload_lever - starts[1])
    )
    q = np.zeros(6)
    q[1] = math.pi / 2
    tau = wall.dynamics().inverse_dynamics(q, np.zeros(6), np.zeros(6))
    np.testing.assert_allclose(tau[[0, 1, 2, 3, 5]], [0.0, tau_j2, tau_j3, 0.0, 0.0], atol=1e-9)
    assert tau_j2 > 0  # holding the arm up against gravity takes positive torque


# -- Pinocchio vs MuJoCo ----------------------------------------------------------------------


def mujoco_inverse(
    model: mujoco.MjModel, q: NDArray[np.float64], qd: NDArray[np.float64], qdd: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    data = mujoco.MjData(model)
    n = model.nv
    tau = np.empty_like(q)
    mass = np.empty((len(q), n, n))
    for i in range(len(q)):
        data.qpos[:], data.qvel[:], data.qacc[:] = q[i], qd[i], qdd[i]
        mujoco.mj_inverse(model, data)
        tau[i] = data.qfrc_inverse
        mujoco.mj_fullM(model, data, mass[i])
    return tau, mass


@pytest.mark.parametrize("name", ["human_arm_2dof", "curtain_wall_6dof"])
@pytest.mark.parametrize(("payload", "armature"), [(None, True), (7.5, False)])
def test_pinocchio_matches_mujoco_inverse(name: str, payload: float | None, armature: bool) -> None:
    robot = load_robot(name, payload=payload)
    q, qd, qdd = random_states(robot, 200, seed=2)
    dyn = robot.dynamics(armature=armature)
    tau_mj, mass_mj = mujoco_inverse(robot.mujoco_model(armature=armature), q, qd, qdd)
    np.testing.assert_allclose(dyn.inverse_dynamics(q, qd, qdd), tau_mj, rtol=0, atol=1e-8)
    np.testing.assert_allclose(dyn.mass_matrix(q), mass_mj, rtol=0, atol=1e-8)
    if armature and robot.armature.any():
        np.testing.assert_allclose(
            np.diagonal(mass_mj, axis1=1, axis2=2)
            - np.diagonal(robot.dynamics(armature=False).mass_matrix(q), axis1=1, axis2=2),
            np.broadcast_to(robot.armature, q.shape),
            atol=1e-10,
        )


def test_mujoco_friction_is_the_motor_friction(wall: Robot) -> None:
    model = wall.mujoco_model(friction=True)
    np.testing.assert_array_equal(model.dof_damping, [m.viscous_friction for m in wall.motors])
    np.testing.assert_array_equal(model.dof_frictionloss, [m.coulomb_friction for m in wall.motors])
    model.dof_frictionloss[:] = 0.0  # a constraint in MuJoCo; damping alone is a passive force
    q, qd, qdd = random_states(wall, 20, seed=3)
    tau_mj, _ = mujoco_inverse(model, q, qd, qdd)
    viscous = np.array([m.viscous_friction for m in wall.motors])
    np.testing.assert_allclose(
        wall.dynamics().inverse_dynamics(q, qd, qdd) + viscous * qd, tau_mj, atol=1e-8
    )


def test_energies_and_hand_match_mujoco(wall: Robot) -> None:
    model = wall.mujoco_model()
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data = mujoco.MjData(model)
    body = model.body(wall.payload_body).id
    q, qd, _ = random_states(wall, 50, seed=4)
    dyn = wall.dynamics()
    pe, ke, hand = dyn.potential_energy(q), dyn.kinetic_energy(q, qd), dyn.end_effector_position(q)
    for i in range(len(q)):
        data.qpos[:], data.qvel[:] = q[i], qd[i]
        mujoco.mj_forward(model, data)
        mujoco.mj_energyPos(model, data)
        mujoco.mj_energyVel(model, data)
        assert pe[i] == pytest.approx(data.energy[0], abs=1e-9)
        assert ke[i] == pytest.approx(data.energy[1], abs=1e-9)
        expected = data.xpos[body] + data.xmat[body].reshape(3, 3) @ wall.payload.com
        np.testing.assert_allclose(hand[i], expected, atol=1e-12)


def test_gravity_torque_is_potential_gradient(wall: Robot) -> None:
    dyn = wall.dynamics()
    q, _, _ = random_states(wall, 20, seed=5)
    step = 1e-6
    eye = np.eye(6) * step
    grad = np.stack(
        [(dyn.potential_energy(q + e) - dyn.potential_energy(q - e)) / (2 * step) for e in eye],
        axis=-1,
    )
    np.testing.assert_allclose(grad, dyn.inverse_dynamics(q, 0 * q, 0 * q), atol=1e-6)


# -- energy balance -----------------------------------------------------------------------------


def random_quintics(
    n: int, count: int, seed: int, duration: float, samples: int
) -> tuple[NDArray[np.float64], ...]:
    """(count, T, n) positions, velocities, accelerations of random quintic polynomials."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, duration, samples)
    coeffs = rng.normal(scale=1.5, size=(count, n, 6)) / duration ** np.arange(6)
    powers = np.arange(6)
    basis = t[:, None] ** powers
    d_basis = np.where(powers > 0, powers * t[:, None] ** np.maximum(powers - 1, 0), 0.0)
    dd_basis = np.where(
        powers > 1, powers * (powers - 1) * t[:, None] ** np.maximum(powers - 2, 0), 0.0
    )
    q = np.einsum("tk,cnk->ctn", basis, coeffs)
    qd = np.einsum("tk,cnk->ctn", d_basis, coeffs)
    qdd = np.einsum("tk,cnk->ctn", dd_basis, coeffs)
    return t, q, qd, qdd


def check_energy_balance(dyn: Dynamics, seed: int) -> None:
    """Frictionless: the work done by the joint torques equals the change of KE + PE.

    Simpson's rule on 4001 samples over 1 s. Its error falls as h^4 (measured: 2e-12 of the
    absolute work at 4001 samples, 2e-8 at 401); the tolerance is 1e-9 of the absolute work.
    """
    t, q, qd, qdd = random_quintics(dyn.n_joints, count=8, seed=seed, duration=1.0, samples=4001)
    tau = dyn.inverse_dynamics(q, qd, qdd)
    power = np.einsum("ctn,ctn->ct", tau, qd)
    work = simpson(power, x=t, axis=-1)
    energy = dyn.kinetic_energy(q, qd) + dyn.potential_energy(q)
    scale = simpson(np.abs(power), x=t, axis=-1)
    assert np.all(scale > 1.0)
    np.testing.assert_allclose(work, energy[:, -1] - energy[:, 0], rtol=0, atol=1e-9 * scale.max())


def test_energy_balance_closed_form(human: Robot) -> None:
    check_energy_balance(PlanarArm2DOF.from_robot(human.with_payload(12.0)), seed=6)


@pytest.mark.parametrize("name", ["human_arm_2dof", "curtain_wall_6dof"])
def test_energy_balance_pinocchio(name: str) -> None:
    check_energy_balance(load_robot(name).dynamics(armature=True), seed=7)


# -- batching, continuous joints, bad input -------------------------------------------------------


def test_batch_shapes_are_free(wall: Robot) -> None:
    dyn = wall.dynamics()
    q, qd, qdd = random_states(wall, 60, seed=8)
    flat = dyn.inverse_dynamics(q, qd, qdd)
    batched = dyn.inverse_dynamics(*(x.reshape(3, 4, 5, 6) for x in (q, qd, qdd)))
    assert batched.shape == (3, 4, 5, 6)
    np.testing.assert_array_equal(batched.reshape(60, 6), flat)
    np.testing.assert_array_equal(dyn.inverse_dynamics(q[7], qd[7], qdd[7]), flat[7])
    assert dyn.mass_matrix(q.reshape(6, 10, 6)).shape == (6, 10, 6, 6)
    assert dyn.potential_energy(q.reshape(6, 10, 6)).shape == (6, 10)
    assert dyn.kinetic_energy(q[0], qd[0]).shape == ()
    assert dyn.end_effector_position(q.reshape(2, 30, 6)).shape == (2, 30, 3)
    assert dyn.inverse_dynamics(np.zeros((0, 6)), np.zeros((0, 6)), np.zeros((0, 6))).shape == (
        0,
        6,
    )


CHAIN = """<?xml version="1.0"?>
<robot name="two">
  <link name="base"/>
  <joint name="a" type="{kind}"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 1" rpy="0.3 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-10" upper="10" velocity="5" effort="50"/></joint>
  <link name="l1"><inertial><origin xyz="0.2 0 0"/><mass value="2"/>
    <inertia ixx="0.01" ixy="0.001" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial></link>
  <joint name="b" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.4 0 0"/><axis xyz="0.6 0.8 0"/>
    <limit lower="-3" upper="3" velocity="5" effort="50"/></joint>
  <link name="l2"><inertial><origin xyz="0.1 0.1 0"/><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial></link>
</robot>
"""


def test_continuous_joint_equals_revolute(tmp_path: Path) -> None:
    root = tmp_path
    (root / "rev.urdf").write_text(CHAIN.format(kind="revolute"))
    (root / "cont.urdf").write_text(CHAIN.format(kind="continuous"))
    rev = PinocchioDynamics(root / "rev.urdf")
    cont = PinocchioDynamics(root / "cont.urdf")
    rng = np.random.default_rng(9)
    q, qd, qdd = (rng.normal(size=(40, 2)) * s for s in (3.0, 2.0, 5.0))
    np.testing.assert_allclose(
        cont.inverse_dynamics(q, qd, qdd), rev.inverse_dynamics(q, qd, qdd), atol=1e-12
    )
    np.testing.assert_allclose(cont.potential_energy(q), rev.potential_energy(q), atol=1e-12)
    np.testing.assert_allclose(cont.mass_matrix(q), rev.mass_matrix(q), atol=1e-12)
    # and the unaligned axis / rotated origin are handled alike by the vectorised kinematics
    check_energy_balance(cont, seed=10)


def test_bad_input_names_the_problem(human: Robot) -> None:
    dyn = human.dynamics()
    closed = PlanarArm2DOF.from_robot(human)
    for model in (dyn, closed):
        with pytest.raises(ValueError, match=r"q has shape \(5, 3\): expected \(\.\.\., 2\)"):
            model.inverse_dynamics(np.zeros((5, 3)), np.zeros((5, 3)), np.zeros((5, 3)))
        with pytest.raises(ValueError, match=r"qd has shape .* but q has shape"):
            model.inverse_dynamics(np.zeros((5, 2)), np.zeros((4, 2)), np.zeros((5, 2)))
        with pytest.raises(ValueError, match="qdd contains NaN"):
            model.inverse_dynamics(np.zeros(2), np.zeros(2), [np.nan, 0.0])
        with pytest.raises(ValueError, match="q is not numeric"):
            model.potential_energy("abc")
    with pytest.raises(ValueError, match="has no planar 2-link segment table"):
        PlanarArm2DOF.from_robot(load_robot("curtain_wall_6dof"))
    with pytest.raises(ValueError, match=r"m1=-1\.0: expected a finite value > 0"):
        PlanarArm2DOF(l1=0.3, lc1=0.1, m1=-1.0, i1=0.0, l2=0.3, lc2=0.1, m2=1.0, i2=0.0)


def test_models_survive_pickling(wall: Robot) -> None:
    """Job runners ship robots and dynamics to worker processes."""
    dyn = wall.dynamics()
    q, qd, qdd = random_states(wall, 10, seed=12)
    clone = pickle.loads(pickle.dumps(dyn))
    np.testing.assert_array_equal(
        clone.inverse_dynamics(q, qd, qdd), dyn.inverse_dynamics(q, qd, qdd)
    )
    robot = pickle.loads(pickle.dumps(wall))
    np.testing.assert_array_equal(
        robot.dynamics().inverse_dynamics(q, qd, qdd), dyn.inverse_dynamics(q, qd, qdd)
    )
    closed = PlanarArm2DOF.from_robot(load_robot("human_arm_2dof"))
    assert pickle.loads(pickle.dumps(closed)) == closed


NEGATIVE = """<robot name="neg">
  <link name="base"/>
  <joint name="a" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0.1 0.2 1" rpy="0.3 -0.2 0.1"/><axis xyz="0 0 -1"/>
    <limit lower="-3" upper="3" velocity="5" effort="50"/></joint>
  <link name="l1"><inertial><origin xyz="0.2 0.05 0" rpy="0.1 0.2 0.3"/><mass value="2"/>
    <inertia ixx="0.01" ixy="0.001" ixz="0.002" iyy="0.05" iyz="0" izz="0.05"/></inertial></link>
  <joint name="b" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.4 0 0.1" rpy="0 0.5 0"/><axis xyz="-1 0 0"/>
    <limit lower="-3" upper="3" velocity="5" effort="50"/></joint>
  <link name="l2"><inertial><origin xyz="0.1 0.1 0"/><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial></link>
  <joint name="c" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0 0.3 0"/><axis xyz="0 -1 0"/>
    <limit lower="-3" upper="3" velocity="5" effort="50"/></joint>
  <link name="l3"><inertial><origin xyz="0 0 -0.1"/><mass value="0.5"/>
    <inertia ixx="0.003" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.001"/></inertial></link>
  <joint name="tool" type="fixed"><parent link="l3"/><child link="tool0"/>
    <origin xyz="0.02 -0.03 -0.2" rpy="0.4 0.1 -0.3"/></joint>
  <link name="tool0"/>
</robot>
"""


def test_negative_axes_are_aligned_without_changing_anything(tmp_path: Path) -> None:
    """Joints about -x/-y/-z become Pinocchio's RX/RY/RZ; dynamics and frames stay the same."""
    import pinocchio as pin

    path = tmp_path / "neg.urdf"
    path.write_text(NEGATIVE)
    raw = pin.buildModelFromUrdf(str(path))
    assert {raw.joints[j].shortname() for j in (1, 2, 3)} == {"JointModelRevoluteUnaligned"}
    payload = Payload.box(2.0, (0.3, 0.2, 0.1), (0.01, 0.02, -0.05))
    dyn = PinocchioDynamics(path, payload=payload, payload_body="tool0")
    aligned = dyn.model
    assert [aligned.joints[j].shortname() for j in (1, 2, 3)] == [
        "JointModelRZ",
        "JointModelRX",
        "JointModelRY",
    ]
    frame = raw.frames[raw.getFrameId("tool0")]
    raw.inertias[3] = raw.inertias[3] + frame.placement.act(
        pin.Inertia(payload.mass, payload.com, payload.inertia)
    )
    raw_data, aligned_data = raw.createData(), aligned.createData()
    rng = np.random.default_rng(14)
    q, qd, qdd = (rng.normal(size=(25, 3)) for _ in range(3))
    tau = dyn.inverse_dynamics(q, qd, qdd)
    mass = dyn.mass_matrix(q)
    hand = dyn.end_effector_position(q)
    for i in range(len(q)):
        np.testing.assert_allclose(tau[i], pin.rnea(raw, raw_data, q[i], qd[i], qdd[i]), atol=1e-12)
        full = pin.crba(raw, raw_data, q[i])
        np.testing.assert_allclose(mass[i], np.triu(full) + np.triu(full, 1).T, atol=1e-12)
        pin.framesForwardKinematics(raw, raw_data, q[i])
        pin.framesForwardKinematics(aligned, aligned_data, q[i])
        for f in range(len(raw.frames)):
            np.testing.assert_allclose(
                aligned_data.oMf[f].homogeneous, raw_data.oMf[f].homogeneous, atol=1e-12
            )
        tool = raw_data.oMf[raw.getFrameId("tool0")]
        np.testing.assert_allclose(hand[i], tool.act(payload.com), atol=1e-12)
        assert dyn.potential_energy(q[i]) == pytest.approx(
            pin.computePotentialEnergy(raw, raw_data, q[i]), abs=1e-12
        )
