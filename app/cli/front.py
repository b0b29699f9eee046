"""``bioplan front`` and ``bioplan throughput``: trade-offs by optimal control.

``front`` draws the Pareto front between two metrics (or a metric and the duration) of the
task, each point an epsilon-constraint optimum converged on the mesh; ``throughput`` finds the
motion duration inside a production cycle that minimises a metric per cycle
(:mod:`app.planning.front`; docs/planning.md, "Trade-offs").
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from app.cli._common import (
    DURATION_HELP,
    CliError,
    add_json_args,
    add_robot_args,
    duration,
    emit,
    load_robot,
    load_template,
    progress_printer,
    task_from_args,
)
from app.names import FRONT_AXES, OPTIMAL_INTERVALS

#: The axes of a front (the metrics and the duration).
AXES = FRONT_AXES
METHOD_CHOICES = ("bound", "human_optimal")
#: The transcription's coarsest mesh (``app.planning.optimal.DEFAULT_INTERVALS``).
DEFAULT_INTERVALS = OPTIMAL_INTERVALS
#: ``--duration``'s help: none by default, which is 1 s unless duration is an axis.
FRONT_DURATION_HELP = DURATION_HELP + " (default: 1 s; none when duration is an axis)"
#: Refinement stops below this relative change (``app.planning.methods.CONVERGENCE_TOLERANCE``).
DEFAULT_TOLERANCE = 1e-3


def add_front_args(p: argparse.ArgumentParser) -> None:
    """--objectives, --points, --max-duration and the method options (``bioplan front``'s own,
    shared with ``bioplan submit front``)."""
    p.add_argument(
        "--objectives",
        required=True,
        help="A,B: minimise A with B <= epsilon; two of " + ", ".join(AXES),
    )
    p.add_argument("--points", type=int, default=9, help="points of the front, ends included")
    p.add_argument(
        "--max-duration",
        type=float,
        default=None,
        help="the duration axis' longest duration [s] (default: 3 x the shortest feasible)",
    )
    add_method_args(p)


def _add_common(p: argparse.ArgumentParser) -> None:
    add_method_args(p)
    add_json_args(p)


def add_method_args(p: argparse.ArgumentParser) -> None:
    """--method, --template, --intervals, --tolerance, --allow-reversal."""
    p.add_argument(
        "--method",
        choices=METHOD_CHOICES,
        default="bound",
        help="bound: the limits only; human_optimal: also the elbow's human-like speed peak",
    )
    p.add_argument("--template", default=None, help="HumanTemplate JSON from `bioplan analyze`")
    p.add_argument(
        "--intervals",
        type=int,
        default=DEFAULT_INTERVALS,
        help="coarsest constant-jerk mesh; every point is refined from it to convergence",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        default=DEFAULT_TOLERANCE,
        help="mesh refinement stops when the objective changes by less than this fraction",
    )
    p.add_argument(
        "--allow-reversal",
        action="store_true",
        help="let joints move against their stroke (default: no joint reverses)",
    )


def _intervals(value: int) -> int:
    if value < 8:
        raise CliError(f"--intervals must be >= 8, got {value}")
    return value


def check_front_args(args: argparse.Namespace) -> tuple[str, str]:
    """The two axes (A, B) of ``--objectives``, after checking the front's options together.

    Raises:
        BioPlanError: a bad axis, the same axis twice, a bad --points, --method, --duration,
            --max-duration or --intervals; the message names the option.
    """
    from app.planning.front import check_front_options

    a, b = check_front_options(
        args.objectives, points=args.points, method=args.method, duration=args.duration
    )
    if args.duration is not None:
        duration("duration", args.duration)
    if args.max_duration is not None:
        if "duration" not in (a, b):
            raise CliError("--max-duration given but duration is not an axis of --objectives")
        duration("max-duration", args.max_duration)
    _intervals(args.intervals)
    return a, b


def cmd_front(args: argparse.Namespace) -> int:
    from app.planning.front import pareto_front

    a, b = check_front_args(args)
    robot = load_robot(args)
    front = pareto_front(
        robot,
        task_from_args(args, robot),
        objectives=(a, b),
        duration=args.duration,
        method=args.method,
        points=args.points,
        template=load_template(args.template),
        n_intervals=_intervals(args.intervals),
        no_reversal=not args.allow_reversal,
        max_duration=args.max_duration,
        tolerance=args.tolerance,
        progress=progress_printer(not args.json),
    )
    payload = front.to_dict()
    emit(args, payload, _front_text(payload))
    return 0


def _number(value: Any) -> str:
    return (
        "-" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.5g}"
    )


def _front_text(d: dict[str, Any]) -> str:
    a, b = d["objectives"]
    lines = [
        f"{d['method']} front of {d['robot']} ({d['payload_mass']:g} kg): minimise {a} with "
        f"{b} <= epsilon" + ("" if d["duration"] is None else f", {d['duration']:g} s"),
        f"rules: {', '.join(d['rules'])}",
        f"{'point':<6} {a:>14} {b:>14} {'likeness':>9}  converged at",
    ]
    for p in d["points"]:
        conv = p["convergence"]
        mark = " knee" if p["knee"] else (f" {p['end']}" if p["end"] else "")
        lines.append(
            f"{p['id']:<6} {_number(p[a]):>14} {_number(p[b]):>14} "
            f"{_number(p['human_likeness']):>9}  {conv['final_intervals']} intervals "
            f"({100 * conv['relative_change']:.2f} %){mark}"
            if conv["relative_change"] is not None
            else f"{p['id']:<6} {_number(p[a]):>14} {_number(p[b]):>14}{mark}"
        )
    if d["shortest_duration"]:
        s = d["shortest_duration"]
        lines.append(
            f"shortest feasible duration {s['duration']:.4f} s ({s['infeasible_below']:.4f} s "
            "is not)"
        )
    for drop in d["dropped"]:
        lines.append(f"dropped: {drop['why']}")
    lines += d["notes"]
    lines.append(f"{d['solves']} solves, {d['seconds']:.1f} s")
    return "\n".join(lines)


def cmd_throughput(args: argparse.Namespace) -> int:
    from app.planning.front import FRONT_METRICS, throughput

    if args.objective not in FRONT_METRICS:
        raise CliError(
            f"--objective {args.objective!r}: expected one of {', '.join(FRONT_METRICS)}"
        )
    if args.duration is not None:
        raise CliError(
            "--duration given: throughput chooses the motion's duration inside the cycle "
            "(expected --cycle-rate and --dwell only)"
        )
    robot = load_robot(args)
    result = throughput(
        robot,
        task_from_args(args, robot),
        objective=args.objective,
        cycle_rate=args.cycle_rate,
        dwell=args.dwell,
        method=args.method,
        template=load_template(args.template),
        points=args.points,
        n_intervals=_intervals(args.intervals),
        no_reversal=not args.allow_reversal,
        tolerance=args.tolerance,
    )
    payload = result.to_dict()
    text = (
        f"{args.cycle_rate:g} lifts/h ({payload['cycle']:.3g} s cycle, dwell {args.dwell:g} s): "
        f"{args.method} {args.objective} per cycle is lowest with a {payload['duration']:.3f} s "
        f"motion: {payload['per_cycle']:.5g} (motion {payload['motion']:.5g}); the quintic in "
        f"{payload['quintic_duration']:.3f} s: {payload['quintic_per_cycle']:.5g}; saving "
        f"{payload['saving_pct']:.1f} %\n{payload['hold_model']}"
    )
    emit(args, payload, text)
    return 0


def register(sub: Any) -> None:
    """Add ``front`` and ``throughput`` to the ``bioplan`` subcommands."""
    p = sub.add_parser("front", help="the Pareto front between two metrics (or the duration)")
    add_robot_args(p)
    p.set_defaults(duration=None)
    for action in p._actions:
        if "--duration" in action.option_strings:
            action.help = FRONT_DURATION_HELP
    add_front_args(p)
    add_json_args(p)
    p.set_defaults(handler=cmd_front)

    p = sub.add_parser(
        "throughput", help="the motion duration inside a production cycle with the lowest metric"
    )
    add_robot_args(p)
    p.set_defaults(duration=None)
    for action in p._actions:
        if "--duration" in action.option_strings:
            action.help = argparse.SUPPRESS  # refused: throughput chooses the duration
    p.add_argument("--objective", default="electrical_energy", help="the metric per cycle")
    p.add_argument(
        "--cycle-rate", type=float, required=True, help="lifts per hour (one motion per cycle)"
    )
    p.add_argument(
        "--dwell",
        type=float,
        default=0.0,
        help="least time per cycle the arm holds still at the goal [s]",
    )
    p.add_argument("--points", type=int, default=5, help="motion durations scanned")
    _add_common(p)
    p.set_defaults(handler=cmd_throughput)
