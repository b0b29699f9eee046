"""The export formats: CSV, JSON, ROS 2 JointTrajectory YAML, rosbag2 MCAP, URScript, OpenSim.

Each writer takes the plan's motion, the chosen method and its samples at the export rate and
returns the file's bytes. Numbers are written with 17 significant digits (``repr``), so every
value reads back exactly. Units are SI with radians everywhere except the OpenSim motion file,
whose rotational coordinates are in degrees as OpenSim expects (``inDegrees=yes``).
"""

from __future__ import annotations

import csv
import functools
import io
import json
import re
import tempfile
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path, PureWindowsPath
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.planning.export._motion import ExportError, MethodMotion, PlanMotion, Samples
from app.planning.jsonsafe import json_safe

__all__ = ["FORMATS", "ExportFormat", "full_arm"]

FloatArray = NDArray[np.float64]
Writer = Callable[[PlanMotion, MethodMotion, Samples], Iterator[bytes]]

#: The Universal Robots controller's servo rate [Hz] (e-Series; CB3 runs at 125 Hz = 500 / 4).
UR_CONTROLLER_HZ = 500.0
UR_JOINTS = 6
#: Samples written per chunk of a streamed export (a chunk is a few hundred kB of text).
CHUNK_SAMPLES = 2000
#: A CSV cell starting with one of these is a formula to a spreadsheet (OWASP CSV injection).
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")
#: An absolute path: POSIX, home, Windows drive or UNC.
_ABSOLUTE = re.compile(r"^(?:/|~|[A-Za-z]:[\\/]|\\\\)")


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
    stream: Writer

    def write(self, motion: PlanMotion, method: MethodMotion, samples: Samples) -> bytes:
        """The whole file's bytes (:attr:`stream`'s chunks joined)."""
        return b"".join(self.stream(motion, method, samples))


def one_line(text: object) -> str:
    """``text`` safe inside a one-line comment or header of any format: every character that
    is not printable (newlines, carriage returns, tabs, other control and format characters,
    Unicode line separators) is written as its escape (``\\n``, ``\\x00``, ``\\u2028``), so
    a name from a robot file can never start a line of its own."""
    out = []
    for ch in str(text):
        if ch.isprintable():
            out.append(ch)
        else:
            out.append(ch.encode("unicode_escape").decode("ascii"))
    return "".join(out)


def csv_cell(text: object) -> str:
    """A text cell a spreadsheet shows as text: one starting with ``= + - @``, a tab or a
    carriage return gets a leading single quote (OWASP's advice against CSV injection)."""
    value = str(text)
    return "'" + value if value.startswith(_FORMULA_START) else value


def _blocks(count: int) -> Iterator[slice]:
    for start in range(0, count, CHUNK_SAMPLES):
        yield slice(start, min(start + CHUNK_SAMPLES, count))


def _table(table: FloatArray, delimiter: str) -> Iterator[bytes]:
    """Rows of numbers, each the shortest text that reads back as the same float (``0.003``,
    never ``0.0030000000000000001``), a chunk of rows at a time."""
    for block in _blocks(table.shape[0]):
        rows = table[block].tolist()
        yield "".join(delimiter.join(map(repr, row)) + "\n" for row in rows).encode()


def _g(x: float) -> str:
    return repr(float(x))


def _row(values: Iterable[float]) -> str:
    return ", ".join(repr(float(v)) for v in values)


def _header_comment(motion: PlanMotion, method: MethodMotion, samples: Samples) -> str:
    """One line (the robot's name escaped by :func:`one_line`)."""
    return one_line(
        f"BioPlan export: robot {motion.robot}, method {method.name}, {samples.t.size} samples "
        f"at {samples.rate:g} Hz over {motion.duration:g} s"
    )


def write_csv(motion: PlanMotion, method: MethodMotion, samples: Samples) -> Iterator[bytes]:
    """Time, then position, velocity, acceleration and torque per joint; units in the header.

    The header is one line written by the ``csv`` module (a joint name with a comma or a quote
    stays one cell, a newline in it is escaped) and no header cell reads as a spreadsheet
    formula (:func:`csv_cell`)."""
    columns = ["time [s]"]
    for prefix, unit in (("q", "rad"), ("qd", "rad/s"), ("qdd", "rad/s^2"), ("tau", "Nm")):
        columns += [f"{prefix}_{name} [{unit}]" for name in motion.joint_names]
    header = io.StringIO()
    csv.writer(header, lineterminator="\n").writerow([csv_cell(one_line(c)) for c in columns])
    yield header.getvalue().encode()
    table = np.column_stack([samples.t, samples.q, samples.qd, samples.qdd, samples.tau])
    yield from _table(table, ",")


