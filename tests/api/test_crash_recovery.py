"""SIGKILL a real server (``bioplan serve`` under uvicorn) during an upload and during jobs.

After a restart on the same data folder: no partial recording (all of it or none), no stray
file, no job left running. The killed server's fork server, job processes and the worker
processes a job started are killed by the kernel when the server dies (``app.jobs._lifeline``):
this test is their child subreaper and reads how each one ended. How fast that is on a busy
machine is measured by ``benchmarks/bench_api.py --only faults``, not asserted here.
"""

from __future__ import annotations

import contextlib
import sqlite3
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import psutil
import pytest

from tests.utils.data import shared_file
from tests.utils.reaper import reap, subreaper
from tests.utils.server import Server

NORAXON = "noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv"

#: The jobs here must run long enough to be killed: lift the per-request caps (issue 14 item 8).
LONG_JOBS = {"BIOPLAN_MAX_PARTICLES": "1000", "BIOPLAN_MAX_ITERATIONS": "10000"}


@pytest.fixture
def servers() -> Iterator[list[Server]]:
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


def _upload_until_killed(server: Server, real: bytes) -> list[int | None]:
    """Upload ``real`` over and over, and once more slowly, then SIGKILL the server mid-way.

    Returns:
        The status of each whole upload, in order (None: cut off by the kill).
    """
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
                timeout=120,
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
                    timeout=120,
                )
                outcomes.append(r.status_code)
            except httpx.HTTPError:
                outcomes.append(None)
                return

    threads = [threading.Thread(target=slow_upload), threading.Thread(target=full_uploads)]
    for th in threads:
        th.start()
    assert streaming.wait(120)
    deadline = time.monotonic() + 120
    while 201 not in outcomes and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.1)  # into the next upload
    server.sigkill()
    for th in threads:
        th.join(120)
    return outcomes


def test_sigkill_during_uploads_leaves_all_or_nothing(
    servers: list[Server], tmp_path: Path
) -> None:
    data_dir = tmp_path / "data"
    real = shared_file(NORAXON).read_bytes()
    servers.append(server := Server(data_dir, **LONG_JOBS).start())
    outcomes = _upload_until_killed(server, real)

    servers.append(server := Server(data_dir, **LONG_JOBS).start())
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
        raw = httpx.get(f"{server.url}/api/recordings/{rec['id']}/files/{f['id']}", timeout=60)
        assert raw.content == real
        assert [c["n_samples"] for c in f["channels"]] == [24600]
        n_channels += 1
    # Nothing half-written: no row without its parent, no file without a row.
    assert _rows(data_dir, "recording_files") == page["total"]
    assert _rows(data_dir, "channels") == n_channels
    assert len(_stored_files(data_dir)) == (1 if page["total"] else 0)  # same bytes, one blob


def test_sigkill_during_a_job_reruns_then_fails_it(servers: list[Server], tmp_path: Path) -> None:
    data_dir = tmp_path / "data"
    body = {"robot": "curtain_wall_6dof", "duration": 1.0, "particles": 1000,
            "iterations": 10000, "n_samples": 2000}  # fmt: skip

    def run_until_running(server: Server, job_id: int) -> list[psutil.Process]:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            job = server.get(f"/api/jobs/{job_id}")
            if job["state"] == "running":
                return server.descendants()
            time.sleep(0.05)
        raise AssertionError(f"job never ran: {job}")

    server = Server(data_dir, **LONG_JOBS).start()
    servers.append(server)
    job = httpx.post(server.url + "/api/plans", json=body, timeout=30).json()
    children = run_until_running(server, job["id"])
    assert children, "no job process"
    server.sigkill()
    # With its server gone, the job process (and the fork server) stop.
    assert _gone(children, timeout=60), [p.pid for p in children if p.is_running()]

    server = Server(data_dir, **LONG_JOBS).start()  # attempt 1 was interrupted: it runs again
    servers.append(server)
    children = run_until_running(server, job["id"])
    again = server.get(f"/api/jobs/{job['id']}")
    assert again["attempts"] == 2
    server.sigkill()
    assert _gone(children, timeout=60)

    server = Server(data_dir, **LONG_JOBS).start()  # no attempts left: failed, with the reason
    servers.append(server)
    final = server.get(f"/api/jobs/{job['id']}")
    assert final["state"] == "failed"
    assert "server stopped while this job was running" in final["error"]
    assert server.get("/api/jobs", params={"state": "running"})["total"] == 0


def _command(process: psutil.Process) -> str:
    """A process's command line; "" for one that has just ended (a zombie until its parent,
    perhaps this test as the subreaper, collects it)."""
    try:
        return " ".join(process.cmdline())
    except psutil.Error:
        return ""


def _running_with_pool(server: Server, plan_id: int, sweep_id: int) -> list[psutil.Process]:
    """The server's descendants once the plan runs and the sweep's pool workers exist."""
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        states = {server.get(f"/api/jobs/{i}")["state"] for i in (plan_id, sweep_id)}
        procs = server.descendants()
        workers = [p for p in procs if "multiprocessing.spawn" in _command(p)]
        if states == {"running"} and len(workers) >= 2:
            return procs
        assert states <= {"queued", "running"}, states
        time.sleep(0.1)
    raise AssertionError("the plan and the sweep's pool never ran together")


def test_a_killed_servers_job_processes_are_killed_with_it(
    servers: list[Server], tmp_path: Path
) -> None:
    """SIGKILL the server while a plan and a two-worker sweep run: the fork server, both job
    processes, their group reapers and the sweep's pool workers all end by SIGKILL (sent by the
    kernel or the reaper when their parent died), none by finishing or polling on its own."""
    plan = {"robot": "curtain_wall_6dof", "particles": 1000, "iterations": 10000,
            "n_samples": 2000}  # fmt: skip
    sweep = {"robot": "human_arm_2dof", "durations": [0.6, 0.9, 1.2, 1.5], "payloads": [0, 5, 10],
             "particles": 200, "iterations": 1000, "workers": 2}  # fmt: skip
    with subreaper():
        server = Server(tmp_path / "data", **LONG_JOBS).start()
        servers.append(server)
        plan_id = server.post("/api/plans", json=plan).json()["id"]
        sweep_id = server.post("/api/sweeps", json=sweep).json()["id"]
        procs = _running_with_pool(server, plan_id, sweep_id)
        # multiprocessing's resource tracker is no job process: it exits on its own.
        # A process that has already ended (a zombie awaiting collection) is not tracked.
        tracked = {p.pid: command for p in procs if (command := _command(p))}
        died = server.sigkill()
        endings = reap(tracked, died, timeout=120)
    assert set(endings) == set(tracked), {p: tracked[p] for p in set(tracked) - set(endings)}
    for pid, ending in endings.items():
        if "resource_tracker" in tracked[pid]:
            continue
        assert ending.killed, (tracked[pid], ending)
    times = sorted(round(e.after, 3) for e in endings.values())
    print(f"descendants reaped {times} s after the server died")  # evidence in the log
