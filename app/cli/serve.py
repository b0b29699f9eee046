"""``bioplan serve``: migrate the database, then serve the API, the jobs and the dashboard."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from app.cli._common import EXIT_BAD_INPUT, EXIT_OK


def serve(
    host: str | None = None,
    port: int | None = None,
    data_dir: str | None = None,
    *,
    demo: bool = False,
) -> int:
    """Migrate the database (``alembic upgrade head``), then serve the API and dashboard.

    Args:
        host: bind address (default ``BIOPLAN_HOST`` or 127.0.0.1); a non-loopback address
            needs ``BIOPLAN_API_TOKEN``.
        port: TCP port (default ``BIOPLAN_PORT`` or 8000).
        data_dir: database and file store folder (default ``BIOPLAN_DATA_DIR`` or ./data).
        demo: when the database has no recordings, store a demo recording session and run its
            analysis, a plan and a simulation first, so the dashboard has something to show.

    Returns:
        Exit code: 0 after a clean stop, 2 for bad settings.
    """
    import logging

    from pydantic import ValidationError

    from app.config import Settings

    overrides: dict[str, Any] = {}
    if host is not None:
        overrides["host"] = host
    if port is not None:
        overrides["port"] = port
    if data_dir is not None:
        overrides["data_dir"] = Path(data_dir)
    try:
        settings = Settings(**overrides)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first.get("loc", ())) or "settings"
        print(f"bioplan serve: error: {where}: {first['msg']}", file=sys.stderr)
        return EXIT_BAD_INPUT
    logging.basicConfig(
        level=settings.log_level.upper(),
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    import uvicorn

    from app.db.session import upgrade
    from app.main import create_app
    from app.viewer import attach_dashboard, seed_demo

    settings.data_dir.mkdir(parents=True, exist_ok=True)
    upgrade(settings.db_url)  # before binding, so a broken database fails fast and loudly
    if demo:
        print("preparing the demo session (analysis, plan, simulation)...", flush=True)
        seed_demo(settings)
    app = create_app(settings)
    attach_dashboard(app, settings)
    print(f"BioPlan dashboard: http://{settings.host}:{settings.port}/", flush=True)
    uvicorn.run(
        app,
        host=settings.host,
        port=settings.port,
        workers=1,  # one process: it owns the job runner (and the viewer)
        log_level=settings.log_level,
        timeout_graceful_shutdown=5,
    )
    return EXIT_OK


def register(sub: Any) -> None:
    """Add ``serve`` to the ``bioplan`` subcommands."""
    p = sub.add_parser("serve", help="run the web service (API, jobs, dashboard)")
    p.add_argument("--host", default=None, help="bind address (default $BIOPLAN_HOST or 127.0.0.1)")
    p.add_argument(
        "--port", type=int, default=None, help="TCP port (default $BIOPLAN_PORT or 8000)"
    )
    p.add_argument(
        "--data-dir",
        default=None,
        help="database and uploads (default $BIOPLAN_DATA_DIR or ./data)",
    )
    p.add_argument(
        "--demo", action="store_true", help="seed a demo recording and comparison when empty"
    )
    p.set_defaults(handler=lambda a: serve(a.host, a.port, a.data_dir, demo=a.demo))
