"""Robots from uploaded files: a robot's files written into a folder and loaded from there.

An uploaded robot is described by a *spec*: ``{"name", "urdf", "mjcf", "sidecar", "package"}``
(file contents as bytes or None; a package is a zip with meshes), ``urdf_member``/
``mjcf_member``/``sidecar_member`` (files inside the package), ``shoulder_joint``,
``elbow_joint``, ``base_link``, ``tip_link`` (names or None) and ``locks`` (joint name ->
degrees, or metres for prismatic joints). The user's file names are never used as paths.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.errors import one_line
from app.planning.robots._loader import load_robot
from app.planning.robots._mjcf_urdf import urdf_from_mjcf
from app.planning.robots._package import check_mjcf_files, open_robot_package, package_dirs
from app.planning.robots._types import Robot, RobotError
from app.planning.robots._urdf import parse_urdf
from app.planning.robots._user import locks_from_display

#: Fixed file names of uploaded single files in a robot's folder.
UPLOAD_NAMES = {"urdf": "robot.urdf", "mjcf": "robot.xml", "sidecar": "robot.yaml"}


@dataclass(frozen=True)
class RobotFiles:
    """An uploaded robot's files on disk.

    Attributes:
        root: the robot's folder.
        urdf, mjcf, sidecar: the model files (None: not uploaded).
        package_dirs: folders ``package://`` mesh names resolve against (a package's).
    """

    root: Path
    urdf: Path | None
    mjcf: Path | None
    sidecar: Path | None
    package_dirs: tuple[Path, ...] = ()


def is_uploaded(spec: Mapping[str, Any]) -> bool:
    """Whether a spec names uploaded files (else it names a built-in robot)."""
    return any(spec.get(k) is not None for k in ("urdf", "mjcf", "package"))


def _member(root: Path, relative: str | None, what: str) -> Path | None:
    """``root/relative`` when ``relative`` names a file inside ``root`` (a package member)."""
    if relative is None:
        return None
    try:
        path = (root / relative).resolve()
        inside = path.is_relative_to(root.resolve()) and path.is_file()
    except (OSError, ValueError):  # a name too long for the file system, a NUL byte
        inside = False
    if not inside:
        raise RobotError(f"{what} '{one_line(relative, 80)}' is not a file of the robot package")
    return path


def write_robot_files(spec: Mapping[str, Any], folder: Path) -> RobotFiles:
    """Write a spec's files into ``folder``: a package zip extracted safely (refusing ``../``,
    absolute paths and links), single files under fixed names (:data:`UPLOAD_NAMES`).

    Raises:
        RobotError: the package is refused, or a ``*_member`` is not one of its files.
    """
    dirs: tuple[Path, ...] = ()
    root = folder
    if spec.get("package") is not None:
        archive = folder.parent / f"{folder.name}.zip"
        archive.write_bytes(spec["package"])
        try:
            package = open_robot_package(archive, folder)
        finally:
            archive.unlink(missing_ok=True)
        root, dirs = package.root, package.package_dirs
    else:
        folder.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path | None] = {}
    for key in ("urdf", "mjcf", "sidecar"):
        if spec.get(key) is not None:
            path = root / UPLOAD_NAMES[key]
            path.write_bytes(spec[key])
            files[key] = path
        else:
            files[key] = _member(root, spec.get(f"{key}_member"), key)
    return RobotFiles(folder, files["urdf"], files["mjcf"], files["sidecar"], dirs)


def robot_files_in(spec: Mapping[str, Any], folder: Path) -> RobotFiles:
    """The files of a robot folder written earlier by :func:`write_robot_files`."""
    files: dict[str, Path | None] = {}
    for key in ("urdf", "mjcf", "sidecar"):
        if spec.get(key) is not None:
            files[key] = folder / UPLOAD_NAMES[key]
        else:
            files[key] = _member(folder, spec.get(f"{key}_member"), key)
    dirs = package_dirs(folder.resolve()) if spec.get("package") is not None else ()
    return RobotFiles(folder, files["urdf"], files["mjcf"], files["sidecar"], dirs)


def load_robot_files(
    files: RobotFiles, spec: Mapping[str, Any], *, payload: float | None = None
) -> Robot:
    """Load an uploaded robot from its files, with the spec's joint roles, links and locks.

    Args:
        files: where the files are (:func:`write_robot_files`, :func:`robot_files_in`).
        spec: the robot's spec (module docstring); its locks are in display units (deg, m).
        payload: payload [kg]; None: the model's default.

    Raises:
        RobotError: no model file, an MJCF naming files outside the upload, or the model
            cannot be loaded (one line naming the file).
    """
    urdf, mjcf = files.urdf, files.mjcf
    if urdf is None and mjcf is None:
        raise RobotError("the robot has no URDF and no MJCF: expected at least one model file")
    if mjcf is not None:
        check_mjcf_files(mjcf, files.root)  # before MuJoCo opens anything it names
    locks = spec.get("locks") or {}
    if locks:
        if urdf is not None:
            locks = locks_from_display(urdf, locks)
        elif mjcf is not None:
            locks = locks_from_display(urdf_from_mjcf(mjcf), locks)
    return load_robot(
        str(urdf if urdf is not None else mjcf),
        payload=payload,
        mjcf=None if urdf is None or mjcf is None else str(mjcf),
        shoulder_joint=spec.get("shoulder_joint"),
        elbow_joint=spec.get("elbow_joint"),
        locks=locks or None,
        sidecar=files.sidecar,
        package_dirs=files.package_dirs,
        base_link=spec.get("base_link"),
        tip_link=spec.get("tip_link"),
    )


def joint_table(robot: Robot) -> list[dict[str, Any]]:
    """Every movable joint of the robot's URDF: ``name``, ``kind``, ``unit``, ``lower``/
    ``upper`` [rad or m], ``velocity`` [rad/s or m/s], ``effort`` [Nm or N], ``locked``,
    ``lock_value`` and ``role`` (``shoulder``, ``elbow`` or None)."""
    model = parse_urdf(Path(robot.urdf_path))
    roles = {robot.shoulder_joint_name: "shoulder", robot.elbow_joint_name: "elbow"}
    rows = []
    for joint in model.joints:
        if joint.name not in robot.all_joint_names:
            continue  # a mimic follower or a joint the reduced model drops
        rows.append(
            {
                "name": joint.name,
                "kind": joint.kind,
                "unit": "m" if joint.kind == "prismatic" else "rad",
                "lower": joint.lower,
                "upper": joint.upper,
                "velocity": joint.velocity,
                "effort": joint.effort,
                "locked": joint.name in robot.locks,
                "lock_value": robot.locks.get(joint.name),
                "role": roles.get(joint.name),
            }
        )
    return rows
