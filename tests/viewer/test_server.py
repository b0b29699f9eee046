"""The viser server wrapper: real port when the asked one is busy, client paths, stop."""

from __future__ import annotations

import logging
import socket
import urllib.request

import pytest

from app.viewer.comparison import Comparison
from app.viewer.scene import PreparedCache
from app.viewer.server import ViewerServer, parse_client_path


def _listening_socket() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.bind(("127.0.0.1", 0))
    sock.listen(1)
    return sock


@pytest.mark.parametrize(
    ("path", "expected"),
    [
        ("/bioplan/plan/7", ("plan", 7)),
        ("/bioplan/simulation/12/", ("simulation", 12)),
        ("/bioplan/plan/7?x=1", ("plan", 7)),
        ("/bioplan/sweep/7", None),
        ("/bioplan/plan/0", None),
        ("/bioplan/plan/-1", None),
        ("/bioplan/plan/12345678901", None),
        ("/bioplan/plan/7/../../etc", None),
        ("/", None),
        ("", None),
        (None, None),
    ],
)
def test_client_paths(path: str | None, expected: tuple[str, int] | None) -> None:
    assert parse_client_path(path) == expected


def test_busy_port_moves_and_the_real_port_is_reported(
    plan_comparison: Comparison, caplog: pytest.LogCaptureFixture
) -> None:
    busy = _listening_socket()
    asked = busy.getsockname()[1]
    viewer = ViewerServer(PreparedCache(lambda k, i: plan_comparison), port=asked)
    try:
        with caplog.at_level(logging.WARNING, logger="app.viewer.server"):
            port = viewer.start()
        assert port != asked and port == viewer.port
        assert f"viewer port {asked} was busy" in caplog.text
        # Something really serves viser's client there.
        page = urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=10).read()
        assert b"<html" in page.lower() and len(page) > 100_000
        assert viewer.url == f"http://127.0.0.1:{port}"
        assert viewer.client_url("plan", 7) == (
            f"http://127.0.0.1:{port}/?websocket=ws://127.0.0.1:{port}/bioplan/plan/7&hideViserLogo"
        )
        assert viewer.sessions() == []
    finally:
        viewer.stop()
        busy.close()
    assert not viewer.running
    with pytest.raises(RuntimeError, match="not running"):
        _ = viewer.port
    # Stopped means nothing listens there any more (TIME_WAIT of our request is fine).
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as again:
        again.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        again.bind(("127.0.0.1", port))
