"""``bioplan plan`` and ``bioplan profiles``: plan a task and compare trajectories on it."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence
from typing import Any

from app.cli._common import (
    OptionsT,
    add_export_args,
    add_json_args,
    add_options,
    add_robot_args,
    attach_motion,
    duration,
    emit,
    load_robot,
    load_template,
    metrics_table,
    options_from_args,
    progress_printer,
    task_from_args,
)
from app.jsonsafe import json_safe
from app.names import METHODS, STANDARD_METHODS
from app.planning.options import PlanOptions
from app.planning.safety import safety_summary


def add_plan_options(
    p: argparse.ArgumentParser, cls: type = PlanOptions, *, exclude: Sequence[str] = ()
) -> None:
    """The options of ``cls`` (``PlanOptions`` for ``plan``; ``SimulationOptions`` for
    ``simulate``), each built from its field, and --template (a file, read here)."""
    add_options(p, cls, exclude=exclude)
    p.add_argument("--template", default=None, help="HumanTemplate JSON from `bioplan analyze`")


def run_on_task(
    args: argparse.Namespace, cls: type[OptionsT], run: Callable[..., Any]
) -> tuple[Any, Any]:
    """The robot of the flags and ``run`` on its task: ``run(robot, options, task=, template=,
    progress=)`` (``plan`` or ``simulate_comparison``) with options ``cls`` from the flags.

    Returns:
        (robot, the result of ``run``).
    """
    robot = load_robot(args)
    result = run(
        robot,
        options_from_args(cls, args),
        task=task_from_args(args, robot),
        template=load_template(args.template),
        progress=progress_printer(not args.json),
    )
    return robot, result


def cmd_plan(args: argparse.Namespace) -> int:
    from app.planning.planner import plan

    duration("duration", args.duration)
    robot, result = run_on_task(args, PlanOptions, plan)
    payload = json_safe(result.to_dict())
    attach_motion(args, robot, result, payload)
    emit(args, payload, _plan_text(robot, args, payload))
    return 0


def _solver_line(name: str, solver: dict[str, Any] | None) -> str | None:
    if not solver:
        return None
    if solver.get("kind") == "pso":
        return (
            f"{name}: PSO {solver['iterations']} iterations, {solver['evaluations']} "
            f"evaluations, seed {solver['seed']}"
        )
    if solver.get("kind") == "ipopt":
        return (
            f"{name}: IPOPT {solver['status']} in {solver['iterations']} iterations, "
            f"{solver['seconds']:.2f} s, {solver['n_intervals']} intervals, warm start "
            f"{solver['warm_start']}, human constraint {solver['human_constraint']}"
            + _convergence_text(solver.get("convergence"))
        )
    return f"{name}: ruckig time-synchronised jerk-limited profile"


def _convergence_text(conv: dict[str, Any] | None) -> str:
    """The mesh-refinement evidence of one optimal-control result ('' without --converge)."""
    if not conv:
        return ""
    steps = " -> ".join(
        f"{s['n_intervals']}: {s['objective']:.6g}" if s.get("objective") is not None
        else f"{s['n_intervals']}: failed"
        for s in conv["sequence"]
    )  # fmt: skip
    # Results made before the Richardson estimate have only the last relative change.
    error = ""
    if "error_estimate" in conv:
        how = "Richardson" if conv.get("extrapolated") else "the last change"
        error = f", error estimate {_percent(conv['error_estimate'])} ({how})"
    state = "converged" if conv.get("converged") else "NOT converged"
    return (
        f"\n  mesh refinement (intervals: objective) {steps}; relative change "
        f"{_percent(conv.get('relative_change'))}{error}, {state} (tolerance "
        f"{100 * conv['tolerance']:g} %), final mesh {conv['final_intervals']} intervals"
    )


def _percent(fraction: float | None) -> str:
    """A relative value [-] in percent, 'n/a' when there is none (NaN becomes None in JSON)."""
    if fraction is None or not math.isfinite(fraction):
        return "n/a"
    return f"{100 * fraction:.3g} %"


def _plan_text(robot: Any, args: argparse.Namespace, payload: dict[str, Any]) -> str:
    methods = payload["methods"]
    shares = payload["share_of_achievable_pct"]
    lines = [
        f"robot {robot.name}, payload {robot.payload.mass:g} kg, duration {args.duration:g} s, "
        f"objective {args.objective}",
        "methods: " + "; ".join(f"{n} = {METHODS[n].label}" for n in methods),
        metrics_table(list(methods.items()), payload["floors"]),
    ]
    task = payload.get("task") or {}
    if "delta_pe_j" in task:
        lines.append(
            f"task: {'lifts' if task['lifts'] else 'lowers'} the robot and payload "
            f"(ΔPE {task['delta_pe_j']:+.2f} J)"
        )
    failed = payload.get("method_errors") or {}
    if failed:  # each method's own error is among the warnings below
        lines.append(
            "failed: " + "; ".join(f"{n} ({f['kind']}, see warnings)" for n, f in failed.items())
        )
    for name, m in methods.items():
        lo, hi = m["peak_velocity_span_deg"]
        if lo is not None and hi is not None and abs(hi - lo) > 1.0:
            lines.append(
                f"{name}: the elbow holds its top speed from {lo:.1f} to {hi:.1f} deg "
                "(v-peak angle: where it first reaches it)"
            )
    for name, m in methods.items():
        if name == "quintic":
            continue
        change = m["improvement_pct"].get(args.objective)
        share = shares.get(name)
        text = f"{METHODS[name].label}: {args.objective} "
        if isinstance(change, list):  # per joint; None where the quintic's is 0 (no ratio)
            defined = [c for c in change if c is not None]
            change = max(defined, key=abs) if defined else None
        text += f"{change:+.1f}% vs the quintic" if change is not None else "(no change)"
        if share is not None and name != "bound":
            text += f", {share:.0f}% of the achievable saving"
        lines.append(text)
    if not shares:
        lines.append("share of the achievable saving: needs the bound (--method ...,bound)")
    lines.append(
        f"target elbow velocity peak {payload['target_peak_velocity_angle_deg']:.1f} deg; "
        "positive change = the method saves"
    )
    lines += [
        line for n, m in methods.items() if (line := _solver_line(n, m.get("solver"))) is not None
    ]
    if payload.get("optimizer"):
        lines.append(f"PSO time {payload['optimizer']['seconds']:.2f} s")
    if not robot.motors_modelled:
        lines.append("electrical_energy: not modelled (no motor model: give --sidecar with motors)")
    if args.export:
        method = args.export_method or payload["motion"]["default_method"]
        lines.append(f"trajectory ({method}) written to {args.export}")
    lines.append(f"safety: {safety_summary(payload.get('safety'))}")
    lines += [f"warning: {w}" for w in payload["warnings"]]
    return "\n".join(lines)


def cmd_profiles(args: argparse.Namespace) -> int:
    from app.planning.comparison import compare_profiles
    from app.planning.planner import plan

    duration("duration", args.duration)
    robot = load_robot(args)
    task = task_from_args(args, robot)
    result = compare_profiles(
        robot,
        task=task,
        duration=args.duration,
        include_min_torque_change=not args.no_min_torque_change,
        mtc_intervals=args.mtc_intervals,
    )
    payload = json_safe(result.to_dict())
    rows = [(name, m) for name, m in payload["profiles"].items()]
    if args.method != "none":
        # --objective and --seed are plan's (PlanOptions'); --method may say none.
        options = options_from_args(PlanOptions, args)
        planned = plan(
            robot,
            options,
            task=task,
            methods=args.method.split(","),
            progress=progress_printer(not args.json),
        ).to_dict()
        payload["objective"] = args.objective
        payload["methods"] = planned["methods"]
        payload["share_of_achievable_pct"] = planned["share_of_achievable_pct"]
        rows += [(f"method {name}", m) for name, m in planned["methods"].items()]
    text = (
        f"robot {robot.name}, payload {robot.payload.mass:g} kg, duration {args.duration:g} s\n"
        + metrics_table(rows, payload["floors"])
    )
    mtc = payload.get("min_torque_change_solver")
    if mtc and mtc["objective"] is not None and math.isfinite(mtc["objective"]):
        text += (
            f"\nminimum torque change within the joint limits: J = ∫Σ τ̇² dt = "
            f"{mtc['objective']:.5g} N²m²/s (IPOPT {mtc['status']}, {mtc['n_intervals']} intervals)"
        )
    emit(args, json_safe(payload), text)
    return 0


def register(sub: Any) -> None:
    """Add ``plan`` and ``profiles`` to the ``bioplan`` subcommands."""
    p = sub.add_parser("plan", help="plan the task with every method and compare them")
    add_robot_args(p)
    add_plan_options(p)
    add_export_args(p)
    add_json_args(p)
    p.set_defaults(handler=cmd_plan)

    p = sub.add_parser("profiles", help="metrics of the classical profiles on the same task")
    add_robot_args(p)
    p.add_argument(
        "--mtc-intervals",
        type=int,
        default=100,
        help="constant-jerk intervals of the minimum-torque-change solve",
    )
    p.add_argument(
        "--no-min-torque-change",
        action="store_true",
        help="skip the minimum-torque-change baseline",
    )
    p.add_argument(
        "--method",
        default=",".join(STANDARD_METHODS),
        help="planning methods to list beside the profiles, comma-separated, or none",
    )
    add_options(p, PlanOptions, only=("objective", "seed"))
    add_json_args(p)
    p.set_defaults(handler=cmd_profiles)
