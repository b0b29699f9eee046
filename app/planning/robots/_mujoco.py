"""Compile a robot's MJCF with the payload, armature and (optionally) friction applied in code."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app.planning.energy import MotorModel
from app.planning.payload import Payload, RobotError

if TYPE_CHECKING:
    import mujoco

    from app.planning.robots._types import Robot

__all__ = ["build_mujoco_model", "combine_inertia", "compile_error", "robot_mujoco_model"]


def combine_inertia(
    mass_a: float,
    com_a: NDArray[np.float64],
    inertia_a: NDArray[np.float64],
    mass_b: float,
    com_b: NDArray[np.float64],
    inertia_b: NDArray[np.float64],
) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """Two rigid bodies in one frame as one (parallel-axis theorem).

    Args:
        mass_a, mass_b: masses [kg].
        com_a, com_b: (3,) centres of mass [m].
        inertia_a, inertia_b: (3, 3) inertias about their own centres of mass [kg m^2].

    Returns:
        (mass, (3,) com, (3, 3) inertia about the combined com).
    """
    mass = mass_a + mass_b
    if mass <= 0.0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    com = (mass_a * com_a + mass_b * com_b) / mass
    inertia = inertia_a + inertia_b
    for m, c in ((mass_a, com_a), (mass_b, com_b)):
        d = c - com
        inertia = inertia + m * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return mass, com, inertia


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def build_mujoco_model(
    mjcf_path: Path,
    *,
    joint_names: Sequence[str],
    payload: Payload,
    payload_body: str,
    armature: NDArray[np.float64] | None,
    motors: Sequence[MotorModel] | None,
    locks: Mapping[str, float] | None = None,
    source: str | None = None,
) -> mujoco.MjModel:
    """Load ``mjcf_path`` through MjSpec, apply locks/payload/armature/friction, compile.

    A URDF works too (MuJoCo's own URDF compiler reads it; it has no actuators, so the
    simulator drives it through ``qfrc_applied``).

    Args:
        mjcf_path: the MJCF file.
        joint_names: (n,) joints that receive armature / friction.
        payload: merged into ``payload_body``'s inertial (parallel-axis theorem).
        payload_body: MJCF body carrying the payload.
        armature: (n,) joint armature [kg m^2], or None to leave the file's values.
        motors: (n,) motor models whose viscous / Coulomb friction become ``damping`` /
            ``frictionloss``, or None for no friction.
        locks: joints removed from the model, their bodies fixed at the given values (name ->
            rad, or m for slide joints).
        source: the user's file ``mjcf_path`` was made from (a URDF compiled through a
            cached copy), named in errors instead of the cache file.

    Returns:
        The compiled model.
    """
    import mujoco

    name = mjcf_path.name if source is None else source
    try:
        spec = mujoco.MjSpec.from_file(str(mjcf_path))
        base_model = spec.compile()
    except Exception as exc:  # mujoco reports parse and compile errors as ValueError
        raise RobotError(compile_error(name, exc)) from exc

    if locks:
        _lock_joints(spec, base_model, locks, name)
    joints = []
    for joint_name in joint_names:
        joint = spec.joint(joint_name)
        if joint is None:
            raise RobotError(f"{name}: no joint '{joint_name}': expected the URDF's joints")
        joints.append(joint)

    if payload.mass > 0.0:
        _merge_payload(spec, base_model, payload, payload_body, name)
    _set_joint_dynamics(joints, armature, motors)

    try:
        return spec.compile()
    except Exception as exc:
        raise RobotError(compile_error(name, exc)) from exc


def _merge_payload(
    spec: mujoco.MjSpec, base_model: mujoco.MjModel, payload: Payload, payload_body: str, name: str
) -> None:
    """Merge ``payload`` into ``payload_body``'s inertial in ``spec`` (parallel-axis theorem);
    ``base_model`` is ``spec`` compiled without it, ``name`` the file named in errors."""
    import mujoco

    body = spec.body(payload_body)
    if body is None:
        raise RobotError(f"{name}: no body '{payload_body}': expected the payload body")
    # Read the body's inertial as compiled (whatever form the file used: diaginertia + quat,
    # fullinertia or inertia from geoms), then write the combined one back explicitly.
    body_id = mujoco.mj_name2id(base_model, mujoco.mjtObj.mjOBJ_BODY, payload_body)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, base_model.body_iquat[body_id])
    rot_m = rot.reshape(3, 3)
    inertia_body = rot_m @ np.diag(base_model.body_inertia[body_id]) @ rot_m.T
    mass, com, inertia = combine_inertia(
        float(base_model.body_mass[body_id]),
        np.array(base_model.body_ipos[body_id]),
        inertia_body,
        payload.mass,
        payload.com,
        payload.inertia,
    )
    principal, axes = np.linalg.eigh((inertia + inertia.T) / 2)
    if np.linalg.det(axes) < 0.0:
        axes[:, 0] *= -1.0
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, axes.flatten())
    body.mass = mass
    body.ipos = com
    body.iquat = quat
    body.inertia = principal
    body.fullinertia = [np.nan, 0.0, 0.0, 0.0, 0.0, 0.0]
    body.explicitinertial = True


def _set_joint_dynamics(
    joints: Sequence[Any],
    armature: NDArray[np.float64] | None,
    motors: Sequence[MotorModel] | None,
) -> None:
    """Write the armature (n,) [kg m^2] and the motors' viscous [N m s/rad] and Coulomb [N m]
    friction into the spec's joints (n,); None leaves the file's values."""
    if armature is not None:
        for joint, value in zip(joints, armature, strict=True):
            joint.armature = float(value)
    if motors is not None:
        for joint, motor in zip(joints, motors, strict=True):
            try:
                joint.damping = float(motor.viscous_friction)  # MuJoCo 3: one coefficient
            except TypeError:
                # MuJoCo 4 holds polynomial damping coefficients; the first is the linear one.
                joint.damping = [float(motor.viscous_friction), 0.0, 0.0]
            joint.frictionloss = float(motor.coulomb_friction)


def compile_error(name: str, exc: BaseException) -> str:
    """MuJoCo's reason, for the user's file, with the fix when one is known."""
    reason = _one_line(exc)
    if "inertia must have positive eigenvalues" in reason or "inertia must satisfy" in reason:
        return (
            f"{name}: MuJoCo cannot compile it ({reason}): expected positive principal "
            "inertias with A + B >= C on that link (fix its <inertial>, or give the URDF alone: "
            "its MuJoCo copy raises such inertias to the smallest MuJoCo accepts and says so)"
        )
    return f"{name}: MuJoCo cannot compile it ({reason}): expected a valid MJCF model"


def _lock_joints(spec: Any, model: Any, locks: Mapping[str, float], file: str) -> None:
    """Remove each locked joint and pose its body as the joint at the locked value would.

    A hinge at ``pos`` p about unit axis a turned by (value - ref) moves the body by
    Trans(p) Rot(a, angle) Trans(-p); a slide moves it by (value - ref) a. The compiled
    model's relative body pose is the starting point, so any orientation form of the file works.
    """
    import mujoco

    for joint_name, value in locks.items():
        joint = spec.joint(joint_name)
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint_name)
        if joint is None or jid < 0:
            raise RobotError(f"{file}: no joint '{joint_name}' to lock: expected a joint name")
        kind = int(model.jnt_type[jid])
        body_id = int(model.jnt_bodyid[jid])
        offset = float(value) - float(model.qpos0[model.jnt_qposadr[jid]])
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.body_quat[body_id])
        rot_b = rot.reshape(3, 3)
        pos = np.array(model.body_pos[body_id], dtype=np.float64)
        axis = np.array(model.jnt_axis[jid], dtype=np.float64)
        quat = np.array(model.body_quat[body_id], dtype=np.float64)
        if kind == int(mujoco.mjtJoint.mjJNT_SLIDE):
            pos = pos + rot_b @ (offset * axis)
        elif kind == int(mujoco.mjtJoint.mjJNT_HINGE):
            turn = np.zeros(4)
            mujoco.mju_axisAngle2Quat(turn, axis, offset)
            turn_m = np.zeros(9)
            mujoco.mju_quat2Mat(turn_m, turn)
            p = np.array(model.jnt_pos[jid], dtype=np.float64)
            pos = pos + rot_b @ (p - turn_m.reshape(3, 3) @ p)
            mujoco.mju_mulQuat(quat, quat.copy(), turn)
        else:
            raise RobotError(
                f"{file}: joint '{joint_name}' is not a hinge or slide: cannot lock it"
            )
        body = spec.body(model.body(body_id).name)
        body.pos = pos
        body.quat = quat
        body.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT
        for actuator in list(spec.actuators):
            if actuator.target == joint_name:
                spec.delete(actuator)
        for equality in list(spec.equalities):
            if joint_name in (equality.name1, equality.name2):
                spec.delete(equality)
        spec.delete(joint)


def robot_mujoco_model(
    robot: Robot, *, armature: bool = True, friction: bool = False
) -> mujoco.MjModel:
    """A robot's MJCF compiled with its payload and armature applied exactly as in its
    dynamics (``Robot.mujoco_model()`` calls this).

    Args:
        robot: the robot (its MJCF, joints, payload, motors and locks).
        armature: set each joint's ``armature`` to the motor's N^2 J_m [kg m^2].
        friction: also set joint ``damping`` to the motor's viscous friction [Nm s/rad] and
            ``frictionloss`` to its Coulomb friction [Nm] (off by default so that the model
            matches the dynamics, which are frictionless; friction is accounted for in the
            energy model).

    Returns:
        A fresh ``mujoco.MjModel`` (callers may modify it).

    Raises:
        RobotError: the robot has no MJCF, or the MJCF lacks the payload body or a joint.
    """
    if robot.mjcf_path is None:
        raise RobotError(
            f"robot '{robot.name}' ({robot.urdf_path.name}) has no MJCF: "
            "expected load_robot(..., mjcf=path) for a MuJoCo model"
        )
    return build_mujoco_model(
        robot.mjcf_path,
        joint_names=robot.joint_names,
        payload=robot.payload,
        payload_body=robot.payload_body,
        armature=robot.armature if armature else None,
        motors=robot.motors if friction else None,
        locks=robot.locks,
        source=_model_source(robot),
    )


def _model_source(robot: Robot) -> str | None:
    """The user's URDF when the MuJoCo model is its cached copy (no MJCF of their own)."""
    spec = robot.spec
    source = spec.get("source") if spec else None
    if not isinstance(source, str) or spec.get("mjcf") or not source.endswith(".urdf"):
        return None
    return f"{Path(source).name} (MuJoCo's copy {Path(str(robot.mjcf_path)).name})"
