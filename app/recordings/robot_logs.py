"""Robot logs: what a real arm measured while it moved (joint positions, speeds, torques).

Three formats, sniffed from the file (the extension is only a hint):

- ROS 2 bags (a bag folder with ``metadata.yaml``, or its ``.mcap`` / ``.db3`` file) of
  ``sensor_msgs/msg/JointState``: ``position`` [rad], ``velocity`` [rad/s], ``effort`` [Nm];
  time from each message's header stamp (the bag's receive time when the stamp is zero).
- Universal Robots RTDE CSV (the RTDE recorder's or ur_rtde's, comma- or space-separated):
  ``timestamp`` [s], ``actual_q_0..5`` [rad], ``actual_qd_0..5`` [rad/s], and
  ``target_moment_0..5`` [Nm] or ``actual_current_0..5`` [A] (motor currents, turned into joint
  torque N k_t i by the sidecar's gear ratio and torque constant). Its joints have no names:
  they are the robot's free joints in order.
- A generic CSV: ``time`` [s], then per joint ``<joint>/position`` [rad], optionally
  ``<joint>/velocity`` [rad/s] (differentiated from the positions when absent) and
  ``<joint>/effort`` [Nm].

Every log is checked and, where it can be done without inventing data, repaired; the repairs
are listed in :attr:`RobotLog.notes`:

- time must increase strictly: a sample that goes back or repeats is refused (line or message);
- a gap longer than :data:`MAX_GAP_FACTOR` median sample intervals is refused (split the log);
- an uneven rate (jitter above 1 %, or joints published at different rates) is resampled onto
  an even grid at the median interval by linear interpolation;
- interior NaN runs of at most :data:`MAX_NAN_RUN` samples are filled by linear interpolation;
  a longer run, or one at an end, is refused naming the channel and the time.
"""

from __future__ import annotations

import csv
import dataclasses
import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app.recordings.types import RecordingError

if TYPE_CHECKING:
    from app.planning.energy import MotorModel

__all__ = [
    "LOG_FORMATS",
    "MAX_GAP_FACTOR",
    "MAX_NAN_RUN",
    "MIN_SAMPLES",
    "RobotLog",
    "read_robot_log",
    "sniff_robot_log",
]

FloatArray = NDArray[np.float64]

#: The formats :func:`read_robot_log` reads.
LOG_FORMATS = ("ros2_bag", "ur_rtde_csv", "csv")
#: Longest NaN run filled by interpolation [samples].
MAX_NAN_RUN = 5
#: A time step longer than this many median steps is a gap (refused).
MAX_GAP_FACTOR = 5.0
#: Relative spread of the time steps above which the log is resampled onto an even grid.
JITTER_TOLERANCE = 0.01
#: Fewest samples of a log.
MIN_SAMPLES = 10
#: Largest CSV log read [bytes] (20 min of a 7-joint arm at 1 kHz is about 300 MB).
MAX_CSV_BYTES = 1 << 30
_UR_JOINTS = 6


