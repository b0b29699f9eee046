"""Security finding 4: event streams exhausted the server. 1,100 idle ``/api/events/jobs``
streams from one client took every descriptor, every request timed out and 117 MB of log were
written in 15 s (asyncio's "socket.accept() out of system resource", with its traceback, up to
2048 times per wake-up). Against a real ``bioplan serve`` with raw sockets: streams beyond the
per-client and the total caps are refused with a 429 problem and ``Retry-After`` while other
requests are served; a refused or failed stream gives its place back; a stream with nothing
to report ends after ``BIOPLAN_STREAM_IDLE_S``; every stream ends (cleanly) when the server
stops; a flood of failed accepts is logged once, not per attempt."""

from __future__ import annotations

import json
import shutil
import signal
import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.utils.server import Server

PER_CLIENT = 3
TOTAL = 3


class RawStream:
    """``GET path`` on its own socket: the status, headers and what followed them."""

    def __init__(self, port: int, path: str = "/api/events/jobs") -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=60)
        self.sock.sendall(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode())
        data = b""
        while b"\r\n\r\n" not in data:
            chunk = self.sock.recv(65536)
            assert chunk, f"closed before answering: {data!r}"
            data += chunk
        head, _, self.rest = data.partition(b"\r\n\r\n")
        lines = head.decode("latin-1").split("\r\n")
        self.status = int(lines[0].split()[1])
        self.headers = {
            k.strip().lower(): v.strip() for k, _, v in (line.partition(":") for line in lines[1:])
        }

    def problem(self) -> dict[str, Any]:
        """The JSON body of a refusal (``Content-Length`` long)."""
        size = int(self.headers["content-length"])
        while len(self.rest) < size:
            chunk = self.sock.recv(65536)
            assert chunk
            self.rest += chunk
        return dict(json.loads(self.rest[:size]))

    def read_to_end(self, deadline_s: float = 120.0) -> bytes | None:
        """Everything until the server closes the stream (None: still open at the deadline)."""
        data = self.rest
        deadline = time.monotonic() + deadline_s
        self.sock.settimeout(1.0)
        while time.monotonic() < deadline:
            try:
                chunk = self.sock.recv(65536)
            except TimeoutError:
                continue
            except ConnectionResetError:
                return data
            if not chunk or data.endswith(b"0\r\n\r\n"):
                return data + chunk
            data += chunk
            if data.endswith(b"0\r\n\r\n"):  # the last chunk: the response ended
                return data
        return None

    def close(self) -> None:
        self.sock.close()


def _health_ok(server: Server) -> float:
    """Seconds ``GET /api/health`` took (it must answer)."""
    started = time.monotonic()
    response = httpx.get(server.url + "/api/health", timeout=60)
    assert response.status_code == 200
    return time.monotonic() - started


def _open_until_accepted(server: Server, deadline_s: float = 60.0) -> RawStream:
    """A stream, retrying while refused (a released place may take a moment to be seen)."""
    deadline = time.monotonic() + deadline_s
    while True:
        stream = RawStream(server.port)
        if stream.status == 200 or time.monotonic() > deadline:
            return stream
        stream.close()
        time.sleep(0.2)


@pytest.fixture(scope="module")
def per_client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    s = Server(
        tmp_path_factory.mktemp("streams") / "data",
        BIOPLAN_MAX_STREAMS_PER_CLIENT=str(PER_CLIENT),
        BIOPLAN_MAX_STREAMS="100",
    )
    s.start()
    try:
        yield s
    finally:
        s.cleanup()


def test_the_per_client_cap_refuses_the_extra_stream_and_others_are_served(
    per_client: Server,
) -> None:
    streams = [RawStream(per_client.port) for _ in range(PER_CLIENT)]
    try:
        assert [s.status for s in streams] == [200] * PER_CLIENT
        extra = RawStream(per_client.port)
        assert extra.status == 429
        assert int(extra.headers["retry-after"]) >= 1
        assert extra.headers["content-type"].startswith("application/problem+json")
        problem = extra.problem()
        assert problem["status"] == 429
        assert "BIOPLAN_MAX_STREAMS_PER_CLIENT" in problem["detail"]
        extra.close()
        took = _health_ok(per_client)  # other requests are still answered
        print(f"GET /api/health with {PER_CLIENT} streams open and one refused: {took:.3f} s")
        # The per-job stream counts too.
        job_stream = RawStream(per_client.port, "/api/jobs/1/events")
        job_stream.close()
        assert job_stream.status == 429
    finally:
        for s in streams:
            s.close()
    # Closed streams give their places back.
    again = [_open_until_accepted(per_client) for _ in range(PER_CLIENT)]
    try:
        assert [s.status for s in again] == [200] * PER_CLIENT
    finally:
        for s in again:
            s.close()


def test_a_stream_that_fails_gives_its_place_back(per_client: Server) -> None:
    for _ in range(3 * PER_CLIENT):  # no such job: 404, and no place kept
        missing = RawStream(per_client.port, "/api/jobs/999999/events")
        assert missing.status == 404
        missing.close()
    streams = [_open_until_accepted(per_client) for _ in range(PER_CLIENT)]
    try:
        assert [s.status for s in streams] == [200] * PER_CLIENT
    finally:
        for s in streams:
            s.close()


