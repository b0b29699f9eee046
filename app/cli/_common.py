"""What every ``bioplan`` command shares: errors, output, progress, robot and task options."""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn, TypeVar

from app.errors import BioPlanError
from app.names import MAX_DURATION, METHODS, METRICS
from app.options import Options, OptionsError, OptionSpec, check_value, option_specs
from app.planning.options import PlanOptions
from app.progress import Progress, ProgressFn

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2
OptionsT = TypeVar("OptionsT", bound=Options)


class CliError(BioPlanError):
    """Bad input detected by the CLI itself (an option's value)."""


class _HelpFormatter(argparse.HelpFormatter):
    """Shows each option's default after its help, unless the help already says it."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        if (
            "default" in text
            or default is None
            or default is argparse.SUPPRESS
            or isinstance(default, bool)
            or not action.option_strings
        ):
            return text
        return f"{text} (default: %(default)s)"


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage block), exit code 2, defaults shown in --help."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")

    def _parse_optional(self, arg_string: str) -> Any:
        # A negative number list ("--durations -1,1", "--start-deg -10,20") is a value, not an
        # option: argparse takes only a lone negative number as one. No option starts "-<digit>".
        if _NEGATIVE.match(arg_string):
            return None
        return super()._parse_optional(arg_string)


#: What a value starting with a minus sign looks like: "-1", "-1,1", "-.5 2", "-1e3".
_NEGATIVE = re.compile(r"^-\.?\d")


def write_out(path: str | Path, text: str, option: str = "--out") -> None:
    """Write ``text`` to the file an option names; a CliError (one line) when it cannot be."""
    try:
        Path(path).write_text(text, encoding="utf-8")
    except OSError as exc:
        raise CliError(
            f"{option} {path}: cannot write it ({exc.strerror or exc}): expected a file in an "
            "existing, writable folder"
        ) from None


def emit(args: argparse.Namespace, payload: dict[str, Any], text: str) -> None:
    """Print JSON (``--json``) or text, and write the JSON to ``--out`` when asked."""
    blob = json.dumps(payload, indent=2, allow_nan=False)
    out = getattr(args, "out", None)
    if out:
        write_out(out, blob + "\n")
    if getattr(args, "json", False):
        print(blob)
    else:
        print(text)


def add_json_args(p: argparse.ArgumentParser, *, out: bool = True) -> None:
    """--json and (unless ``out`` is False) --out FILE: what :func:`emit` reads."""
    p.add_argument("--json", action="store_true", help="print one JSON object")
    if out:
        p.add_argument("--out", default=None, help="also write the JSON to this file")


def progress_printer(enabled: bool) -> ProgressFn | None:
    """A progress bar on stderr (never stdout, which carries the JSON), when it is a terminal."""
    if not enabled or not sys.stderr.isatty():
        return None

    def show(update: Progress) -> None:
        bar = "#" * int(30 * update.fraction)
        line = update.message or f"{update.stage} {update.done}/{update.of}"
        print(
            f"\r[{bar:<30}] {100 * update.fraction:5.1f}% {line[:60]:<60}", end="", file=sys.stderr
        )
        if update.fraction >= 1.0:
            print(file=sys.stderr)

    return show


def positive(name: str, value: float) -> float:
    """``value`` when it is a finite number > 0, else a CliError naming ``--name``."""
    if not (math.isfinite(value) and value > 0):
        raise CliError(f"--{name} must be a positive number, got {value}")
    return value


def duration(name: str, value: float) -> float:
    """``value`` when it is a duration the API would plan too (> 0 s and at most
    :data:`~app.names.MAX_DURATION`), else a CliError naming ``--name``."""
    positive(name, value)
    if value > MAX_DURATION:
        raise CliError(f"--{name} must be at most {MAX_DURATION:g} s (as the API's), got {value:g}")
    return value


def _cli_spec(spec: OptionSpec) -> tuple[str, float, str | None]:
    """(flag, scale, unit) of an option on the command line."""
    flag = spec.meta.get("flag") or "--" + spec.name.replace("_", "-")
    return flag, float(spec.meta.get("cli_scale", 1.0)), spec.meta.get("cli_unit", spec.unit)


def _cli_help(spec: OptionSpec) -> str:
    """The option's help with its unit, range and (for lists) "comma-separated"."""
    _, scale, unit = _cli_spec(spec)
    text = spec.help + (f" [{unit}]" if unit else "")
    if spec.sequence:
        text = "comma-separated " + text
    signs = {"ge": ">=", "gt": ">", "le": "<=", "lt": "<"}
    bounds = [f"{signs[k]} {_number_text(v * scale)}" for k, v in spec.bounds().items()]
    if bounds:
        text += "; " + " and ".join(bounds)
    if "none_means" in spec.meta:
        text += f" (default: {spec.meta['none_means']})"
    if spec.choices is not None and spec.sequence:
        text += "; some of " + ", ".join(str(c) for c in spec.choices)
    return text.replace("%", "%%")  # argparse formats help with %


