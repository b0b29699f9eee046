"""``bioplan simulate`` and ``bioplan sweep``: planned trajectories tracked in MuJoCo."""

from __future__ import annotations

import argparse
from typing import Any

from app.cli._common import (
    CliError,
    add_export_args,
    add_robot_args,
    attach_motion,
    emit,
    floats,
    load_robot,
    positive,
    progress_printer,
    task_from_args,
)
from app.names import OBJECTIVES, PSO_DEFAULTS
from app.planning.jsonsafe import json_safe


def cmd_simulate(args: argparse.Namespace) -> int:
    from app.simulation import simulate_comparison

    positive("duration", args.duration)
    robot = load_robot(args)
    result = simulate_comparison(
        robot,
        task=task_from_args(args, robot),
        duration=args.duration,
        objective=args.objective,
        seed=args.seed,
        progress=progress_printer(not args.json),
    )
    payload = json_safe(result.to_dict())
    attach_motion(args, robot, result.plan, payload)
    emit(args, payload, result.summary())
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    from app.planning.robots import load_robot as load
    from app.simulation import run_sweep

    durations = [positive("durations", d) for d in floats(args.durations, "durations")]
    payloads = floats(args.payloads, "payloads")
    if any(p < 0 for p in payloads):
        raise CliError("--payloads must not be negative")
    robot = load(args.robot)
    result = run_sweep(
        robot=robot,
        durations=durations,
        payloads=payloads,
        objectives=args.objectives.split(","),
        seed=args.seed,
        progress=progress_printer(not args.json),
    )
    emit(args, json_safe(result.to_dict()), result.summary())
    return 0


def register(sub: Any) -> None:
    """Add ``simulate`` and ``sweep`` to the ``bioplan`` subcommands."""
    p = sub.add_parser("simulate", help="plan, then simulate both trajectories in MuJoCo")
    add_robot_args(p)
    p.add_argument("--objective", default="abs_work", help="one of " + ", ".join(OBJECTIVES))
    p.add_argument("--seed", type=int, default=PSO_DEFAULTS.seed, help="PSO seed")
    add_export_args(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--out", default=None, help="also write the JSON to this file")
    p.set_defaults(handler=cmd_simulate)

    p = sub.add_parser("sweep", help="savings over a grid of durations and payloads")
    p.add_argument("--robot", default="curtain_wall_6dof", help="built-in robot name or URDF")
    p.add_argument("--durations", default="0.5,0.75,1.0,1.5,2.0", help="comma-separated [s]")
    p.add_argument("--payloads", default="0,4,8,12,20", help="comma-separated [kg]")
    p.add_argument("--objectives", default="abs_work", help="comma-separated metric names")
    p.add_argument("--seed", type=int, default=PSO_DEFAULTS.seed, help="PSO seed")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--out", default=None, help="also write the JSON to this file")
    p.set_defaults(handler=cmd_sweep)
