"""The ``bioplan`` command (CLI contract in DESIGN.md).

One module per command group; each has ``register(subparsers)``. Handlers import what they need
inside, so ``bioplan plan`` does not pay for scipy.signal, MuJoCo or the web stack. With
``--json`` a command prints exactly one JSON object on stdout. Bad input (any ``BioPlanError``)
gives a one-line error on stderr and exit code 2; anything else is a bug and shows its traceback.

``-v`` (INFO), ``-vv`` (DEBUG) and ``--quiet`` (errors only) come before the command
(``bioplan -v plan ...``) and set the level of BioPlan's log (``app.logs``), printed on stderr
one line per record; stdout is unchanged (with ``--json`` still exactly one JSON object). They
are the top-level parser's: ``bioplan pose-env --verbose`` (after the command) stays that
command's own flag, the installers' output.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

from app import __version__
from app.cli import (
    analyze,
    cohort,
    demo,
    export,
    front,
    identify,
    plan,
    samples,
    serve,
    simulate,
    submit,
    validate,
)
from app.cli._common import EXIT_BAD_INPUT, Parser
from app.errors import BioPlanError, one_line
from app.logs import set_log_level

__all__ = ["build_parser", "main"]

#: Command groups, in the order ``bioplan --help`` lists them.
_COMMANDS = (
    *(plan, analyze, cohort, simulate, export, demo, samples, serve, submit),
    *(validate, identify),
    front,
)


def build_parser() -> argparse.ArgumentParser:
    """The ``bioplan`` argument parser with every subcommand."""
    parser = Parser(
        prog="bioplan",
        description="Bio-inspired, energy-efficient trajectory planning from human lifting data.",
    )
    parser.add_argument("--version", action="version", version=f"bioplan {__version__}")
    loud = parser.add_mutually_exclusive_group()
    loud.add_argument(
        "-v",
        "--verbose",
        action="count",
        default=0,
        dest="log_verbosity",
        help="show what the science decides on stderr: -v INFO (methods, solve times, channels, "
        "repetitions), -vv DEBUG (every step); before the command (default: warnings only)",
    )
    loud.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        dest="log_quiet",
        help="show only errors on stderr (no warnings); before the command",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module in _COMMANDS:
        module.register(sub)
    return parser


def log_level(verbosity: int, quiet: bool) -> str:
    """The log level of ``-v`` given ``verbosity`` times, or of ``--quiet``."""
    if quiet:
        return "ERROR"
    return ("WARNING", "INFO")[verbosity] if verbosity < 2 else "DEBUG"


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bioplan`` console script."""
    args = build_parser().parse_args(argv)
    before = set_log_level(log_level(args.log_verbosity, args.log_quiet))
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        return handler(args)
    except BioPlanError as exc:
        print(f"bioplan {args.command}: error: {one_line(str(exc))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    finally:  # called in-process (tests, scripts): the caller's logging as it was
        set_log_level(before, handler=False)