def _file_name(value: Any) -> Any:
    """A path's last part (``/srv/data/robots/ab12/arm.urdf`` -> ``arm.urdf``); not a path:
    itself. An export leaves the machine it was made on: no folder of it is written."""
    if not isinstance(value, str) or not _ABSOLUTE.match(value):
        return value
    return PureWindowsPath(value).name  # splits at both / and \\


def public_spec(spec: Any) -> dict[str, Any]:
    """``Robot.spec`` with its files as file names only (``source``, ``mjcf``, ``sidecar``,
    ``package_dirs``): what an export says about its robot without the folders it was in."""
    out = dict(spec)
    for key in ("source", "mjcf", "sidecar"):
        if key in out:
            out[key] = _file_name(out[key])
    if isinstance(out.get("package_dirs"), list):
        out["package_dirs"] = [_file_name(p) for p in out["package_dirs"]]
    return out


def public_result(result: Any) -> Any:
    """A stored plan's or simulation's result as the API serves it: its ``motion`` block's
    robot spec with file names only (the stored one keeps the places it rebuilds from)."""
    if not isinstance(result, dict) or not isinstance(result.get("motion"), dict):
        return result
    motion = result["motion"]
    if not isinstance(motion.get("robot_spec"), dict):
        return result
    return {**result, "motion": {**motion, "robot_spec": public_spec(motion["robot_spec"])}}


def write_json(motion: PlanMotion, method: MethodMotion, samples: Samples) -> Iterator[bytes]:
    """The samples with the task, robot, method and metrics (one JSON object)."""
    conditions = dict(motion.conditions)
    if "template" in conditions:
        conditions["template"] = _file_name(conditions["template"])
    document = {
        "format": "bioplan.trajectory/1",
        "robot": motion.robot,
        "robot_spec": public_spec(motion.robot_spec),
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
        "conditions": json_safe(conditions),
    }
    head = json.dumps(document, allow_nan=False)
    yield head[:-1].encode()  # without its closing brace: the arrays follow
    for key in ("t", "q", "qd", "qdd", "tau"):
        array = getattr(samples, key)
        yield f', "{key}": ['.encode()
        for n, block in enumerate(_blocks(array.shape[0])):
            part = json.dumps(array[block].tolist(), allow_nan=False)[1:-1]
            yield ((", " if n else "") + part).encode()
        yield b"]"
    yield b"}\n"


def _yaml_float(x: float) -> str:
    # YAML 1.1 readers (PyYAML) take 1e-05 for a string: give every float a decimal point.
    text = repr(float(x))
    return text.replace("e", ".0e") if "e" in text and "." not in text else text


def _yaml_list(values: Iterable[float]) -> str:
    return "[" + ", ".join(_yaml_float(v) for v in values) + "]"


def _duration(t: float) -> tuple[int, int]:
    total = round(t * 1e9)
    return total // 1_000_000_000, total % 1_000_000_000


def _yaml_names(names: Iterable[str]) -> str:
    """``joint_names: [...]`` by PyYAML's safe dumper: every name one quoted string."""
    import yaml

    text: str = yaml.safe_dump(
        {"joint_names": [str(n) for n in names]},
        default_flow_style=True,
        default_style='"',
        width=float("inf"),
        allow_unicode=False,
    )
    # ``{"joint_names": [...]}`` -> ``"joint_names": [...]`` (one line: escapes, no breaks)
    return text.strip()[1:-1]


