"""``bioplan export``: a saved ``plan``/``simulate`` JSON result as a controller file."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from app.cli._common import CliError, add_json_args, emit, floats


def _read_result(path: str) -> dict[str, Any]:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise CliError(f"{path}: cannot read the result ({exc.strerror})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CliError(
            f"{path}: not JSON (line {exc.lineno}): expected the --json output of plan/simulate"
        ) from None
    if not isinstance(data, dict):
        raise CliError(f"{path}: expected a JSON object (the --json output of plan/simulate)")
    return data


def _from_position(text: str | None, joints: tuple[str, ...]) -> list[float] | None:
    """``--from-position`` (degrees, one per free joint) in radians, or None."""
    if text is None:
        return None
    values = floats(text, "from-position")
    if len(values) != len(joints):
        raise CliError(
            f"--from-position has {len(values)} angles: expected {len(joints)} in degrees, one "
            f"per joint ({', '.join(joints)})"
        )
    return [math.radians(v) for v in values]


def cmd_export(args: argparse.Namespace) -> int:
    from app.planning.export import (
        FORMATS,
        check_rate,
        check_ros_options,
        export_stream,
        format_of,
        motion_of_result,
        one_line,
        write_chunks,
    )

    fmt = args.format or format_of(args.out_file)
    if fmt not in FORMATS:
        raise CliError(f"--format {fmt}: expected one of {', '.join(FORMATS)}")
    if args.format and Path(args.out_file).suffix and format_of(args.out_file) != args.format:
        raise CliError(
            f"--out {args.out_file} has extension {Path(args.out_file).suffix} but --format is "
            f"{args.format}: expected them to agree"
        )
    rate = check_rate(FORMATS[fmt].default_rate if args.rate is None else args.rate)
    # before the result is read (its message names the option, not the result file)
    check_ros_options(fmt, goal=args.goal, topic=args.topic, from_position=args.from_position)
    try:
        motion = motion_of_result(_read_result(args.result))
    except CliError:
        raise
    except ValueError as exc:  # ExportError names the field; prefix the file
        raise CliError(f"{args.result}: {exc}") from None
    chosen = motion.method(args.method)
    chunks = export_stream(
        motion,
        fmt,
        method=chosen.name,
        rate=rate,
        force=args.force,
        allow_unsafe=args.allow_unsafe,
        goal=args.goal,
        topic=args.topic,
        from_position=_from_position(args.from_position, motion.joint_names),
    )
    written = write_chunks(args.out_file, chunks)
    record = chunks.context
    size = written.stat().st_size
    payload = {
        "out": str(written),
        "format": fmt,
        "method": chosen.name,
        "rate": rate,
        "robot": motion.robot,
        "joint_names": list(motion.joint_names),
        "duration": motion.duration,
        "bytes": size,
        "export": record.to_dict(),
    }
    text = (
        f"wrote {written} ({fmt}, {size} bytes): robot {one_line(motion.robot)}, "
        f"method {chosen.name}, "
        f"{rate:g} Hz over {motion.duration:g} s; " + "; ".join(record.lines())
    )
    emit(args, payload, text)
    return 0


def register(sub: Any) -> None:
    """Add ``export`` to the ``bioplan`` subcommands."""
    from app.planning.export import FORMATS

    p = sub.add_parser(
        "export", help="write a saved plan or simulation result as a controller file"
    )
    p.add_argument("result", help="JSON result of `bioplan plan --json` or `bioplan simulate`")
    p.add_argument(
        "--format",
        default=None,
        choices=list(FORMATS),
        help="file format (default: from the extension of --out)",
    )
    p.add_argument(
        "--rate",
        type=float,
        default=None,
        metavar="HZ",
        help="sample rate (default: the format's: "
        + ", ".join(f"{f.name} {f.default_rate:g} Hz" for f in FORMATS.values())
        + ")",
    )
    p.add_argument(
        "--method",
        default=None,
        help="planning method to export (default: the result's optimised one, paper)",
    )
    p.add_argument("--out", dest="out_file", required=True, help="file to write")
    p.add_argument(
        "--force",
        action="store_true",
        help="write it although a sample leaves the robot's position, speed, acceleration or "
        "torque limits (or a URScript for a robot that is not a UR); the file records what "
        "was exceeded (default: refuse, exit 2)",
    )
    p.add_argument(
        "--allow-unsafe",
        action="store_true",
        help="write a method the plan's collision check found in contact; the file records "
        "the first contact (default: refuse, exit 2)",
    )
    p.add_argument(
        "--goal",
        action="store_true",
        help="yaml: a control_msgs/action/FollowJointTrajectory goal (for ros2 action "
        "send_goal) instead of the bare trajectory_msgs/msg/JointTrajectory",
    )
    p.add_argument(
        "--topic",
        default=None,
        metavar="NAME",
        help="yaml, mcap: the controller's topic (or action, with --goal), e.g. "
        "/scaled_joint_trajectory_controller/joint_trajectory (default: /joint_trajectory; "
        "goal: /joint_trajectory_controller/follow_joint_trajectory)",
    )
    p.add_argument(
        "--from-position",
        default=None,
        metavar="DEG,...",
        help="yaml, mcap: the arm's current joint positions [deg, one per joint]: the file "
        "first moves from there to the plan's start (rest to rest, at most half the speed "
        "and acceleration limits, at least 1 s)",
    )
    add_json_args(p, out=False)
    p.set_defaults(handler=cmd_export)
