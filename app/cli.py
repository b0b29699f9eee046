"""The ``bioplan`` command (CLI contract in DESIGN.md).

Every subcommand imports what it needs inside its handler, so ``bioplan plan`` does not pay for
scipy.signal, MuJoCo or the web stack. With ``--json`` a command prints exactly one JSON object on
stdout. Bad input gives a one-line error on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

from app.planning.jsonsafe import json_safe

EXIT_BAD_INPUT = 2


class CliError(Exception):
    """Bad input detected by the CLI itself."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage block), exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def _emit(args: argparse.Namespace, payload: dict[str, Any], text: str) -> None:
    """Print JSON or text, and write the JSON to ``--out`` when asked."""
    blob = json.dumps(payload, indent=2, allow_nan=False)
    out = getattr(args, "out", None)
    if out:
        Path(out).write_text(blob + "\n", encoding="utf-8")
    if getattr(args, "json", False):
        print(blob)
    else:
        print(text)


def _progress_printer(enabled: bool) -> Callable[[float, str], None] | None:
    """A progress line on stderr (never stdout, which carries the JSON)."""
    if not enabled or not sys.stderr.isatty():
        return None

    def show(fraction: float, message: str) -> None:
        bar = "#" * int(30 * fraction)
        print(f"\r[{bar:<30}] {100 * fraction:5.1f}% {message[:60]:<60}", end="", file=sys.stderr)
        if fraction >= 1.0:
            print(file=sys.stderr)

    return show


# ---------------------------------------------------------------------------------------------
# plan / profiles


def _load_robot(args: argparse.Namespace) -> Any:
    from app.planning.robots import load_robot

    return load_robot(args.robot, payload=args.payload, mjcf=getattr(args, "mjcf", None))


def _task(args: argparse.Namespace, robot: Any) -> Any:
    """The task from --start-deg/--goal-deg, each defaulting to the robot's curl task."""
    import numpy as np

    from app.planning.planner import PlanTask

    task = PlanTask.default(robot)
    start, goal = task.start, task.goal
    n = len(robot.joint_names)
    for flag, text, default in (
        ("start-deg", args.start_deg, start),
        ("goal-deg", args.goal_deg, goal),
    ):
        if text is None:
            continue
        values = _floats(text, flag)
        if len(values) != n:
            raise CliError(f"--{flag} needs {n} angles for {robot.name}, got {len(values)}")
        default[:] = np.radians(values)
    return PlanTask(start, goal)


def _positive(name: str, value: float) -> float:
    if not (math.isfinite(value) and value > 0):
        raise CliError(f"--{name} must be a positive number, got {value}")
    return value


def _load_template(path: str | None) -> Any:
    from app.planning.human_template import HumanTemplate

    if path is None:
        return None
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise CliError(f"{path}: cannot read template ({exc.strerror})") from exc
    try:
        return HumanTemplate.from_json(text)
    except (ValueError, TypeError) as exc:
        raise CliError(f"{path}: not a HumanTemplate JSON file: {exc}") from exc


def _metrics_table(rows: Sequence[tuple[str, dict[str, Any]]], floors: dict[str, float]) -> str:
    names = ["tau_sq", "abs_work", "pos_work", "electrical_energy", "peak_power"]
    units = {
        "tau_sq": "N²m²s",
        "abs_work": "J",
        "pos_work": "J",
        "electrical_energy": "J",
        "peak_power": "W",
    }
    header = f"{'profile':<20}" + "".join(f"{n:>19}" for n in names) + f"{'v-peak angle':>14}"
    lines = [header, " " * 20 + "".join(f"{'[' + units[n] + ']':>19}" for n in names)]
    for label, m in rows:
        cells = "".join(f"{m[n]:>19.4g}" for n in names)
        angle = m.get("peak_velocity_angle_deg")
        lines.append(f"{label:<20}{cells}{angle:>12.1f}°" if angle is not None else cells)
    lines.append(
        f"floors: delta_potential = {floors['delta_potential']:.4g} J, "
        f"min_peak_power = {floors['min_peak_power']:.4g} W"
    )
    return "\n".join(lines)