def write_yaml(motion: PlanMotion, method: MethodMotion, samples: Samples) -> Iterator[bytes]:
    """A ROS 2 ``trajectory_msgs/msg/JointTrajectory`` in YAML (what ``ros2 action send_goal``
    and MoveIt read); positions [rad], velocities [rad/s], accelerations [rad/s^2], effort [Nm].

    Names reach the file only as PyYAML-quoted strings or in a comment of one line."""
    lines = [
        f"# {_header_comment(motion, method, samples)}",
        "# trajectory_msgs/msg/JointTrajectory; SI units, radians",
        "header:",
        "  stamp: {sec: 0, nanosec: 0}",
        "  frame_id: ''",
        _yaml_names(motion.joint_names),
        "points:",
    ]
    yield ("\n".join(lines) + "\n").encode()
    for block in _blocks(samples.t.size):
        lines = []
        for k in range(block.start, block.stop):
            sec, nanosec = _duration(float(samples.t[k]))
            lines += [
                f"  - positions: {_yaml_list(samples.q[k])}",
                f"    velocities: {_yaml_list(samples.qd[k])}",
                f"    accelerations: {_yaml_list(samples.qdd[k])}",
                f"    effort: {_yaml_list(samples.tau[k])}",
                f"    time_from_start: {{sec: {sec}, nanosec: {nanosec}}}",
            ]
        yield ("\n".join(lines) + "\n").encode()


@functools.cache
def _typestore() -> Any:
    """ROS 2 Humble's message types; built once (rosbags compiles a serializer per type)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def write_mcap(motion: PlanMotion, method: MethodMotion, samples: Samples) -> Iterator[bytes]:
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
        data = next(bag.glob("*.mcap")).read_bytes()
    yield data


def full_arm(motion: PlanMotion, q: FloatArray) -> FloatArray:
    """(T, n) free-joint values -> (T, N) values of every joint, locked ones inserted."""
    column = {name: i for i, name in enumerate(motion.joint_names)}
    out = np.empty((q.shape[0], len(motion.all_joint_names)))
    for k, name in enumerate(motion.all_joint_names):
        out[:, k] = q[:, column[name]] if name in column else motion.locks[name]
    return out


def write_urscript(motion: PlanMotion, method: MethodMotion, samples: Samples) -> Iterator[bytes]:
    """A URScript program: ``movej`` to the start, then one ``servoj`` per sample, then stop.

    ``servoj``'s ``t`` is the sample period, which must be a whole number of controller steps
    (500 Hz / k). All six joints are sent, locked ones at their locked values. Names (robot,
    joints) appear only in comments of one line; the program's code is the code's own.
    """
    joints = motion.all_joint_names
    if len(joints) != UR_JOINTS:
        raise ExportError(
            f"format script (URScript) needs a 6-joint Universal Robots arm: robot "
            f"'{one_line(motion.robot)}' has {len(joints)} joints "
            f"({one_line(', '.join(joints))})"
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
        f"# joints: {one_line(', '.join(joints))}; radians; servoj t = {period:g} s",
        "def bioplan_trajectory():",
        f"  movej([{_row(q[0])}], a=0.5, v=0.25)",
    ]
    yield ("\n".join(lines) + "\n").encode()
    for block in _blocks(q.shape[0]):
        rows = [f"  servoj([{_row(row)}], 0, 0, {_g(period)}, 0.1, 300)\n" for row in q[block]]
        yield "".join(rows).encode()
    yield b"  stopj(2.0)\nend\n"


def _mot_label(name: str) -> str:
    """A column label of a ``.mot`` file: one tab-separated word (whitespace -> ``_``) that a
    spreadsheet opening the file does not take for a formula."""
    return csv_cell("_".join(one_line(name).split()) or "_")


def write_mot(motion: PlanMotion, method: MethodMotion, samples: Samples) -> Iterator[bytes]:
    """An OpenSim motion file: time and each joint as a coordinate, in degrees.

    The header is exactly six lines (name, version, nRows, nColumns, inDegrees, endheader): the
    name's robot part is escaped to one line and each column label to one word."""
    columns = ["time", *(_mot_label(n) for n in motion.joint_names)]
    table = np.column_stack([samples.t, np.degrees(samples.q)])
    yield (
        f"bioplan_{'_'.join(one_line(motion.robot).split())}_{method.name}\nversion=1\nnRows={table.shape[0]}\n"
        f"nColumns={table.shape[1]}\ninDegrees=yes\nendheader\n" + "\t".join(columns) + "\n"
    ).encode()
    yield from _table(table, "\t")


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
