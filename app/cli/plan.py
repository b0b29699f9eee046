"""``bioplan plan`` and ``bioplan profiles``: plan a task and compare trajectories on it."""

from __future__ import annotations

import argparse
from typing import Any

from app.cli._common import (
    add_export_args,
    add_robot_args,
    attach_motion,
    emit,
    load_robot,
    load_template,
    metrics_table,
    positive,
    progress_printer,
    task_from_args,
)
from app.names import OBJECTIVES, PSO_DEFAULTS
from app.planning.jsonsafe import json_safe


def cmd_plan(args: argparse.Namespace) -> int:
    from app.planning.planner import plan

    positive("duration", args.duration)
    robot = load_robot(args)
    result = plan(
        robot,
        task=task_from_args(args, robot),
        duration=args.duration,
        objective=args.objective,
        template=load_template(args.template),
        seed=args.seed,
        particles=args.particles,
        iterations=args.iterations,
        peak_angle_deg=args.peak_angle_deg,
        progress=progress_printer(not args.json),
    )
    payload = json_safe(result.to_dict())
    attach_motion(args, robot, result, payload)
    emit(args, payload, _plan_text(robot, args, payload))
    return 0


def _plan_text(robot: Any, args: argparse.Namespace, payload: dict[str, Any]) -> str:
    imp = payload["improvement_pct"]
    opt = payload["optimizer"]
    return "\n".join(
        [
            f"robot {robot.name}, payload {robot.payload.mass:g} kg, duration {args.duration:g} s, "
            f"objective {args.objective}",
            metrics_table(
                [
                    ("standard quintic", payload["standard"]),
                    ("bio-optimized", payload["optimized"]),
                ],
                payload["floors"],
            ),
            "change (positive = optimized saves): "
            + ", ".join(
                f"{k} {v:+.1f}%" for k, v in imp.items() if isinstance(v, float | int) and v == v
            ),
            f"elbow velocity peak at {payload['peak_velocity_angle_deg']:.1f} deg "
            f"(target {payload['target_peak_velocity_angle_deg']:.1f} deg); PSO "
            f"{opt['iterations']} iterations, {opt['evaluations']} evaluations, "
            f"{opt['seconds']:.2f} s, seed {opt['seed']}",
            *(
                ["electrical_energy: not modelled (no motor model: give --sidecar with motors)"]
                if not robot.motors_modelled
                else []
            ),
            *(
                [f"trajectory ({args.export_method}) written to {args.export}"]
                if args.export
                else []
            ),
            *[f"warning: {w}" for w in payload["warnings"]],
        ]
    )


def cmd_profiles(args: argparse.Namespace) -> int:
    from app.planning.comparison import compare_profiles

    positive("duration", args.duration)
    robot = load_robot(args)
    payload = json_safe(
        compare_profiles(robot, task=task_from_args(args, robot), duration=args.duration).to_dict()
    )
    rows = [(name, m) for name, m in payload["profiles"].items()]
    text = (
        f"robot {robot.name}, payload {robot.payload.mass:g} kg, duration {args.duration:g} s\n"
        + metrics_table(rows, payload["floors"])
    )
    emit(args, payload, text)
    return 0


def register(sub: Any) -> None:
    """Add ``plan`` and ``profiles`` to the ``bioplan`` subcommands."""
    p = sub.add_parser("plan", help="plan the standard and the bio-inspired trajectory")
    add_robot_args(p)
    p.add_argument("--objective", default="abs_work", help="one of " + ", ".join(OBJECTIVES))
    p.add_argument(
        "--peak-angle-deg",
        type=float,
        default=None,
        help="elbow velocity-peak angle [deg] (default: the template's)",
    )
    p.add_argument("--template", default=None, help="HumanTemplate JSON from `bioplan analyze`")
    add_export_args(p)
    p.add_argument("--seed", type=int, default=PSO_DEFAULTS.seed, help="PSO seed")
    p.add_argument("--particles", type=int, default=PSO_DEFAULTS.particles, help="PSO swarm size")
    p.add_argument(
        "--iterations", type=int, default=PSO_DEFAULTS.iterations, help="PSO iterations (at most)"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--out", default=None, help="also write the JSON to this file")
    p.set_defaults(handler=cmd_plan)

    p = sub.add_parser("profiles", help="metrics of the classical profiles on the same task")
    add_robot_args(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--out", default=None, help="also write the JSON to this file")
    p.set_defaults(handler=cmd_profiles)
