"""``bioplan cohort``: recordings in groups (conditions) in; per-recording measures, per-group
summaries and tests between the groups out. The options are built from
:class:`app.analysis.cohort.CohortOptions` (defaults, units, choices and ranges defined there)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from app.cli._common import CliError, add_json_args, add_options, options_from_args
from app.jsonsafe import json_safe


def _groups(raw: list[list[str]] | None) -> dict[str, list[str]]:
    """``--group NAME FILE...`` occurrences as name -> files, checked."""
    groups: dict[str, list[str]] = {}
    for item in raw or []:
        name, files = item[0], item[1:]
        if not name.strip():
            raise CliError("--group expects a NAME then its files, got an empty name")
        if name in groups:
            raise CliError(f"--group {name!r} is given twice (expected each group once)")
        if not files:
            raise CliError(f"--group {name!r} has no files (expected --group NAME FILE...)")
        for f in files:
            if not Path(f).is_file():
                raise CliError(f"{f}: no such file (in --group {name!r})")
        groups[name] = files
    if len(groups) < 2:
        got = ", ".join(repr(g) for g in groups) or "none"
        raise CliError(f"a cohort needs at least two --group NAME FILE... to compare, got {got}")
    return groups


def cmd_cohort(args: argparse.Namespace) -> int:
    from app.analysis.cohort import CohortOptions, cohort_statistics, write_cohort_csv
    from app.recordings import read_recording

    groups = _groups(args.group)
    options = options_from_args(CohortOptions, args)
    recordings = {
        name: [read_recording(f, emg_rate=options.emg_rate) for f in files]
        for name, files in groups.items()
    }
    result = cohort_statistics(recordings, options)
    payload = json_safe(result.to_dict())
    written: list[str] = []
    if args.plot:
        from app.analysis.cohort_plots import write_cohort_plots

        payload["plots"] = [str(p) for p in write_cohort_plots(result, args.plot)]
        written.append(f"figures written to {args.plot}")
    if args.csv:
        payload["csv"] = [str(p) for p in write_cohort_csv(result, args.csv)]
        written.append(f"tables written to {', '.join(payload['csv'])}")
    if args.json:
        print(json.dumps(payload, indent=2, allow_nan=False))
        return 0
    print(result.summary())
    for line in written:
        print(line)
    return 0


def register(sub: Any) -> None:
    """Add ``cohort`` to the ``bioplan`` subcommands."""
    p = sub.add_parser(
        "cohort",
        help="compare groups of recordings (conditions): measures, summaries, tests",
        description="Analyse every recording alone, measure it (lifts, lift and A/B/C phase"
        " durations, onset latency and envelope peak per muscle, velocity-peak angle), summarise"
        " each group (mean +- SD, median [IQR], activation order) and test every measure"
        " between every two groups with an effect size, corrected for multiple comparisons.",
    )
    p.add_argument(
        "--group",
        nargs="+",
        action="append",
        metavar=("NAME", "FILE"),
        required=True,
        help="a group (condition) and its recording files; give at least two groups",
    )
    from app.analysis.cohort import CohortOptions

    add_options(p, CohortOptions)
    add_json_args(p, out=False)
    p.add_argument(
        "--plot",
        default=None,
        metavar="DIR",
        help="write box plots per measure and an onset-order diagram (HTML) into DIR",
    )
    p.add_argument(
        "--csv",
        default=None,
        metavar="FILE",
        help="write one row per recording to FILE and one row per test to FILE's <stem>_tests.csv",
    )
    p.set_defaults(handler=cmd_cohort)