def cmd_plan(args: argparse.Namespace) -> int:
    from app.planning.planner import plan

    _positive("duration", args.duration)
    robot = _load_robot(args)
    result = plan(
        robot,
        task=_task(args, robot),
        duration=args.duration,
        objective=args.objective,
        template=_load_template(args.template),
        seed=args.seed,
        particles=args.particles,
        iterations=args.iterations,
        peak_angle_deg=args.peak_angle_deg,
        progress=_progress_printer(not args.json),
    )
    payload = json_safe(result.to_dict())
    imp = payload["improvement_pct"]
    text = "\n".join(
        [
            f"robot {robot.name}, payload {robot.payload.mass:g} kg, duration {args.duration:g} s, "
            f"objective {args.objective}",
            _metrics_table(
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
            f"{payload['optimizer']['iterations']} iterations, "
            f"{payload['optimizer']['evaluations']} evaluations, "
            f"{payload['optimizer']['seconds']:.2f} s, seed {payload['optimizer']['seed']}",
            *[f"warning: {w}" for w in payload["warnings"]],
        ]
    )
    _emit(args, payload, text)
    return 0


def cmd_profiles(args: argparse.Namespace) -> int:
    from app.planning.comparison import compare_profiles

    _positive("duration", args.duration)
    robot = _load_robot(args)
    payload = json_safe(
        compare_profiles(robot, task=_task(args, robot), duration=args.duration).to_dict()
    )
    rows = [(name, m) for name, m in payload["profiles"].items()]
    text = (
        f"robot {robot.name}, payload {robot.payload.mass:g} kg, duration {args.duration:g} s\n"
        + _metrics_table(rows, payload["floors"])
    )
    _emit(args, payload, text)
    return 0


# ---------------------------------------------------------------------------------------------
# analyze


def _muscle_map(pairs: Sequence[str] | None) -> dict[str, str] | None:
    if not pairs:
        return None
    out: dict[str, str] = {}
    for pair in pairs:
        label, sep, site = pair.partition("=")
        if not sep or not label or not site:
            raise CliError(f"--muscle expects LABEL=SITE (e.g. 'Biceps.EMG4=biceps'), got {pair!r}")
        out[label] = site
    return out


def cmd_analyze(args: argparse.Namespace) -> int:
    from app.analysis import analyze_files

    for f in args.files:
        if not Path(f).is_file():
            raise CliError(f"{f}: no such file")
    result = analyze_files(args.files, emg_rate=args.emg_rate, muscle_map=_muscle_map(args.muscle))
    payload = json_safe(result.to_dict())
    if args.plot:
        from app.analysis import write_analysis_plots

        paths = write_analysis_plots(result, Path(args.plot))
        payload["plots"] = [str(p) for p in paths]
    if args.out:
        Path(args.out).write_text(result.template.to_json() + "\n", encoding="utf-8")
    if args.json:
        print(json.dumps(payload, indent=2, allow_nan=False))
    else:
        print(result.summary())
        if args.plot:
            print(f"figures written to {args.plot}")
        if args.out:
            print(f"template written to {args.out}")
    return 0


# ---------------------------------------------------------------------------------------------
# simulate / sweep


def cmd_simulate(args: argparse.Namespace) -> int:
    from app.simulation import simulate_comparison

    _positive("duration", args.duration)
    robot = _load_robot(args)
    result = simulate_comparison(
        robot,
        duration=args.duration,
        objective=args.objective,
        seed=args.seed,
        progress=_progress_printer(not args.json),
    )
    payload = json_safe(result.to_dict())
    _emit(args, payload, result.summary())
    return 0


def _floats(text: str, name: str) -> list[float]:
    try:
        values = [float(v) for v in text.replace(",", " ").split()]
    except ValueError as exc:
        raise CliError(f"--{name} expects numbers separated by commas, got {text!r}") from exc
    if not values:
        raise CliError(f"--{name} is empty")
    return values


def cmd_sweep(args: argparse.Namespace) -> int:
    from app.planning.robots import load_robot
    from app.simulation import run_sweep

    durations = [_positive("durations", d) for d in _floats(args.durations, "durations")]
    payloads = _floats(args.payloads, "payloads")
    if any(p < 0 for p in payloads):
        raise CliError("--payloads must not be negative")
    robot = load_robot(args.robot)
    result = run_sweep(
        robot=robot,
        durations=durations,
        payloads=payloads,
        objectives=args.objectives.split(","),
        seed=args.seed,
        progress=_progress_printer(not args.json),
    )
    _emit(args, json_safe(result.to_dict()), result.summary())
    return 0


# ---------------------------------------------------------------------------------------------
# demo


def cmd_demo(args: argparse.Namespace) -> int:
    from app.simulation.report import write_demo_report

    out = Path(args.out_dir)
    index = write_demo_report(out, seed=args.seed, progress=_progress_printer(True))
    print(f"report written to {index}")
    return 0


# ---------------------------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="bioplan",
        description="Bio-inspired, energy-efficient trajectory planning from human lifting data.",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    def robot_args(p: argparse.ArgumentParser, *, payload_default: float | None = None) -> None:
        p.add_argument(
            "--robot",
            default="curtain_wall_6dof",
            help="built-in robot name (human_arm_2dof, curtain_wall_6dof) or a URDF path",
        )
        p.add_argument("--mjcf", default=None, help="MJCF file matching a URDF given by path")
        p.add_argument("--duration", type=float, default=1.0, help="motion time [s]")
        p.add_argument(
            "--payload",
            type=float,
            default=payload_default,
            help="payload mass [kg] (default: the robot's: 12 kg human, 4 kg curtain wall)",
        )
        p.add_argument("--start-deg", default=None, help="start joint angles, comma-separated")
        p.add_argument("--goal-deg", default=None, help="goal joint angles, comma-separated")

    from app.planning.energy import OBJECTIVES

    p = sub.add_parser("plan", help="plan the standard and the bio-inspired trajectory")
    robot_args(p)
    p.add_argument("--objective", default="abs_work", help="one of " + ", ".join(OBJECTIVES))
    p.add_argument("--peak-angle-deg", type=float, default=None, help="elbow velocity-peak angle")
    p.add_argument("--template", default=None, help="HumanTemplate JSON from `bioplan analyze`")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--particles", type=int, default=40)
    p.add_argument("--iterations", type=int, default=100)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--out", default=None, help="also write the JSON to this file")
    p.set_defaults(handler=cmd_plan)

    p = sub.add_parser("profiles", help="metrics of the classical profiles on the same task")
    robot_args(p)
    p.add_argument("--json", action="store_true")
    p.add_argument("--out", default=None)
    p.set_defaults(handler=cmd_profiles)

    p = sub.add_parser("analyze", help="analyse EMG and pose recordings into a human template")
    p.add_argument("files", nargs="+", help="recording files (format detected from content)")
    p.add_argument("--emg-rate", type=float, default=None, help="override the stored EMG rate [Hz]")
    p.add_argument(
        "--muscle", action="append", default=None, metavar="LABEL=SITE", help="map a channel"
    )
    p.add_argument("--frame-rate", type=float, default=None, help="pose frame rate [Hz]")
    p.add_argument(
        "--image-size", type=int, nargs=2, default=None, metavar=("W", "H"), help="video size [px]"
    )
    p.add_argument(
        "--offset", default=None, help="EMG-to-pose clock offset [s], or 'auto' (cross-correlation)"
    )
    p.add_argument(
        "--together", action="store_true", help="treat the files as one recording (EMG + pose)"
    )
    p.add_argument("--phase-bounds-deg", default="40,90", help="A/B and B/C elbow angles [deg]")
    p.add_argument("--body-mass", type=float, default=75.0, help="subject mass [kg]")
    p.add_argument("--body-height", type=float, default=1.75, help="subject height [m]")
    p.add_argument("--load", type=float, default=12.0, help="dumbbell mass [kg]")
    p.add_argument("--json", action="store_true")
    p.add_argument("--out", default=None, help="write the HumanTemplate JSON here")
    p.add_argument("--plot", default=None, metavar="DIR", help="write figures into DIR")
    p.set_defaults(handler=cmd_analyze)

    p = sub.add_parser("simulate", help="plan, then simulate both trajectories in MuJoCo")
    robot_args(p)
    p.add_argument("--objective", default="abs_work", help="one of " + ", ".join(OBJECTIVES))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true")
    p.add_argument("--out", default=None)
    p.set_defaults(handler=cmd_simulate)

    p = sub.add_parser("sweep", help="savings over a grid of durations and payloads")
    p.add_argument("--robot", default="curtain_wall_6dof")
    p.add_argument("--durations", default="0.5,0.75,1.0,1.5,2.0", help="comma-separated [s]")
    p.add_argument("--payloads", default="0,4,8,12,20", help="comma-separated [kg]")
    p.add_argument("--objectives", default="abs_work", help="comma-separated metric names")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true")
    p.add_argument("--out", default=None)
    p.set_defaults(handler=cmd_sweep)

    p = sub.add_parser("demo", help="reproduce the paper's figures and numbers into a report")
    p.add_argument("--out-dir", default="report", help="report folder (default: ./report)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(handler=cmd_demo)

    try:
        from app.api.cli_commands import add_service_subcommands
    except ImportError:  # the service layer is optional for the science CLI
        pass
    else:
        add_service_subcommands(sub)
    return parser


def _bad_input_types() -> tuple[type[BaseException], ...]:
    """Exception types that mean "bad input": reported in one line with exit code 2."""
    types: list[type[BaseException]] = [CliError]
    for module, name in (
        ("app.planning.planner", "PlanningError"),
        ("app.planning.robots", "RobotError"),
        ("app.recordings.types", "RecordingError"),
        ("app.simulation.tracking", "SimulationError"),
    ):
        mod = sys.modules.get(module)
        if mod is not None and hasattr(mod, name):
            types.append(getattr(mod, name))
    return tuple(types)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bioplan`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        return handler(args)
    except Exception as exc:
        if isinstance(exc, _bad_input_types()):
            print(f"bioplan {args.command}: error: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT
        raise
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