def _number_text(value: float) -> str:
    """A bound as people write it: 600, 0.1, 4294967295 (not 4.29497e+09)."""
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


def _items(text: str) -> list[str]:
    return [v.strip() for v in text.split(",") if v.strip()]


def add_options(
    p: argparse.ArgumentParser,
    cls: type,
    *,
    exclude: Sequence[str] = (),
    only: Sequence[str] | None = None,
) -> None:
    """One flag per option of an options dataclass (``PlanOptions``...), built from its field:
    the flag, type, default, choices, unit and range all come from there.

    Args:
        p: the command's parser.
        cls: the options dataclass; only its fields offered on the command line (``cli``).
        exclude: options this command does not offer although the dataclass has them.
        only: the options this command offers, when it offers a few of the dataclass's
            (``bioplan submit``: what it sends); None: all but ``exclude``.
    """
    for spec in option_specs(cls):
        if not spec.meta.get("cli", True) or spec.name in exclude:
            continue
        if only is not None and spec.name not in only:
            continue
        flag, scale, _ = _cli_spec(spec)
        kwargs: dict[str, Any] = {"dest": spec.name, "help": _cli_help(spec)}
        flagged = spec.kind is bool or (spec.choices is not None and not spec.sequence)
        if not flagged or "metavar" in spec.meta:  # else argparse's own: none, or {a,b,c}
            metavar = flag.removeprefix("--").replace("-", "_").upper()
            kwargs["metavar"] = spec.meta.get("metavar", metavar)
        if spec.kind is bool and not spec.sequence:
            negated = bool(spec.meta.get("negated"))
            kwargs["action"] = "store_false" if negated else "store_true"
            kwargs["default"] = spec.interface_default
        elif spec.sequence:  # numbers stay text: read by floats(), naming the flag
            kwargs["type"] = str if spec.kind in (int, float) else _items
            kwargs["default"] = ",".join(f"{v:g}" if isinstance(v, float) else str(v)
                                         for v in spec.interface_default)  # fmt: skip
        else:
            kwargs["type"] = spec.kind if spec.kind in (int, float, str) else str
            default = spec.interface_default
            kwargs["default"] = default * scale if default is not None and scale != 1 else default
            if spec.choices is not None:
                kwargs["choices"] = spec.choices
        p.add_argument(flag, **kwargs)


def options_from_args(
    cls: type[OptionsT], args: argparse.Namespace, *, exclude: Sequence[str] = ()
) -> OptionsT:
    """The options dataclass ``cls`` from parsed flags; options without a flag on this command
    keep their defaults.

    Args:
        cls: the options dataclass.
        args: the parsed flags.
        exclude: options whose flags the command reads itself (another form than the field's,
            as given to :func:`add_options`): they keep their defaults here.

    Raises:
        CliError: a value out of its range or choices, naming the flag.
    """
    given = vars(args)
    values: dict[str, Any] = {}
    for spec in option_specs(cls):
        if spec.name not in given or spec.name in exclude:
            continue
        flag, scale, _ = _cli_spec(spec)
        value = given[spec.name]
        if spec.sequence and spec.kind in (int, float) and isinstance(value, str):
            value = floats(value, flag.removeprefix("--"))
        if scale != 1 and value is not None:
            value = value / scale
        try:
            values[spec.name] = check_value(spec, value)
        except OptionsError as exc:
            raise CliError(f"{flag}: {exc}") from None
    return cls(**values)


