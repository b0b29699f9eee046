"""The export formats: CSV, JSON, ROS 2 JointTrajectory YAML, rosbag2 MCAP, URScript, OpenSim.

Each writer takes the plan's motion, the chosen method and its samples at the export rate and
returns the file's bytes. Numbers are written with 17 significant digits (``repr``), so every
value reads back exactly. Units are SI with radians everywhere except the OpenSim motion file,
whose rotational coordinates are in degrees as OpenSim expects (``inDegrees=yes``).
"""

from __future__ import annotations

import functools
import io
import json
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.planning.export._motion import ExportError, MethodMotion, PlanMotion, Samples
from app.planning.jsonsafe import json_safe

__all__ = ["FORMATS", "ExportFormat", "full_arm"]

FloatArray = NDArray[np.float64]
Writer = Callable[[PlanMotion, MethodMotion, Samples], bytes]

#: The Universal Robots controller's servo rate [Hz] (e-Series; CB3 runs at 125 Hz = 500 / 4).
UR_CONTROLLER_HZ = 500.0
UR_JOINTS = 6


@dataclass(frozen=True)
class ExportFormat:
    """One export format.

    Attributes:
        name: format name (the ``--format`` value).
        extension: file extension that selects it.
        default_rate: sample rate used when none is given [Hz].
        description: one line for help texts.
        write: the writer.
    """

    name: str
    extension: str
    default_rate: float
    description: str
    write: Writer


def _g(x: float) -> str:
    return repr(float(x))


def _row(values: Iterable[float]) -> str:
    return ", ".join(repr(float(v)) for v in values)


def _header_comment(motion: PlanMotion, method: MethodMotion, samples: Samples) -> str:
    return (
        f"BioPlan export: robot {motion.robot}, method {method.name}, {samples.t.size} samples "
        f"at {samples.rate:g} Hz over {motion.duration:g} s"
    )


def write_csv(motion: PlanMotion, method: MethodMotion, samples: Samples) -> bytes:
    """Time, then position, velocity, acceleration and torque per joint; units in the header."""
    columns = ["time [s]"]
    for prefix, unit in (("q", "rad"), ("qd", "rad/s"), ("qdd", "rad/s^2"), ("tau", "Nm")):
        columns += [f"{prefix}_{name} [{unit}]" for name in motion.joint_names]
    table = np.column_stack([samples.t, samples.q, samples.qd, samples.qdd, samples.tau])
    buffer = io.StringIO()
    buffer.write(",".join(columns) + "\n")
    np.savetxt(buffer, table, fmt="%.17g", delimiter=",")
    return buffer.getvalue().encode()


def write_json(motion: PlanMotion, method: MethodMotion, samples: Samples) -> bytes:
    """The samples with the task, robot, method and metrics (one JSON object)."""
    document = {
        "format": "bioplan.trajectory/1",
        "robot": motion.robot,
        "robot_spec": dict(motion.robot_spec),
        "method": method.name,
        "method_kind": method.kind,
        "joint_names": list(motion.joint_names),
        "locks": dict(motion.locks),
        "task": {
            "start": motion.start.tolist(),
            "goal": motion.goal.tolist(),
            "start_deg": np.degrees(motion.start).tolist(),
            "goal_deg": np.degrees(motion.goal).tolist(),
            "duration": motion.duration,
        },
        "rate": samples.rate,
        "units": {"t": "s", "q": "rad", "qd": "rad/s", "qdd": "rad/s^2", "tau": "Nm"},
        "metrics": json_safe(dict(method.metrics)),
        "floors": json_safe(dict(motion.floors)),
        "conditions": json_safe(dict(motion.conditions)),
        "t": samples.t.tolist(),
        "q": samples.q.tolist(),
        "qd": samples.qd.tolist(),
        "qdd": samples.qdd.tolist(),
        "tau": samples.tau.tolist(),
    }
    return (json.dumps(document, allow_nan=False) + "\n").encode()


def _yaml_float(x: float) -> str:
    # YAML 1.1 readers (PyYAML) take 1e-05 for a string: give every float a decimal point.
    text = repr(float(x))
    return text.replace("e", ".0e") if "e" in text and "." not in text else text


def _yaml_list(values: Iterable[float]) -> str:
    return "[" + ", ".join(_yaml_float(v) for v in values) + "]"


def _duration(t: float) -> tuple[int, int]:
    total = round(t * 1e9)
    return total // 1_000_000_000, total % 1_000_000_000


def write_yaml(motion: PlanMotion, method: MethodMotion, samples: Samples) -> bytes:
    """A ROS 2 ``trajectory_msgs/msg/JointTrajectory`` in YAML (what ``ros2 action send_goal``
    and MoveIt read); positions [rad], velocities [rad/s], accelerations [rad/s^2], effort [Nm]."""
    lines = [
        f"# {_header_comment(motion, method, samples)}",
        "# trajectory_msgs/msg/JointTrajectory; SI units, radians",
        "header:",
        "  stamp: {sec: 0, nanosec: 0}",
        "  frame_id: ''",
        "joint_names: [" + ", ".join(json.dumps(n) for n in motion.joint_names) + "]",
        "points:",
    ]
    for k, t in enumerate(samples.t):
        sec, nanosec = _duration(float(t))
        lines += [
            f"  - positions: {_yaml_list(samples.q[k])}",
            f"    velocities: {_yaml_list(samples.qd[k])}",
            f"    accelerations: {_yaml_list(samples.qdd[k])}",
            f"    effort: {_yaml_list(samples.tau[k])}",
            f"    time_from_start: {{sec: {sec}, nanosec: {nanosec}}}",
        ]
    return ("\n".join(lines) + "\n").encode()


