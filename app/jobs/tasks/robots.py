"""Robot jobs: load a job's robot from its spec, describe an uploaded robot (checked by
loading it before it is stored).

The uploaded files are read by the planning package's public loader
(``app.planning.robots.write_robot_files``, ``load_robot_files``); this module only chooses the
folder they live in.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TypedDict

import numpy as np

from app.errors import BioPlanError
from app.jobs.tasks.types import RobotSpec
from app.jsonsafe import json_safe
from app.planning.robots import (
    BUILTIN_ROBOTS,
    UPLOAD_NAMES,
    Robot,
    is_uploaded,
    joint_table,
    load_robot,
    load_robot_files,
    missing_meshes,
    robot_files_in,
    write_robot_files,
)

__all__ = [
    "UPLOAD_NAMES",
    "builtin_robots",
    "default_task_safety",
    "describe_robot",
    "package_members",
    "robot_from_spec",
]


@contextmanager
def robot_from_spec(
    spec: RobotSpec, payload_kg: float | None = None, *, folder: Path | None = None
) -> Iterator[Robot]:
    """Load the robot of a job's spec; uploaded files are written to a folder first.

    This is the one function the service reads uploaded robot files (URDF, MJCF, package zip,
    sidecar) through (``app.planning.robots.write_robot_files``/``load_robot_files``): every
    upload is checked through it before it is stored.

    Args:
        spec: ``{"name"}`` for a built-in robot, or an uploaded one: ``{"name", "urdf",
            "mjcf", "sidecar", "package"}`` (bytes or None; a package is a zip with meshes),
            ``urdf_member``/``mjcf_member``/``sidecar_member`` (files inside the package),
            ``shoulder_joint``, ``elbow_joint`` (names or None), ``locks`` (name -> degrees,
            or metres for prismatic joints) and ``payload`` [kg].
        payload_kg: payload [kg]; None takes the spec's, then the model's default.
        folder: where to keep the files (kept after the context, e.g. for the viewer's meshes;
            reused when it exists); None: a temporary folder removed afterwards.

    Yields:
        The loaded ``app.planning.robots.Robot`` (its files exist while the context is open).

    Raises:
        RobotError: the model cannot be loaded, or the package is refused (a ``BioPlanError``).
    """
    payload = payload_kg if payload_kg is not None else spec.get("payload")
    if not is_uploaded(spec):
        yield load_robot(spec["name"], payload=payload)
        return
    if folder is not None:
        ready = folder / ".complete"
        if not ready.exists():
            with tempfile.TemporaryDirectory(prefix=".partial-", dir=folder.parent) as tmp:
                files = write_robot_files(spec, Path(tmp) / "robot")
                load_robot_files(files, spec, payload=payload)  # refuse before keeping anything
                try:
                    Path(tmp, "robot").rename(folder)
                except OSError:
                    if not ready.exists():  # not another request that kept it meanwhile
                        raise
                ready.touch()
        yield load_robot_files(robot_files_in(spec, folder), spec, payload=payload)
        return
    with tempfile.TemporaryDirectory(prefix="bioplan-robot-") as tmp:
        yield load_robot_files(write_robot_files(spec, Path(tmp) / "robot"), spec, payload=payload)


class PackageMember(TypedDict):
    """One file of a robot package zip."""

    path: str  #: relative path in the zip
    bytes: int  #: uncompressed size
    role: str  #: urdf, mjcf, sidecar, mesh or other


def package_members(data: bytes) -> list[PackageMember]:
    """Files of a robot package zip: relative path, size [bytes] and role (names only; the
    zip is checked and extracted by :func:`robot_from_spec`)."""
    import io
    import zipfile

    roles = {".urdf": "urdf", ".xml": "mjcf", ".mjcf": "mjcf", ".yaml": "sidecar"}
    roles.update({".yml": "sidecar", ".stl": "mesh", ".dae": "mesh", ".obj": "mesh"})
    out: list[PackageMember] = []
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        for info in archive.infolist():
            if info.is_dir():
                continue
            role = roles.get(Path(info.filename).suffix.lower(), "other")
            out.append({"path": info.filename, "bytes": info.file_size, "role": role})
    return out


def builtin_robots() -> list[str]:
    """Names of the built-in robots."""
    return sorted(BUILTIN_ROBOTS)


def describe_robot(spec: RobotSpec, folder: Path | None = None) -> dict[str, object]:
    """Joints, limits, roles, locks, motors and default task of a robot (SI units: rad, rad/s,
    Nm; payload in kg; ``*_deg`` in degrees).

    Args:
        spec: the robot's spec (:func:`robot_from_spec`).
        folder: keep an uploaded robot's files there (see :func:`robot_from_spec`).

    Raises:
        RobotError: the model cannot be loaded; one-line message.
    """
    with robot_from_spec(spec, folder=folder) as robot:
        described: dict[str, object] = json_safe(
            {
                "name": spec["name"],
                "joint_names": list(robot.joint_names),
                "q_min": np.asarray(robot.q_min, float),
                "q_max": np.asarray(robot.q_max, float),
                "qd_max": np.asarray(robot.qd_max, float),
                "tau_max": np.asarray(robot.tau_max, float),
                "payload": float(robot.payload.mass),
                "has_mjcf": robot.mjcf_path is not None,
                "shoulder_joint": robot.shoulder_joint_name,
                "elbow_joint": robot.elbow_joint_name,
                "locks": dict(robot.locks),
                "all_joint_names": list(robot.all_joint_names),
                "joints": joint_table(robot),
                "motors_modelled": bool(robot.motors_modelled),
                "default_start_deg": np.degrees(np.asarray(robot.default_start, float)),
                "default_goal_deg": np.degrees(np.asarray(robot.default_goal, float)),
                "missing_meshes": missing_meshes(robot),
                "default_task_safety": default_task_safety(robot),
            }
        )
    return described


#: Duration of the default task's quintic checked at onboarding [s]; the path a quintic
#: sweeps does not depend on its duration, only the times of the findings scale with it.
DEFAULT_TASK_CHECK_S = 1.0


def default_task_safety(robot: Robot) -> dict[str, object]:
    """The safety check of the robot's default task (its quintic from the default start to the
    default goal over ``DEFAULT_TASK_CHECK_S``), run before the robot is offered.

    Returns:
        ``{ok (None when not checked), checked, reason, min_clearance [m], duration [s],
        findings (count), worst (the deepest finding's dict, or None), summary}``; ``worst``
        holds ``links``, ``kind``, ``obstacle``, ``depth`` [m] and ``deepest_time`` [s].
    """
    from app.planning.profiles import quintic
    from app.planning.safety import check_safety as safety
    from app.planning.safety import not_checked
    from app.planning.safety import safety_summary as summary

    trajectory = quintic(
        np.asarray(robot.default_start, float),
        np.asarray(robot.default_goal, float),
        DEFAULT_TASK_CHECK_S,
        n_samples=201,
    )
    try:
        report = safety(robot, {"quintic": trajectory}).to_dict()
    except BioPlanError as exc:  # e.g. a sidecar changed since: the robot is still offered
        report = not_checked(f"not checked: {exc}").to_dict()
    findings = list(report.get("findings") or [])
    worst = max(findings, key=lambda f: float(f["depth"])) if findings else None
    return {
        "ok": report["ok"],
        "checked": report["checked"],
        "reason": report.get("reason"),
        "min_clearance": report.get("min_clearance"),
        "duration": DEFAULT_TASK_CHECK_S,
        "findings": len(findings),
        "worst": worst,
        "summary": summary(report),
    }
