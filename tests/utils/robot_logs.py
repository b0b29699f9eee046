"""Synthetic robot logs for identification and validation tests: arms, motions, writers.

Torques come from MuJoCo's inverse dynamics (``mj_inverse``) of a *true* URDF (masses changed,
a payload added), so the Pinocchio-based identification is checked against another engine.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = [
    "arm_urdf",
    "excitation",
    "mujoco_torques",
    "write_bag",
    "write_generic_csv",
    "write_ur_csv",
]

#: Joint axes of the synthetic arms (a Panda-like alternation of yaw and pitch).
_AXES = ("0 0 1", "0 1 0", "0 0 1", "0 1 0", "0 0 1", "0 1 0", "0 0 1")


def arm_urdf(
    n: int = 3,
    *,
    name: str = "arm",
    masses: Sequence[float] | None = None,
    payload: float = 0.0,
) -> str:
    """A serial arm of ``n`` revolute joints (links 0.3 m long, up from the base).

    Args:
        masses: (n,) link masses [kg] (default 4, 3.5, 3, ... kg).
        payload: a point mass [kg] 0.05 m beyond the last link's origin, as a fixed child link
            ``payload`` (the *true* robot carries it; the nominal URDF has none).
    """
    masses = list(masses) if masses is not None else [4.0 - 0.5 * j for j in range(n)]
    parts = ['<?xml version="1.0"?>', f'<robot name="{name}">', '<link name="base"/>']
    parent = "base"
    for j in range(n):
        m = masses[j]
        length = 0.3 if j < n - 1 else 0.1
        ixx = m * length * length / 12.0 + 0.002 * (j + 1)
        izz = 0.5 * m * 0.05 * 0.05 + 0.001
        parts.append(
            f'<link name="link{j + 1}"><inertial><origin xyz="0.01 0.005 {0.45 * length:.4f}"/>'
            f'<mass value="{m}"/><inertia ixx="{ixx:.6f}" iyy="{ixx * 1.1:.6f}" izz="{izz:.6f}" '
            f'ixy="0.0005" ixz="0" iyz="0"/></inertial></link>'
        )
        origin = "0 0 0.1" if j == 0 else "0 0 0.3"
        parts.append(
            f'<joint name="joint{j + 1}" type="revolute"><parent link="{parent}"/>'
            f'<child link="link{j + 1}"/><origin xyz="{origin}"/><axis xyz="{_AXES[j % 7]}"/>'
            '<limit lower="-3.0" upper="3.0" effort="200" velocity="3.0"/></joint>'
        )
        parent = f"link{j + 1}"
    if payload > 0.0:
        parts.append(
            f'<link name="payload"><inertial><origin xyz="0 0 0"/><mass value="{payload}"/>'
            '<inertia ixx="1e-6" iyy="1e-6" izz="1e-6" ixy="0" ixz="0" iyz="0"/></inertial></link>'
            f'<joint name="payload_mount" type="fixed"><parent link="link{n}"/>'
            '<child link="payload"/><origin xyz="0.05 0 0.1"/></joint>'
        )
    parts.append("</robot>")
    return "\n".join(parts)


def excitation(
    duration: float, rate: float, n: int, *, seed: int = 0, amplitude: float = 0.8
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, q, qd, qdd) of a sum of five sines per joint (analytic derivatives)."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(duration * rate) + 1) / rate
    q, qd, qdd = (np.zeros((t.size, n)) for _ in range(3))
    base = 2.0 * math.pi / 4.0
    for j in range(n):
        for k in range(1, 6):
            a = amplitude / (k * 1.7) * rng.uniform(0.5, 1.0)
            w, phase = base * k * rng.uniform(0.8, 1.2), rng.uniform(0, 2 * math.pi)
            q[:, j] += a * np.sin(w * t + phase)
            qd[:, j] += a * w * np.cos(w * t + phase)
            qdd[:, j] -= a * w * w * np.sin(w * t + phase)
    return t, q, qd, qdd


def mujoco_torques(robot: object, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """(T, n) joint torques of ``robot`` (a loaded Robot) by MuJoCo's ``mj_inverse``."""
    import mujoco

    model = robot.mujoco_model(armature=True)  # type: ignore[attr-defined]
    data = mujoco.MjData(model)
    out = np.empty_like(q)
    for k in range(q.shape[0]):
        data.qpos[:] = q[k]
        data.qvel[:] = qd[k]
        data.qacc[:] = qdd[k]
        mujoco.mj_inverse(model, data)
        out[k] = data.qfrc_inverse
    return out


