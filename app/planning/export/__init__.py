"""Trajectory export: a plan's methods as files a robot controller, ROS 2 or OpenSim reads.

Public API::

    from app.planning.export import plan_motion, export_bytes, write_export, export_result
    motion = plan_motion(result, robot)          # exact knots of every method, JSON-ready
    data = export_bytes(motion, "csv", method="paper", rate=1000.0, robot=robot)
    write_export("paper.script", motion, rate=500.0, robot=robot)
    data = export_result(json.load(open("plan.json")), "yaml")   # from a saved --json result

Formats (``FORMATS``): csv, json, yaml (ROS 2 JointTrajectory), mcap (rosbag2), script
(URScript), mot (OpenSim). See ``docs/export.md`` for units and resampling.

Before writing, every export checks its samples against the robot's limits and the plan's
safety check (``_checks``): a file past a limit or into a contact is refused
(:class:`ExportRefused`) unless ``force=True`` / ``allow_unsafe=True``, which it then records.
"""

from app.planning.export._api import (
    ROS_FORMATS,
    ExportStream,
    approach_duration,
    check_export_size,
    check_ros_options,
    export_bytes,
    export_result,
    export_sample_limit,
    export_stream,
    format_of,
    motion_of_result,
    with_approach,
    write_chunks,
    write_export,
)
from app.planning.export._checks import (
    Exceedance,
    ExportNotes,
    ExportRefused,
    check_export,
    limit_exceedances,
    safety_status,
)
from app.planning.export._formats import (
    DEFAULT_ACTION,
    DEFAULT_TOPIC,
    FORMATS,
    UR_JOINT_NAMES,
    ExportContext,
    ExportFormat,
    csv_cell,
    full_arm,
    is_universal_robot,
    one_line,
    public_result,
    public_spec,
    ur_number,
)
from app.planning.export._motion import (
    MAX_RATE_HZ,
    MOTION_FORMAT,
    ExportError,
    MethodMotion,
    PlanMotion,
    Samples,
    check_rate,
    method_motion,
    plan_methods,
    plan_motion,
    sample_count,
)

__all__ = [
    "DEFAULT_ACTION",
    "DEFAULT_TOPIC",
    "FORMATS",
    "MAX_RATE_HZ",
    "MOTION_FORMAT",
    "ROS_FORMATS",
    "UR_JOINT_NAMES",
    "Exceedance",
    "ExportContext",
    "ExportError",
    "ExportFormat",
    "ExportNotes",
    "ExportRefused",
    "ExportStream",
    "MethodMotion",
    "PlanMotion",
    "Samples",
    "approach_duration",
    "check_export",
    "check_export_size",
    "check_rate",
    "check_ros_options",
    "csv_cell",
    "export_bytes",
    "export_result",
    "export_sample_limit",
    "export_stream",
    "format_of",
    "full_arm",
    "is_universal_robot",
    "limit_exceedances",
    "method_motion",
    "motion_of_result",
    "one_line",
    "plan_methods",
    "plan_motion",
    "public_result",
    "public_spec",
    "safety_status",
    "sample_count",
    "ur_number",
    "with_approach",
    "write_chunks",
    "write_export",
]