@dataclass(frozen=True, eq=False)
class RobotLog:
    """A robot's measured motion on an even time grid, SI units.

    Attributes:
        path: the file (or bag folder).
        format: one of :data:`LOG_FORMATS`.
        t: (T,) sample times [s], strictly increasing, evenly spaced.
        joint_names: (n,) joint names as in the file (UR logs: ``joint_0..5``, matched by order).
        position: (T, n) joint angles [rad].
        velocity: (T, n) joint speeds [rad/s], or None (not logged: differentiate).
        effort: (T, n) joint torques [Nm], or None (not logged).
        current: (T, n) motor currents [A], or None (UR ``actual_current_*``).
        notes: repairs made while reading, and how the torque was obtained.
        by_order: the joints have no names of their own and match the robot's in order.
    """

    path: Path
    format: str
    t: FloatArray
    joint_names: tuple[str, ...]
    position: FloatArray
    velocity: FloatArray | None = None
    effort: FloatArray | None = None
    current: FloatArray | None = None
    notes: tuple[str, ...] = ()
    by_order: bool = False

    @property
    def n_samples(self) -> int:
        return int(self.t.size)

    @property
    def rate(self) -> float:
        """Sample rate [Hz]."""
        return float((self.t.size - 1) / (self.t[-1] - self.t[0]))

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def matched(
        self, joint_names: Sequence[str], *, motors: Sequence[MotorModel] | None = None
    ) -> RobotLog:
        """The log with its columns in the robot's joint order, torques in Nm.

        Args:
            joint_names: (n,) the robot's free joints.
            motors: (n,) the robot's motors: turn logged currents into joint torque N k_t i
                when the log has no torque.

        Raises:
            RecordingError: a robot joint missing from the log (both lists named), or a UR log
                for a robot without six joints.
        """
        names = list(joint_names)
        if self.by_order:
            if len(names) != len(self.joint_names):
                raise RecordingError(
                    f"the log's {len(self.joint_names)} unnamed joints (UR RTDE) do not match the "
                    f"robot's {len(names)} joints {names}",
                    file=self.path.name,
                    expected="a robot with as many free joints as the log (matched in order)",
                )
            index = list(range(len(names)))
        else:
            missing = [name for name in names if name not in self.joint_names]
            if missing:
                raise RecordingError(
                    f"robot joints {missing} are not in the log; the log has "
                    f"{list(self.joint_names)}, the robot {names}",
                    file=self.path.name,
                    expected="every free joint of the robot logged under its URDF name",
                )
            index = [self.joint_names.index(name) for name in names]
        notes = list(self.notes)
        extra = [name for name in self.joint_names if name not in names and not self.by_order]
        if extra:
            notes.append(f"log joints not in the robot ignored: {extra}")
        effort = None if self.effort is None else self.effort[:, index]
        current = None if self.current is None else self.current[:, index]
        if effort is None and current is not None and motors is not None:
            from app.planning.energy import motors_modelled

            if motors_modelled(motors):
                gain = np.array([m.gear_ratio * m.torque_constant for m in motors])
                effort = current * gain
                notes.append("joint torque = gear ratio x torque constant x motor current")
        return dataclasses.replace(
            self,
            joint_names=tuple(names),
            position=self.position[:, index],
            velocity=None if self.velocity is None else self.velocity[:, index],
            effort=effort,
            current=current,
            notes=tuple(notes),
            by_order=False,
        )

    def split(self, fraction: float) -> tuple[RobotLog, RobotLog]:
        """(first part, last ``fraction`` of the samples) — the held-back part for validation."""
        cut = round(self.n_samples * (1.0 - fraction))
        return self._part(slice(0, cut)), self._part(slice(cut, None))

    def _part(self, part: slice) -> RobotLog:
        def take(a: FloatArray | None) -> FloatArray | None:
            return None if a is None else a[part]

        return dataclasses.replace(
            self,
            t=self.t[part],
            position=self.position[part],
            velocity=take(self.velocity),
            effort=take(self.effort),
            current=take(self.current),
        )


def _fail(file: str, message: str, expected: str, **where: Any) -> RecordingError:
    return RecordingError(message, file=file, expected=expected, **where)


# -- sniffing ------------------------------------------------------------------------------


def sniff_robot_log(path: str | Path) -> str:
    """The format of a robot log (one of :data:`LOG_FORMATS`).

    Raises:
        RecordingError: no such file, or not a format this module reads.
    """
    p = Path(path)
    if not p.exists():
        raise _fail(p.name, f"no such file ({p})", "a robot log: ROS 2 bag, UR RTDE CSV or CSV")
    if p.is_dir():
        if (p / "metadata.yaml").is_file() or any(p.glob("*.mcap")) or any(p.glob("*.db3")):
            return "ros2_bag"
        raise _fail(p.name, "a folder without metadata.yaml", "a ROS 2 bag folder")
    with open(p, "rb") as handle:
        head = handle.read(4096)
    if head.startswith(b"\x89MCAP") or head.startswith(b"SQLite format 3\x00"):
        return "ros2_bag"
    header = _header_fields(head.decode("utf-8", errors="replace").splitlines()[:1])
    if "timestamp" in header and any(h.startswith("actual_q_") for h in header):
        return "ur_rtde_csv"
    if header and header[0] == "time" and any(h.endswith("/position") for h in header):
        return "csv"
    raise _fail(
        p.name,
        "not a robot log this program reads",
        "a ROS 2 bag (MCAP or SQLite), a UR RTDE CSV (timestamp, actual_q_0..5) or a CSV "
        "with 'time' and '<joint>/position' columns",
    )


def _delimiter(line: str) -> str:
    counts = {d: line.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=lambda d: counts[d])
    return best if counts[best] else " "


def _header_fields(lines: Sequence[str]) -> list[str]:
    if not lines:
        return []
    line = lines[0].lstrip("\ufeff").strip()
    delimiter = _delimiter(line)
    return [h.strip() for h in (line.split() if delimiter == " " else line.split(delimiter))]