def write_generic_csv(
    path: Path,
    t: np.ndarray,
    names: Sequence[str],
    q: np.ndarray,
    tau: np.ndarray | None,
    qd: np.ndarray | None = None,
) -> Path:
    """A generic robot-log CSV (``time``, ``<joint>/position|velocity|effort``)."""
    header = ["time"]
    columns = [t[:, None]]
    for j, name in enumerate(names):
        header.append(f"{name}/position")
        columns.append(q[:, j : j + 1])
        if qd is not None:
            header.append(f"{name}/velocity")
            columns.append(qd[:, j : j + 1])
        if tau is not None:
            header.append(f"{name}/effort")
            columns.append(tau[:, j : j + 1])
    table = np.hstack(columns)
    np.savetxt(path, table, delimiter=",", header=",".join(header), comments="", fmt="%.10g")
    return path


def write_ur_csv(
    path: Path,
    t: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    *,
    current: np.ndarray | None = None,
    moment: np.ndarray | None = None,
    delimiter: str = " ",
) -> Path:
    """A Universal Robots RTDE recorder CSV (six joints; space-separated like record.py)."""
    header = (
        ["timestamp"] + [f"actual_q_{i}" for i in range(6)] + [f"actual_qd_{i}" for i in range(6)]
    )
    columns = [t[:, None], q, qd]
    if current is not None:
        header += [f"actual_current_{i}" for i in range(6)]
        columns.append(current)
    if moment is not None:
        header += [f"target_moment_{i}" for i in range(6)]
        columns.append(moment)
    np.savetxt(
        path,
        np.hstack(columns),
        delimiter=delimiter,
        header=delimiter.join(header),
        comments="",
        fmt="%.10g",
    )
    return path


def write_bag(
    path: Path,
    t: np.ndarray,
    names: Sequence[str],
    q: np.ndarray,
    qd: np.ndarray | None,
    tau: np.ndarray | None,
    *,
    storage: str = "mcap",
    topic: str = "/joint_states",
    other: tuple[str, np.ndarray] | None = None,
) -> Path:
    """A ROS 2 bag of sensor_msgs/msg/JointState written with rosbags (``mcap`` or ``sqlite3``).

    ``other`` = (topic, efforts): a second JointState topic, the same motion, other efforts.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    joint_state = store.types["sensor_msgs/msg/JointState"]
    header_type = store.types["std_msgs/msg/Header"]
    time_type = store.types["builtin_interfaces/msg/Time"]
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    start = 1_700_000_000.0
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        connections = [
            (writer.add_connection(topic, joint_state.__msgtype__, typestore=store), tau)
        ]
        if other is not None:
            second = writer.add_connection(other[0], joint_state.__msgtype__, typestore=store)
            connections.append((second, other[1]))
        for k in range(t.size):
            stamp = start + float(t[k])
            sec = int(stamp)
            for connection, efforts in connections:
                message = joint_state(
                    header=header_type(
                        stamp=time_type(sec=sec, nanosec=round((stamp - sec) * 1e9)),
                        frame_id="",
                    ),
                    name=list(names),
                    position=np.asarray(q[k], dtype=np.float64),
                    velocity=np.zeros(0) if qd is None else np.asarray(qd[k], dtype=np.float64),
                    effort=np.zeros(0) if efforts is None else np.asarray(efforts[k], float),
                )
                data = store.serialize_cdr(message, joint_state.__msgtype__)
                writer.write(connection, int(stamp * 1e9), data)
    return path