#: The help of ``--duration`` (and ``--durations``): the cap, as the API states it.
DURATION_HELP = f"motion time [s], above 0 and at most {MAX_DURATION:g}"
#: The task's duration option (its default and range live in ``PlanOptions``).
_TASK_DURATION = next(s for s in option_specs(PlanOptions) if s.name == "duration")


def floats(text: str, name: str) -> list[float]:
    """Comma- or space-separated numbers of option ``--name``."""
    try:
        values = [float(v) for v in text.replace(",", " ").split()]
    except ValueError as exc:
        raise CliError(f"--{name} expects numbers separated by commas, got {text!r}") from exc
    if not values:
        raise CliError(f"--{name} is empty")
    return values


def add_robot_args(p: argparse.ArgumentParser) -> None:
    """--robot, --mjcf, the onboarding options, --duration, --payload, --start-deg, --goal-deg."""
    add_robot_flag(p)
    p.add_argument(
        "--mjcf",
        default=None,
        help="MJCF of the same robot as the URDF (compared with it at load; default: MuJoCo "
        "compiles the URDF itself)",
    )
    add_onboarding_args(p)
    p.add_argument("--duration", type=float, default=_TASK_DURATION.default, help=DURATION_HELP)
    p.add_argument(
        "--payload",
        type=float,
        default=None,
        help="payload mass [kg] (default: the robot's: 12 kg human, 4 kg curtain wall)",
    )
    p.add_argument(
        "--start-deg", default=None, help="start joint angles [deg], comma-separated (all joints)"
    )
    p.add_argument(
        "--goal-deg", default=None, help="goal joint angles [deg], comma-separated (all joints)"
    )


def add_robot_flag(p: argparse.ArgumentParser, *, required: bool = False) -> None:
    """--robot: a built-in robot's name or a robot file (the curtain wall unless ``required``)."""
    p.add_argument(
        "--robot",
        required=required,
        default=None if required else "curtain_wall_6dof",
        help="built-in robot name (human_arm_2dof, curtain_wall_6dof), a URDF path, or an MJCF "
        "path alone",
    )


def add_onboarding_args(p: argparse.ArgumentParser) -> None:
    """--shoulder-joint, --elbow-joint, --lock NAME=VALUE (repeatable), --sidecar FILE."""
    p.add_argument(
        "--shoulder-joint",
        default=None,
        help="joint that human shoulder flexion maps to (default: the sidecar's, else the first "
        "pitch pair of the arm; see docs/robots.md)",
    )
    p.add_argument(
        "--elbow-joint",
        default=None,
        help="joint that human elbow flexion maps to (default: as --shoulder-joint)",
    )
    p.add_argument(
        "--lock",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="hold a joint fixed, degrees for revolute and metres for prismatic joints "
        "(repeatable; e.g. fingers, a gripper, a torso; default: none)",
    )
    p.add_argument(
        "--sidecar",
        default=None,
        help="robot sidecar YAML: motors, gears, payload, locks (docs/robots.md; default: none, "
        "electrical metrics not modelled)",
    )
    p.add_argument(
        "--base-link",
        default=None,
        help="the arm's base link on a robot whose joints branch (legs, a mobile base, two arms): "
        "joints on other branches are locked (default: the sidecar's; see docs/robots.md)",
    )
    p.add_argument(
        "--tip-link",
        default=None,
        help="the arm's end link when the arm branches below its base (with --base-link)",
    )


def parse_locks(entries: Sequence[str]) -> dict[str, float]:
    """``--lock NAME=VALUE`` entries as {name: value} (display units)."""
    out: dict[str, float] = {}
    for entry in entries:
        name, sep, text = entry.partition("=")
        if not sep or not name.strip():
            raise CliError(f"--lock {entry!r}: expected NAME=VALUE")
        out[name.strip()] = finite(
            text,
            not_number=f"--lock {entry!r}: expected a number after '='",
            not_finite=f"--lock {entry!r}: expected a finite number",
        )
    return out


