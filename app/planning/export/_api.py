"""Export entry points: a plan's motion (or a saved JSON result), method, rate, format -> bytes.

``export_bytes`` is what a web route calls (it returns the file's bytes); ``write_export``
writes a file atomically (nothing half-written is left); ``export_result`` starts from the
JSON a ``plan`` or ``simulate`` command saved (its ``"motion"`` block).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
import re
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from app.planning.export._checks import check_export
from app.planning.export._formats import FORMATS, ExportContext, one_line
from app.planning.export._motion import (
    MAX_SAMPLES,
    ExportError,
    PlanMotion,
    Samples,
    check_rate,
    sample_count,
)

if TYPE_CHECKING:
    from app.planning.robots import Robot

__all__ = [
    "ROS_FORMATS",
    "ExportStream",
    "approach_duration",
    "check_export_size",
    "check_ros_options",
    "export_bytes",
    "export_result",
    "export_sample_limit",
    "export_stream",
    "format_of",
    "motion_of_result",
    "with_approach",
    "write_chunks",
    "write_export",
]

_ALIASES = {".yml": "yaml", ".urscript": "script", ".sto": "mot"}
#: A ROS 2 topic or action name: slash-separated tokens of letters, digits and ``_``, none
#: starting with a digit (ROS 2's name rules without substitutions).
_ROS_NAME = re.compile(r"^/?[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*$")
#: The formats the ROS 2 options apply to.
ROS_FORMATS = ("yaml", "mcap")
#: An approach moves each joint at no more than this fraction of its speed and acceleration
#: limits [-], and takes at least APPROACH_MIN_S [s].
APPROACH_LIMIT_FRACTION = 0.5
APPROACH_MIN_S = 1.0
#: Approach speed of a joint without a speed limit [rad/s].
APPROACH_DEFAULT_SPEED = 0.5


def format_of(path: str | Path) -> str:
    """The format a file name selects by its extension (``.csv`` -> ``csv``, ...)."""
    suffix = Path(path).suffix.lower()
    for fmt in FORMATS.values():
        if fmt.extension == suffix:
            return fmt.name
    if suffix in _ALIASES:
        return _ALIASES[suffix]
    known = ", ".join(f.extension for f in FORMATS.values())
    raise ExportError(
        f"{one_line(Path(path).name)}: unknown export extension '{one_line(suffix)}': "
        f"expected one of {known}"
    )


def _format(fmt: str) -> Any:
    if fmt not in FORMATS:
        raise ExportError(f"export format '{one_line(fmt)}': expected one of {', '.join(FORMATS)}")
    return FORMATS[fmt]


def export_sample_limit(joints: int, max_samples: int) -> int:
    """The most samples an export of ``joints`` free joints may hold under a cap of
    ``max_samples`` for a six-joint arm: samples x joints stays within ``6 * max_samples``."""
    return max(2, max_samples * 6 // max(joints, 6))


def check_export_size(
    motion: PlanMotion, fmt: str, rate: float | None, max_samples: int | None
) -> tuple[float, int]:
    """The export's rate [Hz] and sample count, refused when it holds too many samples.

    Args:
        max_samples: the most samples of a six-joint arm (None: only the library's own cap);
            a robot with more free joints gets proportionally fewer
            (:func:`export_sample_limit`).

    Raises:
        ExportError: unknown format, a bad rate, or too many samples (naming ``rate``).
    """
    spec = _format(fmt)
    hz = check_rate(spec.default_rate if rate is None else rate)
    count = sample_count(motion.duration, hz)
    if max_samples is not None:
        joints = len(motion.joint_names)
        limit = export_sample_limit(joints, max_samples)
        if count > limit:
            raise ExportError(
                f"rate {hz:g} Hz gives {count} samples over {motion.duration:g} s: expected "
                f"at most {limit} samples for {joints} joints (a lower rate)"
            )
    return hz, count


def check_ros_options(
    fmt: str, *, goal: bool = False, topic: str | None = None, from_position: Any = None
) -> None:
    """Refuse a ROS 2 option the format does not take, or a topic that is not a ROS 2 name."""
    if goal and fmt != "yaml":
        raise ExportError(
            f"goal (a FollowJointTrajectory goal) is for format yaml: format is {one_line(fmt)}"
        )
    if topic is not None:
        if fmt not in ROS_FORMATS:
            raise ExportError(f"topic is for formats yaml and mcap: format is {one_line(fmt)}")
        if not isinstance(topic, str) or not _ROS_NAME.match(topic):
            raise ExportError(
                f"topic '{one_line(topic)}': expected a ROS 2 name such as "
                "/scaled_joint_trajectory_controller/joint_trajectory (letters, digits, _ and /)"
            )
    if from_position is not None and fmt not in ROS_FORMATS:
        raise ExportError(
            f"from_position (an approach segment) is for formats yaml and mcap: format is "
            f"{one_line(fmt)} (a URScript approaches the start with its movej)"
        )


def approach_duration(delta: np.ndarray, robot: Robot) -> float:
    """Time [s] of a rest-to-rest quintic over ``delta`` (n,) [rad] that keeps every joint
    within APPROACH_LIMIT_FRACTION of its speed and acceleration limits (peak speed of the
    quintic 1.875 |d| / T, peak acceleration 10 / sqrt(3) |d| / T^2), at least APPROACH_MIN_S."""
    d = np.abs(delta)
    speed = np.where(
        np.isfinite(robot.qd_max), APPROACH_LIMIT_FRACTION * robot.qd_max, APPROACH_DEFAULT_SPEED
    )
    times = [APPROACH_MIN_S, float(np.max(1.875 * d / speed))]
    qdd = robot.qdd_max if robot.qdd_max is not None else np.full(d.shape, np.inf)
    finite = np.isfinite(qdd)
    if finite.any():
        accel = APPROACH_LIMIT_FRACTION * qdd[finite]
        times.append(float(np.max(np.sqrt(10.0 / math.sqrt(3.0) * d[finite] / accel))))
    return max(times)


def with_approach(samples: Samples, start_from: Sequence[float], robot: Robot) -> Samples:
    """``samples`` after a rest-to-rest quintic from ``start_from`` (n,) [rad] to their first
    position, on the same grid (a whole number of periods, :func:`approach_duration` or just
    longer); the plan's samples follow, shifted by the approach's duration.

    Raises:
        ExportError: ``start_from`` has the wrong length, is not finite or is outside the
            robot's position limits (naming the joint).
    """
    names = robot.joint_names
    try:
        q0 = np.array(start_from, dtype=np.float64)
    except (TypeError, ValueError):
        raise ExportError("from_position: expected one number per joint") from None
    if q0.shape != (len(names),) or not np.all(np.isfinite(q0)):
        raise ExportError(
            f"from_position has {q0.size} values: expected {len(names)} finite joint positions "
            f"({', '.join(names)})"
        )
    for j, name in enumerate(names):
        if not robot.q_min[j] <= q0[j] <= robot.q_max[j]:
            raise ExportError(
                f"from_position: joint '{one_line(name)}' at {math.degrees(q0[j]):.6g} deg is "
                f"outside its limits [{math.degrees(robot.q_min[j]):.6g}, "
                f"{math.degrees(robot.q_max[j]):.6g}] deg"
            )
    delta = samples.q[0] - q0
    span = approach_duration(delta, robot)
    if not span * samples.rate <= MAX_SAMPLES:  # a continuous joint sent round many turns
        raise ExportError(
            f"from_position: the approach would take {span:.6g} s at the joints' speed limits: "
            f"expected at most {MAX_SAMPLES} samples at {samples.rate:g} Hz (a nearer position)"
        )
    count = math.ceil(span * samples.rate - 1e-9)
    span = count / samples.rate
    t = np.arange(count, dtype=np.float64) / samples.rate
    tau_ = (t / span)[:, None]
    q = q0 + delta * tau_**3 * (10.0 - 15.0 * tau_ + 6.0 * tau_**2)
    qd = delta * 30.0 * tau_**2 * (1.0 - tau_) ** 2 / span
    qdd = delta * 60.0 * tau_ * (1.0 - tau_) * (1.0 - 2.0 * tau_) / span**2
    tau = np.asarray(robot.dynamics().inverse_dynamics(q, qd, qdd), dtype=np.float64)
    return dataclasses.replace(
        samples,
        t=np.concatenate([t, samples.t + span]),
        q=np.concatenate([q, samples.q]),
        qd=np.concatenate([qd, samples.qd]),
        qdd=np.concatenate([qdd, samples.qdd]),
        tau=np.concatenate([tau, samples.tau]),
    )


def export_stream(
    motion: PlanMotion,
    fmt: str,
    *,
    method: str | None = None,
    rate: float | None = None,
    robot: Robot | None = None,
    max_samples: int | None = None,
    force: bool = False,
    allow_unsafe: bool = False,
    goal: bool = False,
    topic: str | None = None,
    from_position: Sequence[float] | None = None,
) -> ExportStream:
    """One method of a plan as the chunks of an export file (a few thousand samples each).

    Everything that can be refused is checked before this returns (the first chunk is made
    already), so a caller that streams the chunks never sends half a file and then an error.
    Arguments as :func:`export_bytes`; ``max_samples`` as :func:`check_export_size`.
    """
    spec = _format(fmt)
    chosen = motion.method(method)
    check_ros_options(fmt, goal=goal, topic=topic, from_position=from_position)
    hz, _ = check_export_size(motion, fmt, rate, max_samples)
    if robot is None:
        from app.planning.robots import load_robot_spec

        robot = load_robot_spec(motion.robot_spec)
    motion.check_robot(robot)
    samples = motion.sample(chosen.name, hz, robot)
    approach = 0.0
    if from_position is not None:
        planned = samples.t.size
        samples = with_approach(samples, from_position, robot)
        approach = float(samples.t[samples.t.size - planned])
        if max_samples is not None:
            limit = export_sample_limit(len(motion.joint_names), max_samples)
            if samples.t.size > limit:
                raise ExportError(
                    f"rate {hz:g} Hz gives {samples.t.size} samples with the approach: "
                    f"expected at most {limit} (a lower rate)"
                )
    notes = check_export(
        chosen.name,
        samples,
        robot,
        safety=motion.safety,
        force=force,
        allow_unsafe=allow_unsafe,
    )
    context = ExportContext(notes=notes, goal=goal, topic=topic, approach=approach)
    chunks = iter(spec.stream(motion, chosen, samples, context))
    first = next(chunks, b"")
    return ExportStream(itertools.chain((first,), chunks), context)


class ExportStream(Iterator[bytes]):
    """The chunks of an export file, with what the file records (``context``: limits exceeded
    when forced, the safety state, the approach)."""

    def __init__(self, chunks: Iterator[bytes], context: ExportContext) -> None:
        self._chunks = chunks
        self.context = context

    def __next__(self) -> bytes:
        return next(self._chunks)


def export_bytes(
    motion: PlanMotion,
    fmt: str,
    *,
    method: str | None = None,
    rate: float | None = None,
    robot: Robot | None = None,
    force: bool = False,
    allow_unsafe: bool = False,
    goal: bool = False,
    topic: str | None = None,
    from_position: Sequence[float] | None = None,
) -> bytes:
    """One method of a plan as the bytes of an export file.

    Args:
        motion: the plan's motion (``plan_motion(result, robot)`` or ``motion_of_result``).
        fmt: ``csv``, ``json``, ``yaml``, ``mcap``, ``script`` or ``mot``.
        method: method name; None = the motion's default (the optimised one).
        rate: sample rate [Hz]; None = the format's default.
        robot: the robot; None = rebuilt from ``motion.robot_spec``. Either way its torques
            are checked against the plan's, so a changed robot file is refused.
        force: write a file whose samples leave the robot's limits (or a URScript for a robot
            that is not a UR); the file records what was exceeded.
        allow_unsafe: write a method the plan's safety check found in contact; the file records
            the first contact.
        goal: YAML as a ``control_msgs/action/FollowJointTrajectory`` goal (yaml only).
        topic: the controller's topic (message, MCAP) or action (goal) name (yaml, mcap).
        from_position: (n,) current joint positions [rad]: the file starts there and
            approaches the plan's start first (yaml, mcap).

    Raises:
        ExportRefused: a limit exceeded without ``force`` or a contact without
            ``allow_unsafe`` (an :class:`ExportError`; the service answers 409).
        ExportError: unknown format or method, a rate outside (0, 20 kHz], a robot that differs
            from the planned one, an option the format does not take, or a format the robot
            cannot use (URScript needs six joints).
        RobotError: the robot cannot be rebuilt (its files are gone).
    """
    return b"".join(
        export_stream(
            motion,
            fmt,
            method=method,
            rate=rate,
            robot=robot,
            force=force,
            allow_unsafe=allow_unsafe,
            goal=goal,
            topic=topic,
            from_position=from_position,
        )
    )


def motion_of_result(result: Mapping[str, Any]) -> PlanMotion:
    """The motion block of a saved ``plan``/``simulate`` JSON result."""
    if not isinstance(result, Mapping) or "motion" not in result:
        raise ExportError(
            "result has no 'motion' block: expected the --json output of bioplan plan or simulate"
        )
    motion = PlanMotion.from_dict(result["motion"])
    safety = result.get("safety")
    return dataclasses.replace(motion, safety=dict(safety) if isinstance(safety, Mapping) else None)


def export_result(
    result: Mapping[str, Any],
    fmt: str,
    *,
    method: str | None = None,
    rate: float | None = None,
    robot: Robot | None = None,
    **options: Any,
) -> bytes:
    """:func:`export_bytes` of a saved JSON result (its robot rebuilt from the result, its
    ``safety`` block checked); ``options`` as :func:`export_bytes` (``force``, ...)."""
    return export_bytes(
        motion_of_result(result), fmt, method=method, rate=rate, robot=robot, **options
    )


def write_export(
    path: str | Path,
    motion: PlanMotion,
    *,
    fmt: str | None = None,
    method: str | None = None,
    rate: float | None = None,
    robot: Robot | None = None,
    **options: Any,
) -> Path:
    """Write an export file atomically (a temporary file in the same folder, then renamed).

    Args:
        path: the file; its extension selects the format unless ``fmt`` is given.
        options: as :func:`export_bytes` (``force``, ``allow_unsafe``, ``goal``, ``topic``,
            ``from_position``).

    Returns:
        The path written.
    """
    target = Path(path)
    chunks = export_stream(
        motion, fmt or format_of(target), method=method, rate=rate, robot=robot, **options
    )
    return write_chunks(target, chunks)


def write_chunks(path: str | Path, chunks: Iterator[bytes]) -> Path:
    """Write ``chunks`` (an :func:`export_stream`) to ``path`` atomically; the path written."""
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise ExportError(f"{target}: folder {folder} does not exist: expected an existing folder")
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".bioplan-export-", suffix=target.suffix)
    try:
        with os.fdopen(fd, "wb") as handle:
            for chunk in chunks:
                handle.write(chunk)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target
