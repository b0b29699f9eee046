"""``bioplan analyze``: recordings of lifts in, lifts, phases, onsets and a human template out."""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from app.cli._common import CliError
from app.planning.jsonsafe import json_safe


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


def register(sub: Any) -> None:
    """Add ``analyze`` to the ``bioplan`` subcommands."""
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
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--out", default=None, help="write the HumanTemplate JSON here")
    p.add_argument("--plot", default=None, metavar="DIR", help="write figures into DIR")
    p.set_defaults(handler=cmd_analyze)
