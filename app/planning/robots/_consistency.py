"""Do a URDF and an MJCF describe the same robot? Checked at load, joint by joint.

Names alone are not enough (a Menagerie UR5e MJCF and another UR5 URDF share every joint name
and still track 98 deg apart). The two models are compared as the planner and the simulator
will use them, with the same locks and payload and without armature or passive forces:

1. every free joint exists in both;
2. at the zero configuration, each joint's axis (world frame) and its anchor relative to the
   first joint's anchor agree (1 deg, 1 mm);
3. the mass each joint carries (its subtree) agrees (1 % + 1 g);
4. inverse dynamics agree at random states: Pinocchio's ``rnea`` vs MuJoCo's ``mj_inverse``
   (1 % of the joint's largest torque, + 1 mNm).

The first disagreement is refused with a ``RobotError`` naming the joint.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app.planning.robots._types import RobotError

if TYPE_CHECKING:
    from app.planning.robots._types import Robot

__all__ = ["check_same_robot"]

FloatArray = NDArray[np.float64]

AXIS_TOL_DEG = 1.0
ANCHOR_TOL_M = 1e-3
MASS_TOL = 0.01
TORQUE_TOL = 0.01
N_STATES = 8


def _pinocchio_frames(robot: Robot) -> tuple[Any, FloatArray, FloatArray, FloatArray]:
    """Pinocchio model, world axes (n, 3), anchors (n, 3) and subtree masses (n,) at q = 0."""
    import pinocchio as pin

    model = robot.dynamics(armature=False).model  # type: ignore[attr-defined]
    data = model.createData()
    q0 = pin.neutral(model)
    pin.computeJointJacobians(model, data, q0)
    pin.computeSubtreeMasses(model, data)
    axes, anchors, masses = [], [], []
    for j in range(1, model.njoints):
        jac = pin.getJointJacobian(model, data, j, pin.ReferenceFrame.WORLD)
        column = model.joints[j].idx_v
        axes.append(np.array(jac[3:6, column]))
        anchors.append(np.array(data.oMi[j].translation))
        masses.append(float(data.mass[j]))
    return model, np.array(axes), np.array(anchors), np.array(masses)


def _mujoco_frames(
    robot: Robot,
) -> tuple[Any, Any, NDArray[np.intp], FloatArray, FloatArray, FloatArray]:
    """MuJoCo model, data, dof addresses, world axes, anchors and subtree masses at q = 0."""
    import mujoco

    model = robot.mujoco_model(armature=False, friction=False)
    model.dof_armature[:] = 0.0
    model.dof_damping[:] = 0.0
    model.dof_frictionloss[:] = 0.0
    model.opt.disableflags |= int(
        mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
        | mujoco.mjtDisableBit.mjDSBL_SPRING
        | mujoco.mjtDisableBit.mjDSBL_DAMPER
    )
    data = mujoco.MjData(model)
    jids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in robot.joint_names]
    data.qpos[:] = model.qpos0
    for j in jids:
        data.qpos[model.jnt_qposadr[j]] = 0.0
    mujoco.mj_forward(model, data)
    axes = np.array([data.xaxis[j] for j in jids])
    anchors = np.array([data.xanchor[j] for j in jids])
    masses = np.array([model.body_subtreemass[model.jnt_bodyid[j]] for j in jids])
    dofs = np.array([model.jnt_dofadr[j] for j in jids], dtype=np.intp)
    return model, data, dofs, axes, anchors, masses


def _check_names(robot: Robot, mjcf_joints: list[str]) -> None:
    missing = [name for name in robot.joint_names if name not in mjcf_joints]
    if missing:
        raise RobotError(
            f"{robot.mjcf_path.name if robot.mjcf_path else 'MJCF'}: no joint '{missing[0]}' of "
            f"the URDF: expected the same joints (the MJCF has {mjcf_joints})"
        )
    extra = [name for name in mjcf_joints if name not in robot.joint_names]
    if extra:
        raise RobotError(
            f"{robot.mjcf_path.name if robot.mjcf_path else 'MJCF'}: joint '{extra[0]}' is not a "
            "free joint of the URDF: expected the same joints (lock it in both with --lock)"
        )


def _check_geometry(
    robot: Robot,
    pin_frames: tuple[FloatArray, FloatArray, FloatArray],
    mj_frames: tuple[FloatArray, FloatArray, FloatArray],
) -> None:
    (pa, pp, pm), (ma, mp, mm) = pin_frames, mj_frames
    pp, mp = pp - pp[0], mp - mp[0]
    for j, name in enumerate(robot.joint_names):
        cosine = float(np.clip(pa[j] @ ma[j], -1.0, 1.0))
        angle = math.degrees(math.acos(cosine))
        if angle > AXIS_TOL_DEG:
            raise RobotError(
                f"URDF and MJCF disagree: joint '{name}' turns about {np.round(pa[j], 3).tolist()} "
                f"in the URDF but {np.round(ma[j], 3).tolist()} in the MJCF at the zero "
                f"configuration ({angle:.1f} deg apart): expected the same robot"
            )
        gap = float(np.linalg.norm(pp[j] - mp[j]))
        if gap > ANCHOR_TOL_M:
            raise RobotError(
                f"URDF and MJCF disagree: joint '{name}' sits {1000 * gap:.1f} mm apart at the "
                "zero configuration: expected the same kinematics"
            )
        if abs(pm[j] - mm[j]) > MASS_TOL * max(pm[j], mm[j]) + 1e-3:
            raise RobotError(
                f"URDF and MJCF disagree: joint '{name}' carries {pm[j]:.3f} kg in the URDF but "
                f"{mm[j]:.3f} kg in the MJCF: expected the same masses"
            )


def _random_states(
    robot: Robot, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray, FloatArray]:
    lower = np.maximum(np.asarray(robot.q_min), -math.pi)
    upper = np.minimum(np.asarray(robot.q_max), math.pi)
    n = robot.n_joints
    q = rng.uniform(lower, upper, size=(N_STATES, n))
    return q, rng.normal(size=(N_STATES, n)), rng.normal(size=(N_STATES, n))


def check_same_robot(robot: Robot) -> None:
    """Refuse a URDF/MJCF pair whose dynamics disagree (see the module docstring).

    Raises:
        RobotError: the first disagreement, naming the joint.
    """
    import mujoco

    model, data, dofs, m_axes, m_anchors, m_masses = _mujoco_frames(robot)
    mjcf_joints = [
        model.joint(j).name
        for j in range(model.njnt)
        if int(model.jnt_type[j])
        in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    ]
    _check_names(robot, mjcf_joints)
    _, p_axes, p_anchors, p_masses = _pinocchio_frames(robot)
    _check_geometry(robot, (p_axes, p_anchors, p_masses), (m_axes, m_anchors, m_masses))
    q, qd, qdd = _random_states(robot, np.random.default_rng(0))
    tau_pin = robot.dynamics(armature=False).inverse_dynamics(q, qd, qdd)
    qadr = np.array(
        [
            model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)]
            for n in robot.joint_names
        ]
    )
    tau_mj = np.empty_like(tau_pin)
    for k in range(N_STATES):
        data.qpos[:] = model.qpos0
        data.qvel[:] = 0.0
        data.qacc[:] = 0.0
        data.qpos[qadr] = q[k]
        data.qvel[dofs] = qd[k]
        data.qacc[dofs] = qdd[k]
        mujoco.mj_inverse(model, data)
        tau_mj[k] = data.qfrc_inverse[dofs]
    scale = np.abs(tau_pin).max(axis=0) + 1e-3
    error = np.abs(tau_pin - tau_mj).max(axis=0)
    bad = np.flatnonzero(error > TORQUE_TOL * scale)
    if bad.size:
        j = int(bad[np.argmax(error[bad] / scale[bad])])
        raise RobotError(
            f"URDF and MJCF disagree: joint '{robot.joint_names[j]}' needs torques up to "
            f"{error[j]:.3g} Nm apart (of {scale[j]:.3g} Nm) at random states (rnea vs "
            "mj_inverse): expected the same inertias"
        )
