"""``bioplan simulate`` and ``bioplan sweep``: planned trajectories tracked in MuJoCo."""

from __future__ import annotations

import argparse
from typing import Any

from app.cli._common import (
    DURATION_HELP,
    CliError,
    add_export_args,
    add_robot_args,
    attach_motion,
    duration,
    emit,
    floats,
    load_robot,
    load_template,
    positive,
    progress_printer,
    task_from_args,
)
from app.cli.plan import add_method_args, add_pso_args
from app.jsonsafe import json_safe
from app.names import OBJECTIVES, PSO_DEFAULTS, STANDARD_METHODS


def cmd_simulate(args: argparse.Namespace) -> int:
    from app.simulation import simulate_comparison

    duration("duration", args.duration)
    robot = load_robot(args)
    result = simulate_comparison(
        robot,
        task=task_from_args(args, robot),
        duration=args.duration,
        objective=args.objective,
        template=load_template(args.template),
        seed=args.seed,
        particles=args.particles,
        iterations=args.iterations,
        peak_angle_deg=args.peak_angle_deg,
        methods=args.method.split(","),
        human_constraint=args.human_constraint,
        timestep=positive("timestep-ms", args.timestep_ms) / 1000.0,
        progress=progress_printer(not args.json),
    )
    payload = json_safe(result.to_dict())
    attach_motion(args, robot, result.plan, payload)
    emit(args, payload, result.summary())
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    from app.planning.robots import load_robot as load
    from app.simulation import run_sweep

    durations = [duration("durations", d) for d in floats(args.durations, "durations")]
    payloads = floats(args.payloads, "payloads")
    if any(p < 0 for p in payloads):
        raise CliError("--payloads must not be negative")
    robot = load(args.robot, mjcf=args.mjcf)
    result = run_sweep(
        robot=robot,
        durations=durations,
        payloads=payloads,
        objectives=args.objectives.split(","),
        seed=args.seed,
        particles=args.particles,
        iterations=args.iterations,
        methods=args.method.split(","),
        check_seed=None if args.no_check else args.check_seed,
        seeds=args.seeds,
        converge=args.converge,
        workers=args.workers,
        executor=args.executor,
        progress=progress_printer(not args.json),
    )
    emit(args, json_safe(result.to_dict()), result.summary())
    return 0


def register(sub: Any) -> None:
    """Add ``simulate`` and ``sweep`` to the ``bioplan`` subcommands."""
    from app.simulation.sweep import SWEEP_ITERATIONS, SWEEP_PARTICLES, SWEEP_SEEDS

    p = sub.add_parser("simulate", help="plan, then simulate every method in MuJoCo")
    add_robot_args(p)
    add_pso_args(p)
    add_method_args(p, transcription=False)
    p.add_argument("--timestep-ms", type=float, default=1.0, help="MuJoCo time step [ms]")
    add_export_args(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--out", default=None, help="also write the JSON to this file")
    p.set_defaults(handler=cmd_simulate)

    p = sub.add_parser("sweep", help="savings over a grid of durations and payloads")
    p.add_argument("--robot", default="curtain_wall_6dof", help="built-in robot name or URDF")
    p.add_argument("--mjcf", default=None, help="MJCF file matching a URDF given by path")
    p.add_argument(
        "--durations",
        default="0.5,0.75,1.0,1.5,2.0",
        help=f"comma-separated motion times; each {DURATION_HELP.removeprefix('motion time ')}",
    )
    p.add_argument("--payloads", default="0,4,8,12,20", help="comma-separated [kg]")
    p.add_argument(
        "--objectives", default="abs_work", help="comma-separated, of " + ", ".join(OBJECTIVES)
    )
    p.add_argument(
        "--method", default=",".join(STANDARD_METHODS), help="comma-separated methods per cell"
    )
    p.add_argument("--seed", type=int, default=PSO_DEFAULTS.seed, help="PSO seed")
    p.add_argument(
        "--check-seed",
        type=int,
        default=-1,
        help="first check seed of the paper's PSO (-1: seed + 1; the others follow it)",
    )
    p.add_argument(
        "--seeds",
        type=int,
        default=SWEEP_SEEDS,
        help="seeds the paper's PSO runs with per cell (the cell's --seed and the check seeds); "
        "a verdict is certain only when all agree, otherwise marked '?' with its spread",
    )
    p.add_argument("--no-check", action="store_true", help="skip the convergence check (one seed)")
    p.add_argument(
        "--converge",
        action="store_true",
        help="refine every optimal-control result until its objective changes by less than "
        "0.1 %% (several times slower; docs/planning.md)",
    )
    p.add_argument("--particles", type=int, default=SWEEP_PARTICLES, help="PSO swarm per cell")
    p.add_argument("--iterations", type=int, default=SWEEP_ITERATIONS, help="PSO iterations")
    p.add_argument("--workers", type=int, default=None, help="processes (default: up to 2)")
    p.add_argument(
        "--executor",
        default="local",
        help="where the cells run: local (a pool of --workers processes) or dask://HOST:PORT "
        "(one task per cell on that Dask scheduler's workers)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--out", default=None, help="also write the JSON to this file")
    p.set_defaults(handler=cmd_sweep)
