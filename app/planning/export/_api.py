"""Export entry points: a plan's motion (or a saved JSON result), method, rate, format -> bytes.

``export_bytes`` is what a web route calls (it returns the file's bytes); ``write_export``
writes a file atomically (nothing half-written is left); ``export_result`` starts from the
JSON a ``plan`` or ``simulate`` command saved (its ``"motion"`` block).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.planning.export._formats import FORMATS
from app.planning.export._motion import ExportError, PlanMotion, check_rate

if TYPE_CHECKING:
    from app.planning.robots import Robot

__all__ = ["export_bytes", "export_result", "format_of", "motion_of_result", "write_export"]

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
        f"{Path(path).name}: unknown export extension '{suffix}': expected one of {known}"
    )


def _format(fmt: str) -> Any:
    if fmt not in FORMATS:
        raise ExportError(f"export format '{fmt}': expected one of {', '.join(FORMATS)}")
    return FORMATS[fmt]


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
    spec = _format(fmt)
    chosen = motion.method(method)
    hz = check_rate(spec.default_rate if rate is None else rate)
    if robot is None:
        from app.planning.robots import load_robot_spec

        robot = load_robot_spec(motion.robot_spec)
    motion.check_robot(robot)
    samples = motion.sample(chosen.name, hz, robot)
    data: bytes = spec.write(motion, chosen, samples)
    return data


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
    data = export_bytes(motion, fmt or format_of(target), method=method, rate=rate, robot=robot)
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise ExportError(f"{target}: folder {folder} does not exist: expected an existing folder")
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".bioplan-export-", suffix=target.suffix)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target
