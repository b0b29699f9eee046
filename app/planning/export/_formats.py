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
from dataclasses import dataclass, field
from pathlib import Path, PureWindowsPath
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.jsonsafe import json_safe
from app.planning.export._checks import ExportNotes
from app.planning.export._motion import ExportError, MethodMotion, PlanMotion, Samples

__all__ = [
    "DEFAULT_ACTION",
    "DEFAULT_TOPIC",
    "FORMATS",
    "UR_JOINT_NAMES",
    "ExportContext",
    "ExportFormat",
    "full_arm",
    "is_universal_robot",
    "ur_number",
]

FloatArray = NDArray[np.float64]

#: The Universal Robots controller's servo rate [Hz] (e-Series; CB3 runs at 125 Hz = 500 / 4).
UR_CONTROLLER_HZ = 500.0
UR_JOINTS = 6
#: Samples written per chunk of a streamed export (a chunk is a few hundred kB of text).
CHUNK_SAMPLES = 2000
#: A CSV cell starting with one of these is a formula to a spreadsheet (OWASP CSV injection).
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")
#: An absolute path: POSIX, home, Windows drive or UNC.
_ABSOLUTE = re.compile(r"^(?:/|~|[A-Za-z]:[\\/]|\\\\)")
#: The six joints of every Universal Robots description, base to tool (the controller's order).
UR_JOINT_NAMES = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
#: Where a bare JointTrajectory goes by default: a trajectory controller's topic.
DEFAULT_TOPIC = "/joint_trajectory"
#: Where a FollowJointTrajectory goal goes by default (ros2_control's default controller name).
DEFAULT_ACTION = "/joint_trajectory_controller/follow_joint_trajectory"
#: Topic of the JointState messages in an MCAP (what Foxglove and PlotJuggler plot).
JOINT_STATES_TOPIC = "/joint_states"
#: Topic of the export's own record (limits, safety) in an MCAP, one std_msgs/String of JSON.
EXPORT_RECORD_TOPIC = "/bioplan/export"
#: Decimal places of a URScript number (1e-12 rad: far below any encoder's resolution).
UR_DECIMALS = 12


@dataclass(frozen=True)
class ExportContext:
    """What an export adds to the samples: its record and the ROS 2 options.

    Attributes:
        notes: what the file records about limits and safety.
        goal: YAML as a ``control_msgs/action/FollowJointTrajectory`` goal (``trajectory:``
            wrapping the message) instead of the bare ``trajectory_msgs/msg/JointTrajectory``.
        topic: the controller's topic (a message) or action (a goal); None = the defaults
            :data:`DEFAULT_TOPIC` / :data:`DEFAULT_ACTION`.
        approach: seconds of approach from a given position at the start of the samples
            (0: none); the plan starts at this time in the file.
    """

    notes: ExportNotes = field(default_factory=ExportNotes)
    goal: bool = False
    topic: str | None = None
    approach: float = 0.0

    def lines(self) -> list[str]:
        """The record as comment lines (each one line)."""
        out = [one_line(line) for line in self.notes.lines()]
        if self.approach > 0.0:
            out.append(
                f"approach: {self.approach:g} s from the given position to the start (rest to "
                f"rest quintic); the plan starts at t={self.approach:g} s"
            )
        return out

    def to_dict(self) -> dict[str, Any]:
        return {**self.notes.to_dict(), "approach": self.approach}


Writer = Callable[[PlanMotion, MethodMotion, Samples, ExportContext], Iterator[bytes]]


def is_universal_robot(joint_names: Iterable[str]) -> bool:
    """A Universal Robots arm: exactly six joints whose names end, in order, with
    :data:`UR_JOINT_NAMES` (a prefix such as ``ur5e_`` or ``left_`` is allowed). The robot's
    name is not used: a URDF's name is free text, the joint names are what UR descriptions
    share and what the controller's joint order follows."""
    names = list(joint_names)
    return len(names) == len(UR_JOINT_NAMES) and all(
        name.endswith(ur) for name, ur in zip(names, UR_JOINT_NAMES, strict=True)
    )


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

    def write(
        self,
        motion: PlanMotion,
        method: MethodMotion,
        samples: Samples,
        context: ExportContext | None = None,
    ) -> bytes:
        """The whole file's bytes (:attr:`stream`'s chunks joined)."""
        return b"".join(self.stream(motion, method, samples, context or ExportContext()))


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


