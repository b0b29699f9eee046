"""``python -m app.cli``: the ``bioplan`` command."""

from app.cli import main

raise SystemExit(main())
