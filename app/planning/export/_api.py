"""Export entry points: a plan's motion (or a saved JSON result), method, rate, format -> bytes.

``export_bytes`` is what a web route calls (it returns the file's bytes); ``write_export``
writes a file atomically (nothing half-written is left); ``export_result`` starts from the
JSON a ``plan`` or ``simulate`` command saved (its ``"motion"`` block).
"""

from __future__ import annotations

import itertools
import os
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.planning.export._formats import FORMATS, one_line
from app.planning.export._motion import ExportError, PlanMotion, check_rate, sample_count

if TYPE_CHECKING:
    from app.planning.robots import Robot

__all__ = [
    "check_export_size",
    "export_bytes",
    "export_result",
    "export_sample_limit",
    "export_stream",
    "format_of",
    "motion_of_result",
    "write_export",
]

_ALIASES = {".yml": "yaml", ".urscript": "script", ".sto": "mot"}


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


def export_stream(
    motion: PlanMotion,
    fmt: str,
    *,
    method: str | None = None,
    rate: float | None = None,
    robot: Robot | None = None,
    max_samples: int | None = None,
) -> Iterator[bytes]:
    """One method of a plan as the chunks of an export file (a few thousand samples each).

    Everything that can be refused is checked before this returns (the first chunk is made
    already), so a caller that streams the chunks never sends half a file and then an error.
    Arguments as :func:`export_bytes`; ``max_samples`` as :func:`check_export_size`.
    """
    spec = _format(fmt)
    chosen = motion.method(method)
    hz, _ = check_export_size(motion, fmt, rate, max_samples)
    if robot is None:
        from app.planning.robots import load_robot_spec

        robot = load_robot_spec(motion.robot_spec)
    motion.check_robot(robot)
    samples = motion.sample(chosen.name, hz, robot)
    chunks = iter(spec.stream(motion, chosen, samples))
    first = next(chunks, b"")
    return itertools.chain((first,), chunks)


def export_bytes(
    motion: PlanMotion,
    fmt: str,
    *,
    method: str | None = None,
    rate: float | None = None,
    robot: Robot | None = None,
) -> bytes:
    """One method of a plan as the bytes of an export file.

    Args:
        motion: the plan's motion (``plan_motion(result, robot)`` or ``motion_of_result``).
        fmt: ``csv``, ``json``, ``yaml``, ``mcap``, ``script`` or ``mot``.
        method: method name; None = the motion's default (the optimised one).
        rate: sample rate [Hz]; None = the format's default.
        robot: the robot; None = rebuilt from ``motion.robot_spec``. Either way its torques
            are checked against the plan's, so a changed robot file is refused.

    Raises:
        ExportError: unknown format or method, a rate outside (0, 20 kHz], a robot that differs
            from the planned one, or a format the robot cannot use (URScript needs six joints).
        RobotError: the robot cannot be rebuilt (its files are gone).
    """
    return b"".join(export_stream(motion, fmt, method=method, rate=rate, robot=robot))


def motion_of_result(result: Mapping[str, Any]) -> PlanMotion:
    """The motion block of a saved ``plan``/``simulate`` JSON result."""
    if not isinstance(result, Mapping) or "motion" not in result:
        raise ExportError(
            "result has no 'motion' block: expected the --json output of bioplan plan or simulate"
        )
    return PlanMotion.from_dict(result["motion"])


def export_result(
    result: Mapping[str, Any],
    fmt: str,
    *,
    method: str | None = None,
    rate: float | None = None,
    robot: Robot | None = None,
) -> bytes:
    """:func:`export_bytes` of a saved JSON result (its robot rebuilt from the result)."""
    return export_bytes(motion_of_result(result), fmt, method=method, rate=rate, robot=robot)


def write_export(
    path: str | Path,
    motion: PlanMotion,
    *,
    fmt: str | None = None,
    method: str | None = None,
    rate: float | None = None,
    robot: Robot | None = None,
) -> Path:
    """Write an export file atomically (a temporary file in the same folder, then renamed).

    Args:
        path: the file; its extension selects the format unless ``fmt`` is given.

    Returns:
        The path written.
    """
    target = Path(path)
    chunks = export_stream(motion, fmt or format_of(target), method=method, rate=rate, robot=robot)
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
