"""Issue 14 item 1: the viewer's websocket gave any web page a plan's title, power curve and
every joint pose. Real websocket clients: a capability for one comparison, the viewer page's own
``Origin``, bounded connections; a refused client is closed before any scene message."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest
from websockets.exceptions import ConnectionClosed

from app.viewer import server as server_module
from app.viewer.access import Refused, ViewerAccess
from app.viewer.comparison import Comparison
from app.viewer.scene import PreparedCache
from app.viewer.server import ViewerServer
from tests.viewer._fakes import connect_client, issued_path, listening_socket


@pytest.fixture
def viewer(plan_comparison: Comparison) -> Iterator[ViewerServer]:
    with listening_socket() as sock:
        port = sock.getsockname()[1]
    access = ViewerAccess(max_connections=3, max_per_token=2)
    server = ViewerServer(
        PreparedCache(lambda k, i: plan_comparison), port=port, autoplay=False, access=access
    )
    server.start()
    try:
        yield server
    finally:
        server.stop()


def _own(viewer: ViewerServer) -> str:
    return f"http://127.0.0.1:{viewer.port}"


def _outcome(ws: Any, timeout: float = 30.0) -> tuple[int | None, bytes]:
    """(close code or None if still open at the deadline, every byte received)."""
    received = b""
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            try:
                message = ws.recv(timeout=1.0)
            except TimeoutError:
                if received:
                    return None, received  # open and streaming: admitted
                continue
            received += message if isinstance(message, bytes) else message.encode()
    except ConnectionClosed as exc:
        return (exc.rcvd.code if exc.rcvd else None), received
    return None, received


def _sessions_after(viewer: ViewerServer, wait: float = 3.0) -> int:
    time.sleep(wait)  # a refused tab must never get a session, however long one waits
    return len(viewer.sessions())


@pytest.mark.parametrize(
    "case", ["foreign origin", "no token", "wrong comparison", "forged token", "other port"]
)
def test_refused_before_any_scene_message(
    viewer: ViewerServer, plan_comparison: Comparison, case: str
) -> None:
    own = _own(viewer)
    path, origin = {
        "foreign origin": (issued_path(viewer, "plan", 7), "https://evil.example"),
        "no token": ("/bioplan/plan/7", own),
        "wrong comparison": (issued_path(viewer, "plan", 8).replace("/plan/8", "/plan/7"), own),
        "forged token": ("/bioplan/plan/7?token=" + "A" * 32, own),
        "other port": (issued_path(viewer, "plan", 7), "http://127.0.0.1:1"),
    }[case]
    ws = connect_client(viewer, path, origin=origin)
    try:
        code, received = _outcome(ws)
    finally:
        ws.close()
    assert code == 1008, (case, code)
    assert received == b""  # not one message: closed before anything was sent
    assert _sessions_after(viewer) == 0
    assert viewer.access.connections() == 0


def test_the_issued_address_is_served_and_connections_are_bounded(
    viewer: ViewerServer, plan_comparison: Comparison
) -> None:
    own = _own(viewer)
    first = connect_client(viewer, issued_path(viewer, "plan", 7), origin=own)
    second = connect_client(viewer, issued_path(viewer, "plan", 7))  # no Origin: not a browser
    try:
        for ws in (first, second):
            code, received = _outcome(ws, timeout=60.0)
            assert code is None and len(received) > 10_000  # the scene streams (compressed)
        assert {s["id"] for s in viewer.sessions()} == {7}
        # A third tab on the same capability is beyond max_per_token (2).
        third = connect_client(viewer, issued_path(viewer, "plan", 7), origin=own)
        assert _outcome(third)[0] == 1008
        third.close()
        # Another comparison's capability still has room, until max_connections (3) in all.
        other = connect_client(viewer, issued_path(viewer, "simulation", 9), origin=own)
        assert _outcome(other, timeout=60.0)[0] is None
        fourth = connect_client(viewer, issued_path(viewer, "simulation", 9), origin=own)
        assert _outcome(fourth)[0] == 1008
        fourth.close()
        other.close()
    finally:
        first.close()
        second.close()
    deadline = time.monotonic() + 30
    while viewer.access.connections() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert viewer.access.connections() == 0  # closed tabs free their places


def test_the_handshake_is_still_readable(viewer: ViewerServer) -> None:
    """The check reads the path and Origin from viser's private connection table
    (``app.viewer.server._handshake``); if a viser upgrade moves it, every tab is refused
    (fail closed) and this test says where to look."""
    own = _own(viewer)
    ws = connect_client(viewer, issued_path(viewer, "plan", 7), origin=own)
    try:
        assert _outcome(ws, timeout=60.0)[0] is None, "_handshake no longer reads viser's table"
        # viser streams before the tab's session is registered: wait for it (a busy machine).
        deadline = time.monotonic() + 60
        while not viewer.sessions() and time.monotonic() < deadline:
            time.sleep(0.1)
        client_id = viewer.sessions()[0]["client_id"]
        path, origin = server_module._handshake(viewer._server, client_id) or (None, None)
        assert path is not None and path.startswith("/bioplan/plan/7?token="), path
        assert origin == own
    finally:
        ws.close()


def test_capabilities_expire_and_are_per_comparison() -> None:
    now = [0.0]
    access = ViewerAccess(ttl_s=10.0, now=lambda: now[0])
    ok = lambda origin: True  # noqa: E731
    token = access.issue("plan", 2)
    assert access.issue("plan", 2) == token  # the same while valid (a reloaded page)
    assert access.issue("plan", 3) != token
    grant = access.admit(1, f"/bioplan/plan/2?token={token}&methods=bound,paper", None, ok)
    assert (grant.kind, grant.id, grant.methods) == ("plan", 2, ("bound", "paper"))
    with pytest.raises(Refused, match="not for plan 3"):
        access.admit(2, f"/bioplan/plan/3?token={token}", None, ok)
    now[0] = 11.0
    with pytest.raises(Refused, match="expired"):
        access.admit(3, f"/bioplan/plan/2?token={token}", None, ok)
    access.release(1)
    assert access.connections() == 0
    assert len(access.issue("plan", 2)) >= 32 and access.issue("plan", 2) != token  # a new one
