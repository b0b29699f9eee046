"""Trajectory export: a plan's methods as files a robot controller, ROS 2 or OpenSim reads.

Public API::

    from app.planning.export import plan_motion, export_bytes, write_export, export_result
    motion = plan_motion(result, robot)          # exact knots of every method, JSON-ready
    data = export_bytes(motion, "csv", method="paper", rate=1000.0, robot=robot)
    write_export("paper.script", motion, rate=500.0, robot=robot)
    data = export_result(json.load(open("plan.json")), "yaml")   # from a saved --json result

Formats (``FORMATS``): csv, json, yaml (ROS 2 JointTrajectory), mcap (rosbag2), script
(URScript), mot (OpenSim). See ``docs/export.md`` for units and resampling.
"""

from app.planning.export._api import (
    check_export_size,
    export_bytes,
    export_result,
    export_sample_limit,
    export_stream,
    format_of,
    motion_of_result,
    write_export,
)
from app.planning.export._formats import (
    FORMATS,
    ExportFormat,
    csv_cell,
    full_arm,
    one_line,
    public_result,
    public_spec,
)
from app.planning.export._motion import (
    MAX_RATE_HZ,
    MOTION_FORMAT,
    ExportError,
    MethodMotion,
    PlanMotion,
    Samples,
    check_rate,
    plan_methods,
    plan_motion,
    sample_count,
)

__all__ = [
    "FORMATS",
    "MAX_RATE_HZ",
    "MOTION_FORMAT",
    "ExportError",
    "ExportFormat",
    "MethodMotion",
    "PlanMotion",
    "Samples",
    "check_export_size",
    "check_rate",
    "csv_cell",
    "export_bytes",
    "export_result",
    "export_sample_limit",
    "export_stream",
    "format_of",
    "full_arm",
    "motion_of_result",
    "one_line",
    "plan_methods",
    "plan_motion",
    "public_result",
    "public_spec",
    "sample_count",
    "write_export",
]