def test_refusals_are_logged_a_bounded_number_of_times(per_client: Server) -> None:
    streams = [_open_until_accepted(per_client) for _ in range(PER_CLIENT)]
    try:
        for _ in range(100):
            extra = RawStream(per_client.port)
            assert extra.status == 429
            extra.close()
    finally:
        for s in streams:
            s.close()
    lines = [ln for ln in per_client.log.read_text().splitlines() if "stream from" in ln]
    assert 1 <= len(lines) <= 3, lines


def test_the_total_cap_refuses_streams_from_every_client(tmp_path: Path) -> None:
    # Every loopback client is one address: the per-client cap is raised to test the total.
    server = Server(
        tmp_path / "data", BIOPLAN_MAX_STREAMS=str(TOTAL), BIOPLAN_MAX_STREAMS_PER_CLIENT="100"
    )
    server.start()
    streams: list[RawStream] = []
    try:
        streams = [RawStream(server.port) for _ in range(TOTAL)]
        assert [s.status for s in streams] == [200] * TOTAL
        extra = RawStream(server.port)
        assert extra.status == 429 and "retry-after" in extra.headers
        assert "BIOPLAN_MAX_STREAMS)" in extra.problem()["detail"]
        extra.close()
        took = _health_ok(server)
        print(f"GET /api/health with the total of {TOTAL} streams open: {took:.3f} s")
    finally:
        for s in streams:
            s.close()
        server.cleanup()


def test_an_idle_stream_ends(tmp_path: Path) -> None:
    idle_s = 3.0
    server = Server(tmp_path / "data", BIOPLAN_STREAM_IDLE_S=str(idle_s))
    server.start()
    try:
        idle = RawStream(server.port)
        started = time.monotonic()
        body = idle.read_to_end()
        waited = time.monotonic() - started
        idle.close()
        assert body is not None, "an idle stream stayed open"
        assert b"event: jobs" in body and b"idle" in body
        assert body.endswith(b"0\r\n\r\n")  # ended by the server, as a whole response
        assert waited >= idle_s * 0.9
        print(f"idle stream ended after {waited:.1f} s (BIOPLAN_STREAM_IDLE_S={idle_s:g})")
        again = RawStream(server.port)  # and the client may reconnect at once
        again.close()
        assert again.status == 200
    finally:
        server.cleanup()


def test_every_stream_ends_when_the_server_stops(tmp_path: Path) -> None:
    server = Server(tmp_path / "data")  # streams never idle out during the test
    server.start()
    streams: list[RawStream] = []
    try:
        streams = [RawStream(server.port) for _ in range(4)]
        streams.append(RawStream(server.port, "/api/jobs/1/events"))
        assert [s.status for s in streams] == [200] * 4 + [404]
        streams.pop().close()
        assert server.proc is not None
        stopping = time.monotonic()
        server.proc.send_signal(signal.SIGINT)
        ends = [s.read_to_end(deadline_s=60) for s in streams]
        server.proc.wait(timeout=60)  # the server exits, within a generous deadline
        took = time.monotonic() - stopping
        print(f"server with 4 open streams stopped in {took:.1f} s")
        # Each stream was ended by the server (its last chunk sent), not cut off by uvicorn's
        # graceful-shutdown timeout.
        assert all(end is not None and end.endswith(b"0\r\n\r\n") for end in ends), ends
        log = server.log.read_text()
        assert "timeout graceful shutdown exceeded" not in log, log[-2000:]
    finally:
        for s in streams:
            s.close()
        server.cleanup()


@pytest.mark.skipif(shutil.which("prlimit") is None, reason="needs prlimit (util-linux)")
def test_running_out_of_descriptors_is_logged_once_not_per_attempt(tmp_path: Path) -> None:
    server = Server(tmp_path / "data")
    # A hard limit the server cannot raise: connections run it out of descriptors.
    server.args = ["prlimit", "--nofile=200:200", *server.args]
    server.start()
    held: list[socket.socket] = []
    try:
        before = server.log.stat().st_size
        for _ in range(400):
            sock = socket.create_connection(("127.0.0.1", server.port), timeout=60)
            held.append(sock)
        time.sleep(5)  # accept keeps failing meanwhile
        for sock in held:
            sock.close()
        held.clear()
        deadline = time.monotonic() + 60  # served again once descriptors are free
        while True:
            try:
                took = _health_ok(server)
                break
            except (httpx.HTTPError, AssertionError):
                assert time.monotonic() < deadline, "the server did not recover"
                time.sleep(0.5)
        log = server.log.read_text()
        said = log.count("socket.accept() out of system resource")
        grown = server.log.stat().st_size - before
        print(f"accept failures said {said} times, log grew {grown} bytes; health {took:.3f} s")
        assert 1 <= said <= 3, log[-3000:]
        assert grown < 100_000
    finally:
        for sock in held:
            sock.close()
        server.cleanup()