def finite(text: str, *, not_number: str, not_finite: str) -> float:
    """``text`` as a finite number, else a CliError in the caller's words for each case
    (an option's own message: what it expected, naming the flag)."""
    try:
        value = float(text)
    except ValueError:
        raise CliError(not_number) from None
    if not math.isfinite(value):
        raise CliError(not_finite)
    return value


def load_robot(args: argparse.Namespace) -> Any:
    """The robot of ``--robot`` with ``--payload``, ``--mjcf`` and the onboarding options.

    Also checks the export options (``--export``, ``--export-rate``) first, so that a bad one
    fails before any planning.
    """
    from app.planning.robots import load_robot as load
    from app.planning.robots import locks_from_display

    check_export_args(args)
    locks = parse_locks(getattr(args, "lock", []) or [])
    robot_file = str(args.robot)
    if locks and robot_file.lower().endswith((".xml", ".mjcf")):
        from app.planning.robots import urdf_from_mjcf

        locks = locks_from_display(urdf_from_mjcf(Path(robot_file)), locks)
    elif locks and Path(robot_file).suffix.lower() == ".urdf":
        locks = locks_from_display(robot_file, locks)
    elif locks:
        raise CliError(f"--lock given for built-in robot '{robot_file}': expected a robot file")
    return load(
        args.robot,
        payload=args.payload,
        mjcf=getattr(args, "mjcf", None),
        shoulder_joint=getattr(args, "shoulder_joint", None),
        elbow_joint=getattr(args, "elbow_joint", None),
        locks=locks or None,
        sidecar=getattr(args, "sidecar", None),
        base_link=getattr(args, "base_link", None),
        tip_link=getattr(args, "tip_link", None),
    )


def add_export_args(p: argparse.ArgumentParser) -> None:
    """--export FILE, --export-rate HZ, --export-method NAME."""
    from app.planning.export import FORMATS

    rates = ", ".join(f"{f.extension} {f.default_rate:g} Hz" for f in FORMATS.values())
    p.add_argument(
        "--export",
        default=None,
        metavar="FILE",
        help="also write the trajectory to FILE, the format from its extension "
        f"({', '.join(f.extension for f in FORMATS.values())}; docs/export.md; default: none)",
    )
    p.add_argument(
        "--export-rate",
        type=float,
        default=None,
        metavar="HZ",
        help=f"sample rate of the export (default: the format's: {rates})",
    )
    p.add_argument(
        "--export-method",
        default=None,
        metavar="NAME",
        help="planning method to export, one of " + ", ".join(METHODS) + " (default: the "
        "paper's method when planned, else the first planned of human_optimal, bound, "
        "jerk_limited)",
    )
    p.add_argument(
        "--export-force",
        action="store_true",
        help="write the export although it leaves the robot's limits (the file records it; "
        "default: refuse, exit 2; as bioplan export --force)",
    )
    p.add_argument(
        "--export-allow-unsafe",
        action="store_true",
        help="write the export although the safety check found a contact of its method (the "
        "file records it; default: refuse, exit 2; as bioplan export --allow-unsafe)",
    )


def check_export_args(args: argparse.Namespace) -> None:
    """Refuse bad export options before any work (unknown extension, bad rate, no folder)."""
    target = getattr(args, "export", None)
    if target is None:
        if getattr(args, "export_rate", None) is not None:
            raise CliError("--export-rate given without --export FILE")
        return
    from app.planning.export import FORMATS, check_rate, format_of

    fmt = format_of(target)
    check_rate(FORMATS[fmt].default_rate if args.export_rate is None else args.export_rate)
    folder = Path(target).parent
    if not folder.is_dir():
        raise CliError(f"--export {target}: folder {folder} does not exist")


