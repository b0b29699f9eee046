"""Issue 14 item 11: 2000 half-sent connections were held with no read timeout. Raw sockets
against a real ``bioplan serve``: a request head must be complete within
BIOPLAN_HEAD_TIMEOUT_S, while complete requests and slow-but-steady kept-alive clients are
served."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.utils.server import Server

HEAD_TIMEOUT_S = 2.0


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    s = Server(tmp_path_factory.mktemp("slow") / "data", BIOPLAN_HEAD_TIMEOUT_S=str(HEAD_TIMEOUT_S))
    s.start()
    try:
        yield s
    finally:
        s.cleanup()


def _closed_after(sock: socket.socket, deadline_s: float = 60.0) -> float | None:
    """Seconds until the server closes ``sock`` (None: still open at the deadline)."""
    started = time.monotonic()
    sock.settimeout(1.0)
    while time.monotonic() - started < deadline_s:
        try:
            if sock.recv(4096) == b"":
                return time.monotonic() - started
        except TimeoutError:
            continue
        except ConnectionResetError:
            return time.monotonic() - started
    return None


def _connect(server: Server) -> socket.socket:
    return socket.create_connection(("127.0.0.1", server.port), timeout=30)


@pytest.mark.parametrize(
    "sent", [b"", b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n", b"GET /api/hea"]
)
def test_a_half_sent_head_is_dropped(server: Server, sent: bytes) -> None:
    with _connect(server) as sock:
        sock.sendall(sent)
        waited = _closed_after(sock)
    assert waited is not None, "the server kept a half-sent request open"
    assert waited >= HEAD_TIMEOUT_S * 0.9  # not before its deadline
    print(f"half-sent {sent!r}: closed after {waited:.2f} s")  # evidence in the log


def test_complete_requests_and_slow_steady_clients_are_served(server: Server) -> None:
    request = b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
    with _connect(server) as sock:
        for _ in range(2):  # two requests on one kept-alive connection, each under the deadline
            for i in range(0, len(request), 8):
                sock.sendall(request[i : i + 8])
                time.sleep(HEAD_TIMEOUT_S / 20)
            answer = b""
            while b'"status"' not in answer:
                chunk = sock.recv(4096)
                assert chunk, f"closed instead of answering: {answer!r}"
                answer += chunk
            assert answer.startswith(b"HTTP/1.1 200")


def test_many_half_sent_connections_do_not_block_others(server: Server) -> None:
    idle = [_connect(server) for _ in range(200)]
    try:
        for sock in idle:
            sock.sendall(b"POST /api/plans HTTP/1.1\r\nHost: 127.0.0.1\r\n")
        with _connect(server) as sock:
            sock.sendall(b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            assert sock.recv(4096).startswith(b"HTTP/1.1 200")
        closed = [_closed_after(s) for s in idle[:5]]
        assert all(c is not None for c in closed), closed
    finally:
        for sock in idle:
            sock.close()


def test_the_setting_reaches_the_server(tmp_path: Path) -> None:
    """A longer deadline keeps a half-sent head open past the short one's."""
    s = Server(tmp_path / "data", BIOPLAN_HEAD_TIMEOUT_S="30")
    s.start()
    try:
        with _connect(s) as sock:
            sock.sendall(b"GET /api/health HTTP/1.1\r\n")
            assert _closed_after(sock, deadline_s=HEAD_TIMEOUT_S * 3) is None
    finally:
        s.cleanup()
