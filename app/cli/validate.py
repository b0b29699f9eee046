"""``bioplan validate``: the torques a robot model predicts for a logged motion, and the log's."""

from __future__ import annotations

import argparse
from typing import Any

from app.cli._common import add_json_args, add_robot_flag, emit, load_robot, positive


def add_log_robot_args(p: argparse.ArgumentParser) -> None:
    """--robot, --mjcf, --payload and the onboarding options (--lock, --sidecar, roles)."""
    add_robot_flag(p, required=True)
    p.add_argument(
        "--lock",
        action="append",
        default=[],
        metavar="JOINT=VALUE",
        help="hold a joint fixed, degrees (metres for prismatic joints); repeatable; the log "
        "then needs only the free joints (default: none)",
    )
    p.add_argument(
        "--sidecar",
        default=None,
        help="robot sidecar YAML: motors (currents to torque), friction, identified links, payload "
        "(docs/robots.md; default: none)",
    )
    p.add_argument(
        "--payload", type=float, default=None, help="payload mass [kg] (default: the robot's)"
    )
    p.add_argument(
        "--topic",
        default=None,
        help="JointState topic of a ROS 2 bag (default: the only one, else /joint_states)",
    )
    p.add_argument(
        "--cutoff-hz",
        type=float,
        default=None,
        help="zero-phase Butterworth low-pass cutoff of positions, speeds and torques [Hz] "
        "(default: 10)",
    )


def cmd_validate(args: argparse.Namespace) -> int:
    from app.planning.identification import DEFAULT_CUTOFF_HZ
    from app.planning.validation import (
        ValidateOptions,
        plot_validation,
        summary_lines,
        validate,
    )
    from app.recordings.robot_logs import read_robot_log

    cutoff = positive("cutoff-hz", args.cutoff_hz) if args.cutoff_hz is not None else None
    robot = load_robot(args)
    log = read_robot_log(args.log, topic=args.topic)
    options = ValidateOptions(cutoff_hz=cutoff if cutoff is not None else DEFAULT_CUTOFF_HZ)
    validation = validate(robot, log, options=options, plan=args.plan)
    payload: dict[str, Any] = validation.result
    if args.plot:
        payload["plots"] = [str(p) for p in plot_validation(validation, args.plot)]
    lines = summary_lines(payload, robot.joint_names)
    if "plan" in payload:
        plan = payload["plan"]
        lines.append(
            f"plan: tracks '{plan['method']}', starts at {plan['time_shift_s']:.4g} s in the log"
        )
        saving = plan.get("saving_pct")
        if saving and saving.get("planned") is not None:
            lines.append(
                f"saving vs quintic: planned {saving['planned']:.1f} %, measured "
                f"{saving['measured']:.1f} %"
            )
    lines += [f"note: {note}" for note in payload["log"]["notes"]]
    emit(args, payload, "\n".join(lines))
    return 0


def register(sub: Any) -> None:
    """Add ``validate`` to the ``bioplan`` subcommands."""
    p = sub.add_parser(
        "validate",
        help="measured vs predicted joint torque of a robot log (ROS 2 bag, UR CSV, CSV)",
    )
    add_log_robot_args(p)
    p.add_argument(
        "--log",
        required=True,
        help="robot log: ROS 2 bag (folder, .mcap or .db3) of JointState, UR RTDE CSV, or CSV "
        "with time and <joint>/position, <joint>/velocity (optional), <joint>/effort",
    )
    p.add_argument(
        "--plan",
        default=None,
        help="a `bioplan plan --json --out` result the log executed: "
        "aligned in time, tracking error and savings (default: none)",
    )
    p.add_argument("--plot", default=None, metavar="DIR", help="write plotly HTML plots here")
    add_json_args(p)
    p.set_defaults(handler=cmd_validate)
