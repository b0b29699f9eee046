"""The ``bioplan`` command (CLI contract in DESIGN.md)."""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bioplan`` console script."""
    del argv
    print("bioplan: not implemented yet", file=sys.stderr)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