@functools.cache
def _typestore() -> Any:
    """ROS 2 Humble's message types; built once (rosbags compiles a serializer per type)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def write_mcap(motion: PlanMotion, method: MethodMotion, samples: Samples) -> bytes:
    """A rosbag2 in MCAP storage holding the whole ``trajectory_msgs/msg/JointTrajectory`` as
    one message on ``/joint_trajectory`` at log time 0 (what a trajectory controller takes)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = _typestore()
    types = store.types
    header_t, time_t = types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"]
    point_t = types["trajectory_msgs/msg/JointTrajectoryPoint"]
    trajectory_t = types["trajectory_msgs/msg/JointTrajectory"]
    duration_t = types["builtin_interfaces/msg/Duration"]
    points = [
        point_t(
            positions=samples.q[k],
            velocities=samples.qd[k],
            accelerations=samples.qdd[k],
            effort=samples.tau[k],
            time_from_start=duration_t(*_duration(float(t))),
        )
        for k, t in enumerate(samples.t)
    ]
    trajectory = trajectory_t(
        header=header_t(stamp=time_t(sec=0, nanosec=0), frame_id=""),
        joint_names=list(motion.joint_names),
        points=points,
    )
    msgtype = trajectory_t.__msgtype__
    with tempfile.TemporaryDirectory(prefix="bioplan-bag-") as tmp:
        bag = Path(tmp) / "bag"
        with Writer(bag, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
            topic = writer.add_connection("/joint_trajectory", msgtype, typestore=store)
            writer.write(topic, 0, store.serialize_cdr(trajectory, msgtype))
        return next(bag.glob("*.mcap")).read_bytes()


def full_arm(motion: PlanMotion, q: FloatArray) -> FloatArray:
    """(T, n) free-joint values -> (T, N) values of every joint, locked ones inserted."""
    column = {name: i for i, name in enumerate(motion.joint_names)}
    out = np.empty((q.shape[0], len(motion.all_joint_names)))
    for k, name in enumerate(motion.all_joint_names):
        out[:, k] = q[:, column[name]] if name in column else motion.locks[name]
    return out


def write_urscript(motion: PlanMotion, method: MethodMotion, samples: Samples) -> bytes:
    """A URScript program: ``movej`` to the start, then one ``servoj`` per sample, then stop.

    ``servoj``'s ``t`` is the sample period, which must be a whole number of controller steps
    (500 Hz / k). All six joints are sent, locked ones at their locked values.
    """
    joints = motion.all_joint_names
    if len(joints) != UR_JOINTS:
        raise ExportError(
            f"format script (URScript) needs a 6-joint Universal Robots arm: robot "
            f"'{motion.robot}' has {len(joints)} joints ({', '.join(joints)})"
        )
    steps = UR_CONTROLLER_HZ / samples.rate
    if samples.rate > UR_CONTROLLER_HZ or abs(steps - round(steps)) > 1e-9:
        raise ExportError(
            f"export rate {samples.rate:g} Hz for URScript: expected 500 Hz divided by a whole "
            "number (500, 250, 125, 100, ...), the controller's servo rate"
        )
    period = 1.0 / samples.rate
    q = full_arm(motion, samples.q)
    lines = [
        f"# {_header_comment(motion, method, samples)}",
        f"# joints: {', '.join(joints)}; radians; servoj t = {period:g} s",
        "def bioplan_trajectory():",
        f"  movej([{_row(q[0])}], a=0.5, v=0.25)",
    ]
    lines += [f"  servoj([{_row(row)}], 0, 0, {_g(period)}, 0.1, 300)" for row in q]
    lines += ["  stopj(2.0)", "end"]
    return ("\n".join(lines) + "\n").encode()


def write_mot(motion: PlanMotion, method: MethodMotion, samples: Samples) -> bytes:
    """An OpenSim motion file: time and each joint as a coordinate, in degrees."""
    columns = ["time", *motion.joint_names]
    table = np.column_stack([samples.t, np.degrees(samples.q)])
    buffer = io.StringIO()
    buffer.write(
        f"bioplan_{motion.robot}_{method.name}\nversion=1\nnRows={table.shape[0]}\n"
        f"nColumns={table.shape[1]}\ninDegrees=yes\nendheader\n" + "\t".join(columns) + "\n"
    )
    np.savetxt(buffer, table, fmt="%.17g", delimiter="\t")
    return buffer.getvalue().encode()


FORMATS: dict[str, ExportFormat] = {
    f.name: f
    for f in (
        ExportFormat("csv", ".csv", 1000.0, "CSV: time, q, qd, qdd, tau per joint (SI)", write_csv),
        ExportFormat(
            "json", ".json", 1000.0, "JSON: the samples plus task, robot, metrics", write_json
        ),
        ExportFormat("yaml", ".yaml", 100.0, "ROS 2 JointTrajectory YAML", write_yaml),
        ExportFormat(
            "mcap", ".mcap", 1000.0, "rosbag2 (MCAP): JointTrajectory + JointState", write_mcap
        ),
        ExportFormat(
            "script", ".script", 500.0, "URScript (servoj) for Universal Robots", write_urscript
        ),
        ExportFormat("mot", ".mot", 1000.0, "OpenSim motion file (degrees)", write_mot),
    )
}
