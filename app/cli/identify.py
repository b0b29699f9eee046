"""``bioplan identify``: inertial parameters and friction from robot logs, written as a sidecar."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from app.cli._common import CliError, add_json_args, emit, load_robot, positive
from app.cli.validate import add_log_robot_args


def _base_sidecar(path: str | None) -> dict[str, Any]:
    """The given sidecar's YAML mapping (its motors, locks and roles are kept)."""
    if path is None:
        return {}
    from app.planning.robots import sidecar_yaml

    data = sidecar_yaml(path)
    return {k: v for k, v in data.items() if k not in ("links", "friction")}


def cmd_identify(args: argparse.Namespace) -> int:
    from app.planning.identification import IdentifyOptions, identify, write_sidecar
    from app.recordings.robot_logs import read_robot_log

    out = Path(args.out)
    if not out.parent.is_dir():
        raise CliError(f"--out {args.out}: folder {out.parent} does not exist")
    options = IdentifyOptions(
        validate_fraction=args.validate_fraction,
        cutoff_hz=positive("cutoff-hz", args.cutoff_hz) if args.cutoff_hz else 10.0,
        identify_payload=args.identify_payload,
    )
    robot = load_robot(args)
    logs = [read_robot_log(path, topic=args.topic) for path in args.log]
    result = identify(robot, logs, options)
    base = _base_sidecar(args.sidecar)
    if args.lock and "locks" not in base:
        from app.cli._common import parse_locks

        base["locks"] = parse_locks(args.lock)
    held = result.held_back
    comment = (
        f"Identified by bioplan identify from {', '.join(Path(p).name for p in args.log)}; "
        f"held-back residual rms [Nm]: "
        + ", ".join(f"{k} {v['residual_rms']:.3g}" for k, v in held.items())
    )
    write_sidecar(out, robot, result, base=base, comment=comment)
    payload = {"sidecar": str(out), **result.to_dict()}
    lines = [
        f"{result.n_base} base parameters identified from {result.samples} samples "
        f"in {result.seconds:.2f} s",
        f"{'joint':<16}{'fit residual':>14}{'held-back':>12}{'viscous':>10}{'coulomb':>10}"
        f"{'offset':>10}",
    ]
    for name in result.joint_names:
        f = result.friction[name]
        back = held.get(name, {}).get("residual_rms", float("nan"))
        lines.append(
            f"{name:<16}{result.fit[name]['residual_rms']:>14.4g} {back:>11.4g}"
            f" {f['viscous']:>9.4g} {f['coulomb']:>9.4g} {f['offset']:>9.4g}"
        )
    if result.payload is not None:
        lines.append(f"payload: {result.payload['mass']:.4g} kg at {result.payload['com']}")
    lines.append(f"sidecar written: {out} (use it with --robot {robot.urdf_path} --sidecar {out})")
    emit(argparse.Namespace(json=args.json), payload, "\n".join(lines))
    return 0


def register(sub: Any) -> None:
    """Add ``identify`` to the ``bioplan`` subcommands."""
    p = sub.add_parser(
        "identify", help="identify link inertias and friction from robot logs into a sidecar"
    )
    add_log_robot_args(p)
    p.add_argument("--log", required=True, nargs="+", help="robot logs with joint torques")
    p.add_argument("--out", required=True, help="the sidecar YAML to write")
    p.add_argument(
        "--validate-fraction",
        type=float,
        default=0.2,
        help="last fraction of each log held back to check the fit, in [0, 0.9)",
    )
    p.add_argument(
        "--identify-payload",
        action="store_true",
        help="identify a point payload (mass, centre of mass) at the payload body instead of "
        "that link's own inertia",
    )
    add_json_args(p, out=False)
    p.set_defaults(handler=cmd_identify)
