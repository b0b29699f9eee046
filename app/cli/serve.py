"""``bioplan serve``: migrate the database, then serve the API, the jobs and the dashboard.

The port is bound first, so a busy port is a one-line error at once (exit code 2) rather than a
traceback after the demo is seeded; uvicorn then serves on that very socket. The data directory
and the database are claimed next (one server each). On a stop signal the open event streams
end at once (uvicorn would otherwise wait for them), and asyncio's "socket.accept() out of
system resource" error, which it logs up to 2048 times per wake-up when descriptors run out
(117 MB of log in 15 s), is logged once a minute at most. The URL is printed
only once the server answers ``GET /api/health``; everything said before goes to stderr, so with
``--json`` stdout carries exactly one JSON object.
"""

from __future__ import annotations

import contextlib
import copy
import errno
import json
import logging
import resource
import socket
import sys
import threading
import time
import urllib.request
from pathlib import Path
from typing import Any

from app.cli._common import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK

#: Seconds to wait for a started server to answer its health check before giving up on the URL.
READY_TIMEOUT = 120.0


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def _settings(host: str | None, port: int | None, data_dir: str | None) -> Any:
    """Settings from the environment with the command line's overrides; None after an error."""
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
        return Settings(**overrides)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first.get("loc", ())) or "settings"
        _say(f"bioplan serve: error: {where}: {first['msg']}")
        return None


def bind(host: str, port: int) -> socket.socket:
    """A listening-ready TCP socket bound to ``host:port`` (as uvicorn would bind it).

    Raises:
        OSError: the address cannot be bound (``errno.EADDRINUSE`` when the port is taken).
    """
    family, kind, proto, _, address = socket.getaddrinfo(
        host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
    )[0]
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
    except OSError:
        sock.close()
        raise
    sock.set_inheritable(True)
    return sock


def _bind_or_explain(host: str, port: int) -> socket.socket | None:
    try:
        return bind(host, port)
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            _say(
                f"bioplan serve: error: port {port} on {host} is already in use: "
                "choose another with --port or BIOPLAN_PORT"
            )
        else:
            _say(f"bioplan serve: error: cannot bind to {host}:{port}: {exc.strerror or exc}")
        return None


def _url_host(host: str) -> str:
    if host in ("0.0.0.0", "::", ""):
        return "127.0.0.1"
    return f"[{host}]" if ":" in host else host


def _announce_when_ready(server: Any, app: Any, url: str, json_out: bool) -> None:
    """Print the URL (or the JSON object) once the server answers its health check."""
    deadline = time.monotonic() + READY_TIMEOUT
    while time.monotonic() < deadline and not server.should_exit:
        if server.started:
            try:
                with urllib.request.urlopen(url + "api/health", timeout=2) as response:
                    if response.status == 200:
                        break
            except OSError:
                pass
        time.sleep(0.05)
    else:
        return
    viewer = app.state.services.viewer_info()  # the lifespan has run: the server answered
    if json_out:
        print(json.dumps({"url": url, "viewer": viewer}), flush=True)
        return
    where = f"; 3-D viewer on port {viewer['port']}" if viewer.get("enabled") else ""
    print(f"BioPlan dashboard: {url}{where} (Ctrl+C stops it)", flush=True)


def serve(
    host: str | None = None,
    port: int | None = None,
    data_dir: str | None = None,
    *,
    demo: bool = False,
    json_out: bool = False,
) -> int:
    """Migrate the database (``alembic upgrade head``), then serve the API and dashboard.

    Args:
        host: bind address (default ``BIOPLAN_HOST`` or 127.0.0.1); a non-loopback address
            needs ``BIOPLAN_API_TOKEN``.
        port: TCP port (default ``BIOPLAN_PORT`` or 8000).
        data_dir: database and file store folder (default ``BIOPLAN_DATA_DIR`` or ./data).
        demo: when the database has no recordings, store a demo recording session and run its
            analysis, a plan and a simulation first, so the dashboard has something to show.
        json_out: once the server answers, print ``{"url", "viewer"}`` as one JSON object
            instead of the line for people.

    Returns:
        Exit code: 0 after a clean stop, 2 for bad settings, a busy port, a data directory
        another server uses or one that is not writable, 1 when the server could not start.
    """
    settings = _settings(host, port, data_dir)
    if settings is None:
        return EXIT_BAD_INPUT
    sock = _bind_or_explain(settings.host, settings.port)
    if sock is None:
        return EXIT_BAD_INPUT
    from app.db.lock import DataDirError, lock_data_dir, lock_database

    try:  # before migrating or seeding: one server per (writable) data directory
        data_lock = lock_data_dir(settings.data_dir)
    except DataDirError as exc:
        sock.close()
        _say(f"bioplan serve: error: {exc}")
        return EXIT_BAD_INPUT
    try:  # and one server per database, whatever its data directory
        db_lock = lock_database(settings.db_url, data_dir=settings.data_dir)
    except DataDirError as exc:
        data_lock.release()
        sock.close()
        _say(f"bioplan serve: error: {exc}")
        return EXIT_BAD_INPUT
    except Exception as exc:  # PostgreSQL unreachable: said once, as the migration would
        data_lock.release()
        sock.close()
        from sqlalchemy.engine import make_url

        shown = make_url(settings.db_url).render_as_string(hide_password=True)
        _say(f"bioplan serve: error: cannot use the database {shown}: {_first_line(exc)}")
        return EXIT_FAILED
    try:
        return _run(settings, sock, demo=demo, json_out=json_out)
    finally:
        db_lock.release()
        data_lock.release()
        sock.close()


