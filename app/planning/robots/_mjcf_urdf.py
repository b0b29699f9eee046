"""A URDF generated from an MJCF, so that an MJCF-only robot gets Pinocchio and the viewer too.

MuJoCo compiles the file; the compiled model (body poses relative to their parents, joint
anchors and axes in body frames, principal inertias) is written out as URDF links and joints.
A URDF joint sits at its child link's origin, so each link frame is its body frame moved to the
joint's anchor. The generated URDF is then compared with the MJCF like any URDF/MJCF pair
(``check_same_robot``), which checks this conversion at every load.

Supported: a fixed base, at most one hinge or slide joint per body, joint ``ref`` = 0. Effort
limits come from the joint's ``actuatorfrcrange`` or its actuator's force (or control) range
times the gear; MJCF has no speed limits, so they are unlimited unless a sidecar gives them.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.planning.robots._cache import write_cached
from app.planning.robots._types import RobotError

__all__ = ["urdf_from_mjcf"]

FloatArray = NDArray[np.float64]

#: URDF needs a speed limit; MJCF has none. Written as this value and read back as unlimited.
UNLIMITED_SPEED = 1e6
#: Effort written for a joint without a force limit: the sidecar's ``effort_limits`` must give
#: one (``_user._effort_limits`` refuses it otherwise, naming the joint).
UNLIMITED_EFFORT = 1e12


def _num(value: float) -> str:
    return repr(float(value))


def _vec(values: Any) -> str:
    return " ".join(_num(v) for v in values)


def _rpy(rotation: FloatArray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw of a rotation matrix, R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = math.asin(-max(-1.0, min(1.0, float(rotation[2, 0]))))
    if abs(math.cos(pitch)) > 1e-9:
        roll = math.atan2(float(rotation[2, 1]), float(rotation[2, 2]))
        yaw = math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))
    else:  # gimbal lock: fold yaw into roll
        roll = math.atan2(-float(rotation[1, 2]), float(rotation[1, 1]))
        yaw = 0.0
    return roll, pitch, yaw


def _matrix(quat: Any) -> FloatArray:
    import mujoco

    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, np.asarray(quat, dtype=np.float64))
    return out.reshape(3, 3)


def _effort(model: Any, jid: int, file: str) -> float:
    import mujoco

    if model.jnt_actfrclimited[jid]:
        return float(np.abs(model.jnt_actfrcrange[jid]).max())
    for a in range(model.nu):
        trn_joint = int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)
        if not (trn_joint and int(model.actuator_trnid[a, 0]) == jid):
            continue
        gear = abs(float(model.actuator_gear[a, 0]))
        if model.actuator_forcelimited[a]:
            return gear * float(np.abs(model.actuator_forcerange[a]).max())
        if model.actuator_ctrllimited[a] and int(model.actuator_biastype[a]) == 0:
            return (
                gear
                * float(model.actuator_gainprm[a, 0])
                * float(np.abs(model.actuator_ctrlrange[a]).max())
            )
    return UNLIMITED_EFFORT  # refused at load unless the sidecar gives effort_limits


def _body_joint(model: Any, body: int, file: str) -> int | None:
    """The body's one hinge/slide joint id, None for a welded body; refuses anything else."""
    import mujoco

    count = int(model.body_jntnum[body])
    name = model.body(body).name
    if count == 0:
        return None
    if count > 1:
        raise RobotError(f"{file}: body '{name}' has {count} joints: expected at most one per body")
    jid = int(model.body_jntadr[body])
    kind = int(model.jnt_type[jid])
    if kind not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
        raise RobotError(
            f"{file}: joint '{model.joint(jid).name}' is a free or ball joint: expected a "
            "fixed-base arm of hinge and slide joints"
        )
    if abs(float(model.qpos0[model.jnt_qposadr[jid]])) > 1e-12:
        raise RobotError(
            f"{file}: joint '{model.joint(jid).name}' has ref != 0: expected ref=\"0\""
        )
    return jid


