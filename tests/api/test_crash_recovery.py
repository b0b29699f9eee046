"""SIGKILL a real server (``bioplan serve`` under uvicorn) during an upload and during a job.

After a restart on the same data folder: no partial recording (all of it or none), no stray
file, no job left running; the killed server's job processes stop on their own.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import psutil
import pytest

from app.jobs.tasks import entry_points
from tests.conftest import REPO_ROOT, shared_file

NORAXON = "noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


class Server:
    """``python -m app.cli serve`` in its own session, on a free loopback port."""

    def __init__(self, data_dir: Path, **env: str) -> None:
        self.data_dir = data_dir
        self.env = {**os.environ, "BIOPLAN_LOG_LEVEL": "warning", **env}
        self.env.pop("BIOPLAN_API_TOKEN", None)
        self.proc: subprocess.Popen[bytes] | None = None
        self.url = ""

    def start(self) -> Server:
        port = _free_port()
        self.url = f"http://127.0.0.1:{port}"
        cmd = [sys.executable, "-m", "app.cli", "serve", "--port", str(port)]
        self.proc = subprocess.Popen(
            [*cmd, "--data-dir", str(self.data_dir)],
            cwd=REPO_ROOT,
            env=self.env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,  # its own process group: cleanup below kills only ours
        )
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            assert self.proc.poll() is None, "server exited during start-up"
            try:
                if httpx.get(f"{self.url}/api/health", timeout=1).status_code == 200:
                    return self
            except httpx.HTTPError:
                pass
            time.sleep(0.1)
        raise AssertionError("server did not start")

    def descendants(self) -> list[psutil.Process]:
        assert self.proc is not None
        return psutil.Process(self.proc.pid).children(recursive=True)

    def sigkill(self) -> None:
        assert self.proc is not None
        self.proc.send_signal(signal.SIGKILL)  # the server only, not its children
        self.proc.wait(timeout=10)

    def cleanup(self) -> None:
        if self.proc is not None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(timeout=10)

    def get(self, path: str, **kw: Any) -> Any:
        return httpx.get(self.url + path, timeout=30, **kw).json()


@pytest.fixture
def servers(tmp_path: Path) -> Iterator[list[Server]]:
    started: list[Server] = []
    yield started
    for s in started:
        s.cleanup()


def _gone(procs: list[psutil.Process], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        alive = [p for p in procs if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        if not alive:
            return True
        time.sleep(0.1)
    return False


def _stored_files(data_dir: Path) -> list[Path]:
    return [p for p in (data_dir / "blobs").rglob("*") if p.is_file()]


def _rows(data_dir: Path, table: str) -> int:
    with sqlite3.connect(data_dir / "bioplan.db") as db:
        n: int = db.execute(f"SELECT count(*) FROM {table}").fetchone()[0]
        return n


def test_sigkill_during_uploads_leaves_all_or_nothing(
    servers: list[Server], tmp_path: Path
) -> None:
    data_dir = tmp_path / "data"
    real = shared_file(NORAXON).read_bytes()

    server = Server(data_dir).start()
    servers.append(server)
    boundary = "crash-test"
    head = (
        f'--{boundary}\r\nContent-Disposition: form-data; name="files"; filename="a.csv"\r\n'
        "Content-Type: text/csv\r\n\r\n"
    ).encode()
    streaming = threading.Event()
    outcomes: list[int | None] = []

    def slow_body() -> Iterator[bytes]:
        yield head
        for i in range(0, len(real), 8192):
            yield real[i : i + 8192]
            if i > 3 * 8192:
                streaming.set()
            time.sleep(0.05)
        yield f"\r\n--{boundary}--\r\n".encode()

    def slow_upload() -> None:
        # Still streaming when the server dies.
        with contextlib.suppress(httpx.HTTPError):
            httpx.post(
                server.url + "/api/recordings",
                content=slow_body(),
                headers={"Content-Type": f"multipart/form-data; boundary={boundary}"},
                timeout=30,
            )

    def full_uploads() -> None:
        # Whole bodies, one after the other until the server dies: some are stored, the last
        # is cut while it is parsed or stored.
        for i in range(1000):
            try:
                r = httpx.post(
                    server.url + "/api/recordings",
                    files=[("files", (f"r{i}.csv", real))],
                    data={"subject": f"s{i}"},
                    timeout=30,
                )
                outcomes.append(r.status_code)
            except httpx.HTTPError:
                outcomes.append(None)
                return

    threads = [threading.Thread(target=slow_upload), threading.Thread(target=full_uploads)]
    for th in threads:
        th.start()
    assert streaming.wait(20)
    deadline = time.monotonic() + 20
    while 201 not in outcomes and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.1)  # into the next upload
    server.sigkill()
    for th in threads:
        th.join(30)

    server = Server(data_dir).start()
    servers.append(server)
    page = server.get("/api/recordings")
    # A 201 is sent after the commit: those recordings must be there; the one cut short may
    # or may not be (its commit may have happened before the response); never the slow one.
    stored = outcomes.count(201)
    assert stored >= 1 and outcomes[-1] is None
    assert stored <= page["total"] <= stored + 1
    n_channels = 0
    for item in page["items"]:  # every recording that exists is whole
        rec = server.get(f"/api/recordings/{item['id']}")
        (f,) = rec["files"]
        assert f["size"] == len(real)
        assert httpx.get(f"{server.url}/api/recordings/{rec['id']}/files/{f['id']}").content == real
        assert [c["n_samples"] for c in f["channels"]] == [24600]
        n_channels += 1
    # Nothing half-written: no row without its parent, no file without a row.
    assert _rows(data_dir, "recording_files") == page["total"]
    assert _rows(data_dir, "channels") == n_channels
    assert len(_stored_files(data_dir)) == (1 if page["total"] else 0)  # same bytes, one blob


@pytest.mark.skipif(not entry_points()["plan"], reason="app.planning.plan missing")
def test_sigkill_during_a_job_reruns_then_fails_it(servers: list[Server], tmp_path: Path) -> None:
    data_dir = tmp_path / "data"
    body = {"robot": "curtain_wall_6dof", "duration": 1.0, "particles": 1000,
            "iterations": 10000, "n_samples": 2000}  # fmt: skip

    def run_until_running(server: Server, job_id: int) -> list[psutil.Process]:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            job = server.get(f"/api/jobs/{job_id}")
            if job["state"] == "running":
                return server.descendants()
            time.sleep(0.05)
        raise AssertionError(f"job never ran: {job}")

    server = Server(data_dir).start()
    servers.append(server)
    job = httpx.post(server.url + "/api/plans", json=body, timeout=30).json()
    children = run_until_running(server, job["id"])
    assert children, "no job process"
    server.sigkill()
    # With its server gone, the job process (and the fork server) stop by themselves.
    assert _gone(children, timeout=10), [p.pid for p in children if p.is_running()]

    server = Server(data_dir).start()  # attempt 1 was interrupted: it runs again
    servers.append(server)
    children = run_until_running(server, job["id"])
    again = server.get(f"/api/jobs/{job['id']}")
    assert again["attempts"] == 2
    server.sigkill()
    assert _gone(children, timeout=10)

    server = Server(data_dir).start()  # no attempts left: failed, with the reason
    servers.append(server)
    final = server.get(f"/api/jobs/{job['id']}")
    assert final["state"] == "failed"
    assert "server stopped while this job was running" in final["error"]
    assert server.get("/api/jobs", params={"state": "running"})["total"] == 0