def _comments(
    motion: PlanMotion, method: MethodMotion, samples: Samples, ctx: ExportContext, mark: str
) -> str:
    """The header comment and the export's record, each line starting with ``mark``."""
    lines = [_header_comment(motion, method, samples), *ctx.lines()]
    return "".join(f"{mark} {line}\n" for line in lines)


def write_csv(
    motion: PlanMotion, method: MethodMotion, samples: Samples, ctx: ExportContext
) -> Iterator[bytes]:
    """Time, then position, velocity, acceleration and torque per joint; units in the header.

    ``#`` comment lines come first (what was exported, limits, safety: read with
    ``pandas.read_csv(comment="#")`` or ``numpy.loadtxt``). The column header is one line
    written by the ``csv`` module (a joint name with a comma or a quote stays one cell, a
    newline in it is escaped) and no header cell reads as a spreadsheet formula
    (:func:`csv_cell`)."""
    # A comment line is one cell starting with "#" to a spreadsheet: no comma or quote in it
    # (a robot name could otherwise start a cell of its own, even a formula).
    comments = _comments(motion, method, samples, ctx, "#")
    yield comments.replace(",", ";").replace('"', "'").encode()
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


def write_json(
    motion: PlanMotion, method: MethodMotion, samples: Samples, ctx: ExportContext
) -> Iterator[bytes]:
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
        "export": json_safe(ctx.to_dict()),
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


def _points(samples: Samples, block: slice, indent: str) -> str:
    lines = []
    for k in range(block.start, block.stop):
        sec, nanosec = _duration(float(samples.t[k]))
        lines += [
            f"{indent}- positions: {_yaml_list(samples.q[k])}",
            f"{indent}  velocities: {_yaml_list(samples.qd[k])}",
            f"{indent}  accelerations: {_yaml_list(samples.qdd[k])}",
            f"{indent}  effort: {_yaml_list(samples.tau[k])}",
            f"{indent}  time_from_start: {{sec: {sec}, nanosec: {nanosec}}}",
        ]
    return "\n".join(lines) + "\n"


def write_yaml(
    motion: PlanMotion, method: MethodMotion, samples: Samples, ctx: ExportContext
) -> Iterator[bytes]:
    """A ROS 2 ``trajectory_msgs/msg/JointTrajectory`` in YAML (what ``ros2 topic pub`` and
    MoveIt read), or with ``ctx.goal`` a ``control_msgs/action/FollowJointTrajectory`` goal
    (the message as its ``trajectory``: what ``ros2 action send_goal`` reads); positions [rad],
    velocities [rad/s], accelerations [rad/s^2], effort [Nm].

    Comment lines name the controller's topic or action (``ctx.topic``), the limits and the
    safety record. Names reach the file only as PyYAML-quoted strings or in a comment of one
    line."""
    if ctx.goal:
        target = ctx.topic or DEFAULT_ACTION
        kind = f"action: {target} (control_msgs/action/FollowJointTrajectory goal)"
        indent = "  "
    else:
        target = ctx.topic or DEFAULT_TOPIC
        kind = f"topic: {target} (trajectory_msgs/msg/JointTrajectory)"
        indent = ""
    head = _comments(motion, method, samples, ctx, "#") + f"# {one_line(kind)}; SI units, radians\n"
    lines = [
        *(["trajectory:"] if ctx.goal else []),
        f"{indent}header:",
        f"{indent}  stamp: {{sec: 0, nanosec: 0}}",
        f"{indent}  frame_id: ''",
        indent + _yaml_names(motion.joint_names),
        f"{indent}points:",
    ]
    yield (head + "\n".join(lines) + "\n").encode()
    for block in _blocks(samples.t.size):
        yield _points(samples, block, indent + "  ").encode()


