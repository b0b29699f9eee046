"""Robot models: built-in arms (URDF + MJCF + parameter tables) and user URDFs.

``load_robot("human_arm_2dof")`` (de Leva 1996 segments, 12 kg dumbbell),
``load_robot("curtain_wall_6dof")`` (6-axis installation robot, 4 kg panel) or
``load_robot("my_arm.urdf", mjcf="my_arm.xml")``; an uploaded robot's files with
``write_robot_files(spec, folder)`` and ``load_robot_files(files, spec)``.
"""

from app.planning.robots._cache import cache_root
from app.planning.robots._human import HumanArmSegments, human_arm_segments, segment_masses
from app.planning.robots._identified import LinkInertial, link_inertials
from app.planning.robots._loader import (
    BUILTIN_ROBOTS,
    builtin_files,
    cache_dir,
    load_robot,
    load_robot_spec,
    locks_from_display,
)
from app.planning.robots._mjcf_urdf import urdf_from_mjcf
from app.planning.robots._obstacles import Obstacle
from app.planning.robots._package import (
    MeshLimitError,
    MeshLimits,
    RobotPackage,
    check_mesh,
    check_package_zip,
    open_robot_package,
    resolve_mesh,
)
from app.planning.robots._sidecar import ACTUATOR_FIELDS, Sidecar, read_sidecar, sidecar_yaml
from app.planning.robots._types import IDEAL_ACTUATOR, Payload, Robot, RobotError
from app.planning.robots._uploaded import (
    UPLOAD_NAMES,
    RobotFiles,
    is_uploaded,
    joint_table,
    load_robot_files,
    robot_files_in,
    write_robot_files,
)
from app.planning.robots._urdf import parse_urdf, read_xml
from app.planning.robots._user import missing_meshes

__all__ = [
    "ACTUATOR_FIELDS",
    "BUILTIN_ROBOTS",
    "IDEAL_ACTUATOR",
    "UPLOAD_NAMES",
    "HumanArmSegments",
    "LinkInertial",
    "MeshLimitError",
    "MeshLimits",
    "Obstacle",
    "Payload",
    "Robot",
    "RobotError",
    "RobotFiles",
    "RobotPackage",
    "Sidecar",
    "builtin_files",
    "cache_dir",
    "cache_root",
    "check_mesh",
    "check_package_zip",
    "human_arm_segments",
    "is_uploaded",
    "joint_table",
    "link_inertials",
    "load_robot",
    "load_robot_files",
    "load_robot_spec",
    "locks_from_display",
    "missing_meshes",
    "open_robot_package",
    "parse_urdf",
    "read_sidecar",
    "read_xml",
    "resolve_mesh",
    "robot_files_in",
    "segment_masses",
    "sidecar_yaml",
    "urdf_from_mjcf",
    "write_robot_files",
]