def attach_motion(args: argparse.Namespace, robot: Any, plan: Any, payload: dict[str, Any]) -> None:
    """Put the plan's exact motion into ``payload["motion"]`` and write ``--export`` if asked.

    Args:
        args: the parsed options (``--export``, ``--export-rate``, ``--export-method``).
        robot: the robot the plan was made with.
        plan: the ``PlanResult`` (for ``simulate``: the simulation's plan).
        payload: the command's JSON object (gets the ``motion`` block).
    """
    from app.planning.export import ExportError, plan_motion, write_export

    motion = plan_motion(plan, robot)
    payload["motion"] = motion.to_dict()
    if getattr(args, "export", None):
        try:
            write_export(
                args.export,
                motion,
                method=args.export_method,
                rate=args.export_rate,
                robot=robot,
                force=getattr(args, "export_force", False),
                allow_unsafe=getattr(args, "export_allow_unsafe", False),
            )
        except ExportError as exc:  # name this command's flags, not bioplan export's
            text = str(exc).replace("--allow-unsafe", "--export-allow-unsafe")
            text = text.replace("--force", "--export-force")
            out = getattr(args, "out", None)
            if out:  # the plan took its time: keep it (bioplan export makes files from it)
                write_out(out, json.dumps(payload, indent=2, allow_nan=False) + "\n")
                text += f"; the plan itself was written to {out}"
            raise CliError(f"--export {args.export}: {text}") from None


def task_from_args(args: argparse.Namespace, robot: Any) -> Any:
    """The task from --start-deg/--goal-deg, each defaulting to the robot's curl task."""
    import numpy as np

    from app.planning.planner import PlanTask

    task = PlanTask.default(robot)
    start, goal = task.start.copy(), task.goal.copy()
    n = len(robot.joint_names)
    for flag, text, values_out in (
        ("start-deg", args.start_deg, start),
        ("goal-deg", args.goal_deg, goal),
    ):
        if text is None:
            continue
        values = floats(text, flag)
        if len(values) != n:
            raise CliError(
                f"--{flag} needs {n} angles for {robot.name} "
                f"({', '.join(robot.joint_names)}), got {len(values)}"
            )
        values_out[:] = np.radians(values)
    return PlanTask(start, goal)


def load_template(path: str | None) -> Any:
    """The HumanTemplate in JSON file ``path`` (None gives None: the paper's defaults)."""
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


def metrics_table(rows: Sequence[tuple[str, dict[str, Any]]], floors: dict[str, float]) -> str:
    """A text table of the scalar metrics of each row, with units, and the floors under it."""
    shown = [m for m in METRICS.values() if not m.per_joint]
    header = f"{'profile':<20}" + "".join(f"{m.name:>19}" for m in shown) + f"{'v-peak angle':>14}"
    lines = [header, " " * 20 + "".join(f"{'[' + m.unit + ']':>19}" for m in shown)]
    for label, values in rows:
        cells = "".join(
            f"{values[m.name]:>19.4g}"
            if values.get(m.name) is not None
            else f"{'not modelled' if m.name == 'electrical_energy' else 'n/a':>19}"
            for m in shown
        )
        angle = values.get("peak_velocity_angle_deg")
        lines.append(f"{label:<20}{cells}{angle:>12.1f}°" if angle is not None else cells)
    lines.append(floors_line(floors))
    return "\n".join(lines)


def floors_line(floors: dict[str, Any]) -> str:
    """The floors no method may go below (the planner's ``floors`` block), in one line."""

    def joules(key: str) -> str:
        value = floors.get(key)
        return "not modelled" if value is None else f"{value:.4g} J"

    if "peak_power" not in floors:  # a profiles comparison's floors: |ΔPE| and peak power
        return (
            f"floors (no profile may be below): |ΔPE| {floors['delta_potential']:.4g} J, "
            f"peak power {floors['min_peak_power']:.4g} W"
        )
    return (
        f"floors (no method may be below): |ΔPE| {joules('abs_work')}, positive work "
        f"{joules('pos_work')}, peak power {floors['peak_power']:.4g} W, electrical "
        f"{joules('electrical_energy')} (of which friction {joules('friction_energy')}); "
        "the peak-power floor |ΔPE|/T is loose (the bound is the reference); tau_sq, "
        "peak_torque, torque_change: no floor"
    )
