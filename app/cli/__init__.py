"""The ``bioplan`` command (CLI contract in DESIGN.md).

One module per command group; each has ``register(subparsers)``. Handlers import what they need
inside, so ``bioplan plan`` does not pay for scipy.signal, MuJoCo or the web stack. With
``--json`` a command prints exactly one JSON object on stdout. Bad input (any ``BioPlanError``)
gives a one-line error on stderr and exit code 2; anything else is a bug and shows its traceback.
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
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module in _COMMANDS:
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bioplan`` console script."""
    args = build_parser().parse_args(argv)
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        return handler(args)
    except BioPlanError as exc:
        print(f"bioplan {args.command}: error: {one_line(str(exc))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