def _link(model: Any, body: int, shift: FloatArray) -> list[str]:
    name = model.body(body).name
    lines = [f'  <link name="{name}">']
    mass = float(model.body_mass[body])
    if mass > 0.0:
        rot = _matrix(model.body_iquat[body])
        inertia = rot @ np.diag(model.body_inertia[body]) @ rot.T
        com = np.asarray(model.body_ipos[body]) - shift
        lines += [
            "    <inertial>",
            f'      <origin xyz="{_vec(com)}" rpy="0 0 0"/>',
            f'      <mass value="{_num(mass)}"/>',
            f'      <inertia ixx="{_num(inertia[0, 0])}" ixy="{_num(inertia[0, 1])}" '
            f'ixz="{_num(inertia[0, 2])}" iyy="{_num(inertia[1, 1])}" '
            f'iyz="{_num(inertia[1, 2])}" izz="{_num(inertia[2, 2])}"/>',
            "    </inertial>",
        ]
    lines.append("  </link>")
    return lines


def _joint(
    model: Any, body: int, jid: int | None, shifts: dict[int, FloatArray], file: str
) -> list[str]:
    import mujoco

    parent = int(model.body_parentid[body])
    rot = _matrix(model.body_quat[body])
    origin = np.asarray(model.body_pos[body]) - shifts[parent] + rot @ shifts[body]
    name = model.body(body).name
    head = f'    <parent link="{model.body(parent).name}"/>\n    <child link="{name}"/>'
    pose = f'    <origin xyz="{_vec(origin)}" rpy="{_vec(_rpy(rot))}"/>'
    if jid is None:
        return [f'  <joint name="{name}_weld" type="fixed">', head, pose, "  </joint>"]
    slide = int(model.jnt_type[jid]) == int(mujoco.mjtJoint.mjJNT_SLIDE)
    limited = bool(model.jnt_limited[jid])
    kind = "prismatic" if slide else ("revolute" if limited else "continuous")
    lower, upper = model.jnt_range[jid] if limited else (0.0, 0.0)
    limit = (
        f'    <limit lower="{_num(lower)}" upper="{_num(upper)}" ' if limited else "    <limit "
    ) + f'velocity="{_num(UNLIMITED_SPEED)}" effort="{_num(_effort(model, jid, file))}"/>'
    return [
        f'  <joint name="{model.joint(jid).name}" type="{kind}">',
        head,
        pose,
        f'    <axis xyz="{_vec(model.jnt_axis[jid])}"/>',
        limit,
        "  </joint>",
    ]


def urdf_from_mjcf(mjcf: Path) -> Path:
    """Compile ``mjcf`` with MuJoCo and write the equivalent URDF (cached, content-addressed).

    Raises:
        RobotError: unreadable MJCF, or a model outside what the module docstring supports.
    """
    import mujoco

    file = mjcf.name
    if not mjcf.is_file():
        raise RobotError(f"{file}: no such file ({mjcf}): expected an MJCF file")
    try:
        model = mujoco.MjModel.from_xml_path(str(mjcf))
    except Exception as exc:  # mujoco reports parse and compile errors as ValueError
        from app.planning.robots._mujoco import compile_error

        raise RobotError(compile_error(file, exc)) from None
    joints = {b: _body_joint(model, b, file) for b in range(1, model.nbody)}
    if all(j is None for j in joints.values()):
        raise RobotError(f"{file}: no moving joint: expected at least two hinge joints")
    shifts: dict[int, FloatArray] = {0: np.zeros(3)}
    for body, jid in joints.items():
        shifts[body] = np.zeros(3) if jid is None else np.asarray(model.jnt_pos[jid], dtype=float)
    name = model.names[: model.names.index(b"\0")].decode() if model.names else mjcf.stem
    lines = ['<?xml version="1.0"?>', f"<!-- generated by BioPlan from {file} -->"]
    lines += [f'<robot name="{name or mjcf.stem}">', f'  <link name="{model.body(0).name}"/>']
    for body, jid in joints.items():
        lines += _link(model, body, shifts[body])
        lines += _joint(model, body, jid, shifts, file)
    lines.append("</robot>")
    return write_cached("\n".join(lines) + "\n", mjcf.stem + ".from_mjcf", ".urdf")
