"""``bioplan demo``: the paper's figures and numbers, reproduced into an offline HTML report."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from app.cli._common import emit, progress_printer
from app.names import PSO_DEFAULTS


def cmd_demo(args: argparse.Namespace) -> int:
    from app.simulation.report import write_demo_report

    out = Path(args.out_dir)
    index = write_demo_report(out, seed=args.seed, progress=progress_printer(True))
    results = index.parent / "results.json"
    claims = json.loads(results.read_text(encoding="utf-8"))["claims"]
    payload = {
        "report": str(index.resolve()),
        "results": str(results.resolve()),
        "seed": args.seed,
        "claims": claims,  # per robot and metric: the paper's, measured, per method, conditions
    }
    emit(args, payload, f"report written to {index}")
    return 0


def register(sub: Any) -> None:
    """Add ``demo`` to the ``bioplan`` subcommands."""
    p = sub.add_parser("demo", help="reproduce the paper's figures and numbers into a report")
    p.add_argument("--out-dir", default="report", help="report folder")
    p.add_argument("--seed", type=int, default=PSO_DEFAULTS.seed, help="PSO seed")
    p.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object (the report's paths and the paper's claims beside the "
        "measured savings per method, with their conditions) instead of the line for people",
    )
    p.set_defaults(handler=cmd_demo)
