"""Robot models: built-in arms (URDF + MJCF + parameter tables) and user URDFs.

``load_robot("human_arm_2dof")`` (de Leva 1996 segments, 12 kg dumbbell),
``load_robot("curtain_wall_6dof")`` (6-axis installation robot, 4 kg panel) or
``load_robot("my_arm.urdf", mjcf="my_arm.xml")``.
"""

from app.planning.robots._human import HumanArmSegments, human_arm_segments, segment_masses
from app.planning.robots._loader import (
    BUILTIN_ROBOTS,
    builtin_files,
    cache_dir,
    load_robot,
    load_robot_spec,
    locks_from_display,
)
from app.planning.robots._package import RobotPackage, open_robot_package, resolve_mesh
from app.planning.robots._sidecar import Sidecar, read_sidecar
from app.planning.robots._types import IDEAL_ACTUATOR, Payload, Robot, RobotError
from app.planning.robots._user import missing_meshes

__all__ = [
    "BUILTIN_ROBOTS",
    "IDEAL_ACTUATOR",
    "HumanArmSegments",
    "Payload",
    "Robot",
    "RobotError",
    "RobotPackage",
    "Sidecar",
    "builtin_files",
    "cache_dir",
    "human_arm_segments",
    "load_robot",
    "load_robot_spec",
    "locks_from_display",
    "missing_meshes",
    "open_robot_package",
    "read_sidecar",
    "resolve_mesh",
    "segment_masses",
]