def _first_line(exc: BaseException) -> str:
    orig = getattr(exc, "orig", None) or exc
    text = str(orig).strip()
    return text.splitlines()[0] if text else type(exc).__name__


#: The most file descriptors the server asks for (its soft limit is raised up to the hard one).
MAX_OPEN_FILES = 65536
#: Seconds between two reports of the same flood of failed accepts.
ACCEPT_REPORT_EVERY = 60.0


class _AcceptErrorThrottle(logging.Filter):
    """Lets asyncio's "socket.accept() out of system resource" through once per
    ``ACCEPT_REPORT_EVERY`` seconds, with the count of those dropped meanwhile and without the
    traceback (the same every time); everything else passes."""

    def __init__(self) -> None:
        super().__init__()
        self.next = 0.0
        self.dropped = 0

    def filter(self, record: logging.LogRecord) -> bool:
        if not str(record.msg).startswith("socket.accept() out of system resource"):
            return True
        now = time.monotonic()
        if now < self.next:
            self.dropped += 1
            return False
        error = record.exc_info[1] if record.exc_info else None
        record.msg = "socket.accept() out of system resource (%s); %d more since last said"
        record.args = (error, self.dropped)
        record.exc_info = record.exc_text = None
        self.next, self.dropped = now + ACCEPT_REPORT_EVERY, 0
        return True


def _raise_open_files() -> None:
    """Raise the soft limit on open descriptors to the hard one (up to ``MAX_OPEN_FILES``):
    every connection, event stream and database file takes one."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    want = MAX_OPEN_FILES if hard == resource.RLIM_INFINITY else min(hard, MAX_OPEN_FILES)
    if soft != resource.RLIM_INFINITY and soft < want:
        with contextlib.suppress(ValueError, OSError):  # not allowed: keep the soft one
            resource.setrlimit(resource.RLIMIT_NOFILE, (want, hard))


def _server(config: Any, app: Any) -> Any:
    """A uvicorn server whose stop signal also ends every open event stream at once."""
    import asyncio

    import uvicorn

    class Server(uvicorn.Server):
        def handle_exit(self, sig: int, frame: Any) -> None:
            super().handle_exit(sig, frame)
            services = getattr(app.state, "services", None)
            if services is None:
                return
            try:  # a signal handler: only hand the work to the loop
                asyncio.get_running_loop().call_soon_threadsafe(services.broker.close_all)
            except RuntimeError:
                threading.Thread(target=services.broker.close_all, daemon=True).start()

    return Server(config)


def _uvicorn_logging() -> dict[str, Any]:
    """uvicorn's logging set-up with its access log on stderr too: stdout carries results."""
    from uvicorn.config import LOGGING_CONFIG

    config = copy.deepcopy(LOGGING_CONFIG)
    for handler in config["handlers"].values():
        handler["stream"] = "ext://sys.stderr"
    return config


def _run(settings: Any, sock: socket.socket, *, demo: bool, json_out: bool) -> int:
    import uvicorn

    from app.db.session import upgrade
    from app.main import create_app
    from app.services import seed_demo

    logging.basicConfig(
        level=settings.log_level.upper(),
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    if settings.log_level != "debug":  # Alembic narrates every migration step at INFO
        logging.getLogger("alembic").setLevel(logging.WARNING)
    logging.getLogger("asyncio").addFilter(_AcceptErrorThrottle())
    _raise_open_files()
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import OperationalError

    settings.data_dir.mkdir(parents=True, exist_ok=True)
    shown = make_url(settings.db_url).render_as_string(hide_password=True)
    _say(f"bioplan serve: migrating the database ({shown})")
    try:
        upgrade(settings.db_url)  # before anything else: a broken database fails fast
    except OperationalError as exc:  # unreachable, refused, wrong credentials: not a bug
        reason = str(exc.orig or exc).strip().splitlines()[0]
        _say(f"bioplan serve: error: cannot use the database {shown}: {reason}")
        return EXIT_FAILED
    if demo:
        seed_demo(settings, say=_say)
    _say(
        "bioplan serve: starting the job runner"
        + (" and the 3-D viewer" if settings.viewer else "")
    )
    from app.api.http_protocol import head_timeout_protocol

    app = create_app(settings)
    config = uvicorn.Config(
        app,
        workers=1,  # one process: it owns the job runner and the viewer
        log_level=settings.log_level,
        log_config=_uvicorn_logging(),
        timeout_graceful_shutdown=5,
        # A request's head within head_timeout_s; an idle kept-alive connection for 5 s.
        http=head_timeout_protocol(settings.head_timeout_s),
        timeout_keep_alive=5,
    )
    server = _server(config, app)
    url = f"http://{_url_host(settings.host)}:{settings.port}/"
    threading.Thread(
        target=_announce_when_ready,
        args=(server, app, url, json_out),
        name="bioplan-ready",
        daemon=True,
    ).start()
    server.run(sockets=[sock])
    return EXIT_OK if server.started else EXIT_FAILED


def register(sub: Any) -> None:
    """Add ``serve`` to the ``bioplan`` subcommands."""
    p = sub.add_parser(
        "serve",
        help="run the web service (API, jobs, dashboard)",
        description="Migrate the database, then serve the API, the background jobs, the "
        "dashboard and the 3-D viewer. Prints the dashboard's URL once it answers.",
    )
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
    p.add_argument(
        "--json",
        action="store_true",
        help='once the server answers, print {"url", "viewer"} as one JSON object',
    )
    p.set_defaults(
        handler=lambda a: serve(a.host, a.port, a.data_dir, demo=a.demo, json_out=a.json)
    )