@functools.cache
def _typestore() -> Any:
    """ROS 2 Humble's message types; built once (rosbags compiles a serializer per type)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def _joint_states(
    store: Any, names: list[str], samples: Samples, stamps: list[tuple[int, int]]
) -> Iterator[bytes]:
    """One CDR-serialised ``sensor_msgs/msg/JointState`` per sample, stamped at its time."""
    types = store.types
    state_t = types["sensor_msgs/msg/JointState"]
    header_t, time_t = types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"]
    for k, (sec, nanosec) in enumerate(stamps):
        state = state_t(
            header=header_t(stamp=time_t(sec=sec, nanosec=nanosec), frame_id=""),
            name=names,
            position=samples.q[k],
            velocity=samples.qd[k],
            effort=samples.tau[k],
        )
        yield store.serialize_cdr(state, state_t.__msgtype__)


def write_mcap(
    motion: PlanMotion, method: MethodMotion, samples: Samples, ctx: ExportContext
) -> Iterator[bytes]:
    """A rosbag2 in MCAP storage: the whole ``trajectory_msgs/msg/JointTrajectory`` as one
    message on ``ctx.topic`` (default ``/joint_trajectory``) at log time 0 (what a trajectory
    controller takes), one ``sensor_msgs/msg/JointState`` per sample on ``/joint_states``
    stamped and logged at its time (what Foxglove and PlotJuggler plot over time), and the
    export's record (limits, safety) as one ``std_msgs/msg/String`` of JSON on
    ``/bioplan/export`` at log time 0."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = _typestore()
    types = store.types
    header_t, time_t = types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"]
    point_t = types["trajectory_msgs/msg/JointTrajectoryPoint"]
    trajectory_t = types["trajectory_msgs/msg/JointTrajectory"]
    duration_t = types["builtin_interfaces/msg/Duration"]
    state_t = types["sensor_msgs/msg/JointState"]
    string_t = types["std_msgs/msg/String"]
    names = list(motion.joint_names)
    stamps = [_duration(float(t)) for t in samples.t]
    points = [
        point_t(
            positions=samples.q[k],
            velocities=samples.qd[k],
            accelerations=samples.qdd[k],
            effort=samples.tau[k],
            time_from_start=duration_t(*stamps[k]),
        )
        for k in range(samples.t.size)
    ]
    trajectory = trajectory_t(
        header=header_t(stamp=time_t(sec=0, nanosec=0), frame_id=""),
        joint_names=names,
        points=points,
    )
    record = json.dumps(
        {
            "format": "bioplan.export/1",
            "robot": motion.robot,
            "method": method.name,
            **json_safe(ctx.to_dict()),
        },
        allow_nan=False,
    )
    with tempfile.TemporaryDirectory(prefix="bioplan-bag-") as tmp:
        bag = Path(tmp) / "bag"
        with Writer(bag, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
            topic = writer.add_connection(
                ctx.topic or DEFAULT_TOPIC, trajectory_t.__msgtype__, typestore=store
            )
            states = writer.add_connection(JOINT_STATES_TOPIC, state_t.__msgtype__, typestore=store)
            notes = writer.add_connection(
                EXPORT_RECORD_TOPIC, string_t.__msgtype__, typestore=store
            )
            writer.write(topic, 0, store.serialize_cdr(trajectory, trajectory_t.__msgtype__))
            writer.write(notes, 0, store.serialize_cdr(string_t(data=record), string_t.__msgtype__))
            for k, raw in enumerate(_joint_states(store, names, samples, stamps)):
                sec, nanosec = stamps[k]
                writer.write(states, sec * 1_000_000_000 + nanosec, raw)
        data = next(bag.glob("*.mcap")).read_bytes()
    yield data


def full_arm(motion: PlanMotion, q: FloatArray) -> FloatArray:
    """(T, n) free-joint values -> (T, N) values of every joint, locked ones inserted."""
    column = {name: i for i, name in enumerate(motion.joint_names)}
    out = np.empty((q.shape[0], len(motion.all_joint_names)))
    for k, name in enumerate(motion.all_joint_names):
        out[:, k] = q[:, column[name]] if name in column else motion.locks[name]
    return out


def ur_number(x: float) -> str:
    """A URScript number: a plain decimal (``-0.00000117``, ``1.5``, never ``1.17e-06``),
    rounded to :data:`UR_DECIMALS` places, shortest form that rounds back to it."""
    text: str = np.format_float_positional(float(x), precision=UR_DECIMALS, unique=True, trim="0")
    return "0.0" if float(text) == 0.0 else text


def _ur_list(values: Iterable[float]) -> str:
    return "[" + ", ".join(ur_number(v) for v in values) + "]"


def write_urscript(
    motion: PlanMotion, method: MethodMotion, samples: Samples, ctx: ExportContext
) -> Iterator[bytes]:
    """A URScript program: ``def bioplan_trajectory():`` holding an approach ``movej`` to the
    first sample, one ``servoj`` per sample, then ``stopj``; ``end``; then the call
    ``bioplan_trajectory()``, so the program runs when it is sent to the controller or pasted
    into a Script node. Numbers are plain decimals (:func:`ur_number`).

    ``servoj``'s ``t`` is the sample period, which must be a whole number of controller steps
    (500 Hz / k). All six joints are sent, locked ones at their locked values. A robot whose
    joints are not a UR's (:func:`is_universal_robot`) is refused unless the export is forced.
    Names (robot, joints) appear only in comments of one line; the code is the code's own.
    """
    joints = motion.all_joint_names
    if len(joints) != UR_JOINTS:
        raise ExportError(
            f"format script (URScript) needs a 6-joint Universal Robots arm: robot "
            f"'{one_line(motion.robot)}' has {len(joints)} joints "
            f"({one_line(', '.join(joints))})"
        )
    extra: list[str] = []
    if not is_universal_robot(joints):
        if not ctx.notes.forced:
            raise ExportError(
                f"format script (URScript) is for Universal Robots arms: robot "
                f"'{one_line(motion.robot)}' has joints {one_line(', '.join(joints))}; expected "
                f"joints named {', '.join(UR_JOINT_NAMES)} (a prefix allowed), or --force / "
                "force=true to write it anyway"
            )
        extra.append("FORCED: the joints are not a Universal Robots arm's; check the joint order")
    steps = UR_CONTROLLER_HZ / samples.rate
    if samples.rate > UR_CONTROLLER_HZ or abs(steps - round(steps)) > 1e-9:
        raise ExportError(
            f"export rate {samples.rate:g} Hz for URScript: expected 500 Hz divided by a whole "
            "number (500, 250, 125, 100, ...), the controller's servo rate"
        )
    period = 1.0 / samples.rate
    q = full_arm(motion, samples.q)
    head = _comments(motion, method, samples, ctx, "#")
    lines = [
        *(f"# {line}" for line in extra),
        f"# joints: {one_line(', '.join(joints))}; radians; servoj t = {period:g} s",
        "def bioplan_trajectory():",
        f"  movej({_ur_list(q[0])}, a=0.5, v=0.25)",
    ]
    yield (head + "\n".join(lines) + "\n").encode()
    t = ur_number(period)
    for block in _blocks(q.shape[0]):
        rows = [f"  servoj({_ur_list(row)}, 0, 0, {t}, 0.1, 300)\n" for row in q[block]]
        yield "".join(rows).encode()
    yield b"  stopj(2.0)\nend\nbioplan_trajectory()\n"


def _mot_label(name: str) -> str:
    """A column label of a ``.mot`` file: one tab-separated word (whitespace -> ``_``) that a
    spreadsheet opening the file does not take for a formula."""
    return csv_cell("_".join(one_line(name).split()) or "_")


def write_mot(
    motion: PlanMotion, method: MethodMotion, samples: Samples, ctx: ExportContext
) -> Iterator[bytes]:
    """An OpenSim motion file: time and each joint as a coordinate, in degrees.

    The header is name, version, nRows, nColumns, inDegrees, the export's record as
    ``bioplan_limits=...`` and ``bioplan_safety=...`` lines (OpenSim skips keys it does not
    know), then endheader: the name's robot part is escaped to one line and each column label
    to one word."""
    columns = ["time", *(_mot_label(n) for n in motion.joint_names)]
    table = np.column_stack([samples.t, np.degrees(samples.q)])
    notes = ctx.notes
    yield (
        f"bioplan_{'_'.join(one_line(motion.robot).split())}_{method.name}\nversion=1\n"
        f"nRows={table.shape[0]}\nnColumns={table.shape[1]}\ninDegrees=yes\n"
        f"bioplan_limits={one_line(notes.limits_line().removeprefix('limits: '))}\n"
        f"bioplan_safety={one_line(notes.safety_line().removeprefix('safety: '))}\n"
        "endheader\n" + "\t".join(columns) + "\n"
    ).encode()
    yield from _table(table, "\t")


FORMATS: dict[str, ExportFormat] = {
    f.name: f
    for f in (
        ExportFormat("csv", ".csv", 1000.0, "CSV: time, q, qd, qdd, tau per joint (SI)", write_csv),
        ExportFormat(
            "json", ".json", 1000.0, "JSON: the samples plus task, robot, metrics", write_json
        ),
        ExportFormat(
            "yaml",
            ".yaml",
            100.0,
            "ROS 2 JointTrajectory (or FollowJointTrajectory goal) YAML",
            write_yaml,
        ),
        ExportFormat(
            "mcap", ".mcap", 1000.0, "rosbag2 (MCAP): JointTrajectory + JointState", write_mcap
        ),
        ExportFormat(
            "script", ".script", 500.0, "URScript (servoj) for Universal Robots", write_urscript
        ),
        ExportFormat("mot", ".mot", 1000.0, "OpenSim motion file (degrees)", write_mot),
    )
}
