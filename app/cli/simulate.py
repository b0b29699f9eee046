"""``bioplan simulate`` and ``bioplan sweep``: planned trajectories tracked in MuJoCo."""

from __future__ import annotations

import argparse
from typing import Any

from app.cli._common import (
    CliError,
    add_export_args,
    add_json_args,
    add_options,
    add_robot_args,
    attach_motion,
    duration,
    emit,
    floats,
    options_from_args,
    positive,
    progress_printer,
)
from app.cli.plan import add_plan_options, run_on_task
from app.jsonsafe import json_safe


def cmd_simulate(args: argparse.Namespace) -> int:
    from app.simulation import simulate_comparison
    from app.simulation.options import SimulationOptions

    duration("duration", args.duration)
    positive("timestep-ms", args.timestep)  # the flag's own words before the range check
    robot, result = run_on_task(args, SimulationOptions, simulate_comparison)
    payload = json_safe(result.to_dict())
    attach_motion(args, robot, result.plan, payload)
    emit(args, payload, result.summary())
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    from app.planning.robots import load_robot as load
    from app.simulation import run_sweep
    from app.simulation.options import SweepGrid

    for d in floats(args.durations, "durations"):  # the flag's own words, as the API's cap
        duration("durations", d)
    if any(p < 0 for p in floats(args.payloads, "payloads")):
        raise CliError("--payloads must not be negative")
    grid = options_from_args(SweepGrid, args)
    robot = load(args.robot, mjcf=args.mjcf)
    result = run_sweep(
        robot=robot,
        grid=grid,
        workers=args.workers,
        executor=args.executor,
        progress=progress_printer(not args.json),
    )
    emit(args, json_safe(result.to_dict()), result.summary())
    return 0


def register(sub: Any) -> None:
    """Add ``simulate`` and ``sweep`` to the ``bioplan`` subcommands."""
    from app.simulation.options import SimulationOptions, SweepGrid

    p = sub.add_parser("simulate", help="plan, then simulate every method in MuJoCo")
    add_robot_args(p)
    # The optimal-control transcription's options are the API's and plan's, not simulate's flags.
    add_plan_options(p, SimulationOptions, exclude=("no_reversal", "n_intervals", "converge"))
    add_export_args(p)
    add_json_args(p)
    p.set_defaults(handler=cmd_simulate)

    p = sub.add_parser("sweep", help="savings over a grid of durations and payloads")
    p.add_argument("--robot", default="curtain_wall_6dof", help="built-in robot name or URDF")
    p.add_argument("--mjcf", default=None, help="MJCF file matching a URDF given by path")
    add_options(p, SweepGrid)
    p.add_argument("--workers", type=int, default=None, help="processes (default: up to 2)")
    p.add_argument(
        "--executor",
        default="local",
        help="where the cells run: local (a pool of --workers processes) or dask://HOST:PORT "
        "(one task per cell on that Dask scheduler's workers)",
    )
    add_json_args(p)
    p.set_defaults(handler=cmd_sweep)
