"""ROS 2 bags (MCAP or SQLite storage) of ``sensor_msgs/msg/JointState``, through ``rosbags``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from app.recordings.robot_logs import RobotLog, clean_samples
from app.recordings.types import RecordingError

__all__ = ["JOINT_STATE", "read_joint_states"]

JOINT_STATE = "sensor_msgs/msg/JointState"
_KINDS = ("position", "velocity", "effort")


def _bag_folder(path: Path) -> Path:
    folder = path if path.is_dir() else path.parent
    if not (folder / "metadata.yaml").is_file():
        raise RecordingError(
            "no metadata.yaml beside the bag's storage file",
            file=path.name,
            expected="the ROS 2 bag folder (with metadata.yaml) or its .mcap/.db3 file",
        )
    return folder


def _topic(file: str, connections: list[Any], topic: str | None) -> list[Any]:
    states = [c for c in connections if c.msgtype == JOINT_STATE]
    topics = sorted({c.topic for c in states})
    if topic is not None:
        chosen = [c for c in states if c.topic == topic]
        if not chosen:
            raise RecordingError(
                f"no JointState topic {topic!r}; the bag's JointState topics are {topics}",
                file=file,
                expected="an existing JointState topic",
            )
        return chosen
    if not topics:
        found = sorted({f"{c.topic} ({c.msgtype})" for c in connections})
        raise RecordingError(
            f"no {JOINT_STATE} messages; topics: {found}",
            file=file,
            expected="a topic of sensor_msgs/msg/JointState",
        )
    if len(topics) > 1:
        if "/joint_states" not in topics:
            raise RecordingError(
                f"several JointState topics {topics}",
                file=file,
                expected="one, or /joint_states among them (or choose one with topic=)",
            )
        return [c for c in states if c.topic == "/joint_states"]
    return states


def _collect(path: Path, topic: str | None) -> dict[str, dict[str, list[float]]]:
    """joint -> {"t", "position", "velocity", "effort"} lists over the messages naming it."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    file = path.name
    series: dict[str, dict[str, list[float]]] = {}
    try:
        with AnyReader(
            [_bag_folder(path)], default_typestore=get_typestore(Stores.ROS2_HUMBLE)
        ) as reader:
            connections = _topic(file, list(reader.connections), topic)
            for number, (connection, stamp, raw) in enumerate(
                reader.messages(connections=connections), start=1
            ):
                message: Any = reader.deserialize(raw, connection.msgtype)
                header = message.header.stamp
                t = header.sec + 1e-9 * header.nanosec if (header.sec or header.nanosec) else None
                _add(file, number, message, stamp * 1e-9 if t is None else t, series)
    except RecordingError:
        raise
    except Exception as exc:  # rosbags raises its own ReaderError / AnyReaderError and others
        detail = " ".join(str(exc).split())[:200]
        raise RecordingError(
            f"cannot be read as a ROS 2 bag ({type(exc).__name__}: {detail})",
            file=file,
            expected="a ROS 2 bag (MCAP or SQLite) readable by rosbags",
        ) from None
    return series


def _add(
    file: str, number: int, message: Any, t: float, series: dict[str, dict[str, list[float]]]
) -> None:
    names = list(message.name)
    for kind in _KINDS:
        values = getattr(message, kind)
        if len(values) not in (0, len(names)):
            raise RecordingError(
                f"{len(values)} {kind} values for {len(names)} joint names",
                file=file,
                channel=f"message {number}",
                expected=f"one {kind} per name, or none",
            )
    for k, name in enumerate(names):
        entry = series.setdefault(name, {"t": [], **{kind: [] for kind in _KINDS}})
        entry["t"].append(t)
        for kind in _KINDS:
            values = getattr(message, kind)
            entry[kind].append(float(values[k]) if len(values) else float("nan"))


def read_joint_states(path: Path, *, topic: str | None = None) -> RobotLog:
    """The JointState messages of a bag as a :class:`RobotLog` (see ``robot_logs``)."""
    file = path.name
    series = _collect(path, topic)
    names = list(series)
    notes: list[str] = []
    times = [np.asarray(series[n]["t"]) for n in names]
    reference = max(times, key=len)
    same = all(t.shape == reference.shape and np.array_equal(t, reference) for t in times)
    if not same:  # the span every joint covers
        first, last = max(t.min() for t in times), min(t.max() for t in times)
        reference = reference[(reference >= first) & (reference <= last)]
    channels: dict[str, np.ndarray] = {}
    for kind in _KINDS:
        columns = [np.asarray(series[n][kind]) for n in names]
        if all(np.isnan(c).all() for c in columns):
            continue
        if not same:
            columns = [
                _on(reference, t, c, file, n, kind)
                for t, c, n in zip(times, columns, names, strict=True)
            ]
        channels[kind] = np.stack(columns, axis=1)
    if not same:
        notes.append(
            "joints published at different times: interpolated onto the densest joint's times "
            "within the span all joints cover"
        )
    if "position" not in channels:
        raise RecordingError(
            "JointState messages carry no positions", file=file, expected="position values"
        )
    if "velocity" not in channels:
        notes.append("velocity not logged: differentiated from the filtered positions")
    t, channels = clean_samples(
        file, reference, channels, names, notes, unit="message", first_line=1
    )
    return RobotLog(
        path=path,
        format="ros2_bag",
        t=t,
        joint_names=tuple(names),
        position=channels["position"],
        velocity=channels.get("velocity"),
        effort=channels.get("effort"),
        notes=tuple(notes),
    )


def _on(grid: np.ndarray, t: np.ndarray, values: np.ndarray, file: str, name: str, kind: str):  # type: ignore[no-untyped-def]
    order = np.argsort(t, kind="stable")
    if np.any(np.diff(t[order]) <= 0.0):
        raise RecordingError(
            "time repeats", file=file, channel=f"{name}/{kind}", expected="increasing stamps"
        )
    return np.interp(grid, t[order], values[order], left=np.nan, right=np.nan)