def read_robot_log(path: str | Path, *, topic: str | None = None) -> RobotLog:
    """Read a robot log, sniffing its format; see the module docstring for formats and repairs.

    Args:
        path: the log file (a ROS 2 bag may also be its folder).
        topic: the JointState topic of a bag (default: the only one, else ``/joint_states``).

    Returns:
        The log on an even time grid, SI units, joints as named in the file.

    Raises:
        RecordingError: unreadable file, unknown format, bad value (line and column named),
            time going back, a gap, a long NaN run, fewer than :data:`MIN_SAMPLES` samples.
    """
    p = Path(path)
    kind = sniff_robot_log(p)
    if kind == "ros2_bag":
        from app.recordings._ros2_bag import read_joint_states

        return read_joint_states(p, topic=topic)
    return _read_csv_log(p, kind)


# -- CSV logs ------------------------------------------------------------------------------


def _read_table(path: Path) -> tuple[list[str], FloatArray]:
    """(header, (rows, columns) values) of a delimited text file; NaN for empty cells."""
    file = path.name
    if path.stat().st_size > MAX_CSV_BYTES:
        raise _fail(file, f"larger than {MAX_CSV_BYTES} bytes", "a log of at most 1 GiB")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise _fail(file, f"cannot be read ({exc})", "a UTF-8 text file") from None
    lines = text.splitlines()
    header = _header_fields(lines[:1])
    delimiter = _delimiter(lines[0])
    reader = (
        (line.split() for line in lines[1:])
        if delimiter == " "
        else csv.reader(io.StringIO("\n".join(lines[1:])), delimiter=delimiter)
    )
    rows: list[list[float]] = []
    for number, row in enumerate(reader, start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        if len(row) != len(header):
            raise _fail(
                file,
                f"{len(row)} fields",
                f"{len(header)} fields as in the header",
                line=number,
            )
        values = []
        for column, cell in enumerate(row):
            cell = cell.strip()
            try:
                values.append(float(cell) if cell else float("nan"))
            except ValueError:
                raise _fail(
                    file,
                    f"{cell[:30]!r} is not a number",
                    "a number (or an empty cell)",
                    line=number,
                    channel=header[column],
                ) from None
        rows.append(values)
    if not rows:
        raise _fail(file, "no data rows", "a header line and samples")
    return header, np.array(rows, dtype=np.float64)


def _columns(file: str, header: list[str], names: Sequence[str], what: str) -> list[int] | None:
    """Column indices of ``names``; None when none exist; an error when only some do."""
    present = [name for name in names if name in header]
    if not present:
        return None
    if len(present) != len(names):
        missing = [name for name in names if name not in header]
        raise _fail(file, f"{what} columns {missing} missing", f"all of {list(names)}")
    return [header.index(name) for name in names]


def _read_csv_log(path: Path, kind: str) -> RobotLog:
    file = path.name
    header, table = _read_table(path)
    duplicate = sorted({h for h in header if header.count(h) > 1})
    if duplicate:
        raise _fail(file, f"column {duplicate[0]!r} appears twice", "each column once")
    notes: list[str] = []
    current = None
    if kind == "ur_rtde_csv":
        names = [f"joint_{i}" for i in range(_UR_JOINTS)]
        time_col = header.index("timestamp")
        pos = _columns(file, header, [f"actual_q_{i}" for i in range(_UR_JOINTS)], "position")
        vel = _columns(file, header, [f"actual_qd_{i}" for i in range(_UR_JOINTS)], "velocity")
        eff = _columns(
            file, header, [f"target_moment_{i}" for i in range(_UR_JOINTS)], "target_moment"
        )
        cur = _columns(
            file, header, [f"actual_current_{i}" for i in range(_UR_JOINTS)], "actual_current"
        )
        if eff is not None:
            notes.append("joint torque from target_moment_* [Nm] (the controller's)")
        by_order = True
    else:
        names = [h[: -len("/position")] for h in header if h.endswith("/position")]
        unknown = [
            h
            for h in header[1:]
            if "/" not in h or h.rsplit("/", 1)[1] not in ("position", "velocity", "effort")
        ]
        if unknown:
            raise _fail(
                file,
                f"column {unknown[0]!r} is not understood",
                "'time' then '<joint>/position', '<joint>/velocity', '<joint>/effort'",
                line=1,
            )
        orphans = [h for h in header[1:] if h.rsplit("/", 1)[0] not in names]
        if orphans:
            raise _fail(file, f"column {orphans[0]!r} has no position column", "a position")
        time_col = 0
        pos = _columns(file, header, [f"{n}/position" for n in names], "position")
        vel = _columns(file, header, [f"{n}/velocity" for n in names], "velocity")
        eff = _columns(file, header, [f"{n}/effort" for n in names], "effort")
        cur = None
        by_order = False
    assert pos is not None
    channels = {"position": table[:, pos]}
    if vel is not None:
        channels["velocity"] = table[:, vel]
    else:
        notes.append("velocity not logged: differentiated from the filtered positions")
    if eff is not None:
        channels["effort"] = table[:, eff]
    elif cur is not None:
        channels["current"] = table[:, cur]
    t, channels = clean_samples(file, table[:, time_col], channels, names, notes, unit="line")
    if "current" in channels:
        current = channels["current"]
    return RobotLog(
        path=path,
        format=kind,
        t=t,
        joint_names=tuple(names),
        position=channels["position"],
        velocity=channels.get("velocity"),
        effort=channels.get("effort"),
        current=current,
        notes=tuple(notes),
        by_order=by_order,
    )


# -- checks and repairs --------------------------------------------------------------------


def clean_samples(
    file: str,
    t: FloatArray,
    channels: dict[str, FloatArray],
    names: Sequence[str],
    notes: list[str],
    *,
    unit: str,
    first_line: int = 2,
) -> tuple[FloatArray, dict[str, FloatArray]]:
    """Check time and values; fill short NaN runs; resample an uneven grid (notes say so).

    Args:
        file: the file's name for messages.
        t: (T,) sample times [s].
        channels: kind -> (T, n) values.
        names: (n,) joint names for messages.
        notes: repairs are appended here.
        unit: "line" (CSV rows, numbered from ``first_line``) or "message" (bag messages).
        first_line: the line (or message) number of sample 0.
    """
    if t.size < MIN_SAMPLES:
        raise _fail(file, f"{t.size} samples", f"at least {MIN_SAMPLES}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise _fail(
            file, "time is missing or not a number", "a time on every sample",
            **_where(unit, first_line + int(bad[0])),
        )  # fmt: skip
    step = np.diff(t)
    back = np.flatnonzero(step <= 0.0)
    if back.size:
        k = int(back[0]) + 1
        raise _fail(
            file,
            f"time goes back or repeats ({t[k - 1]:.6g} s then {t[k]:.6g} s)",
            "strictly increasing time",
            **_where(unit, first_line + k),
        )
    median = float(np.median(step))
    gap = int(np.argmax(step))
    if step[gap] > MAX_GAP_FACTOR * median:
        raise _fail(
            file,
            f"a gap of {step[gap]:.4g} s after t = {t[gap] - t[0]:.4g} s (median step "
            f"{median:.4g} s)",
            f"no step longer than {MAX_GAP_FACTOR:g} median steps (split the log there)",
            **_where(unit, first_line + gap + 1),
        )
    for kind, values in channels.items():
        channels[kind] = _fill_nans(file, t, values, names, kind, notes)
    if np.max(np.abs(step - median)) > JITTER_TOLERANCE * median:
        grid = t[0] + median * np.arange(int(np.floor((t[-1] - t[0]) / median + 1e-9)) + 1)
        notes.append(
            f"uneven sampling (steps {step.min():.4g}-{step.max():.4g} s) resampled to "
            f"{1.0 / median:.5g} Hz by linear interpolation"
        )
        channels = {k: _interp(grid, t, v) for k, v in channels.items()}
        t = grid
    return t - t[0], channels


def _where(unit: str, number: int) -> dict[str, Any]:
    if unit == "line":
        return {"line": number}
    return {"channel": f"message {number}"}


def _interp(grid: FloatArray, t: FloatArray, values: FloatArray) -> FloatArray:
    return np.stack([np.interp(grid, t, values[:, j]) for j in range(values.shape[1])], axis=1)


def _fill_nans(
    file: str, t: FloatArray, values: FloatArray, names: Sequence[str], kind: str, notes: list[str]
) -> FloatArray:
    """Interior NaN runs of at most MAX_NAN_RUN samples interpolated; others refused."""
    missing = ~np.isfinite(values)
    if not missing.any():
        return values
    out = values.copy()
    filled = 0
    for j in range(values.shape[1]):
        column = missing[:, j]
        if not column.any():
            continue
        edges = np.diff(np.concatenate([[0], column.astype(np.int8), [0]]))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        for start, end in zip(starts, ends, strict=True):
            if end - start > MAX_NAN_RUN or start == 0 or end == values.shape[0]:
                raise _fail(
                    file,
                    f"{end - start} missing or NaN samples from t = {t[start] - t[0]:.4g} s",
                    f"at most {MAX_NAN_RUN} in a row, not at either end",
                    channel=f"{names[j]}/{kind}",
                )
        good = ~column
        out[column, j] = np.interp(t[column], t[good], values[good, j])
        filled += len(starts)
    notes.append(
        f"{filled} NaN run(s) of at most {MAX_NAN_RUN} samples in {kind} filled by linear "
        "interpolation"
    )
    return out
