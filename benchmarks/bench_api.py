"""Service benchmarks on loopback (a real ``bioplan serve`` process each time).

1. p50/p99 latency of ``GET /api/recordings`` under 16 concurrent clients (target p99 < 50 ms).
2. A 50 MB CSV upload (4 EMG channels), parsed and stored (target < 5 s).
3. Jobs per minute for a batch of 100 plans, on the local runner and on a 2-worker Dask
   ``LocalCluster`` (scheduler and workers over loopback).

    .venv/bin/python benchmarks/bench_api.py [--quick] [--skip-dask] [--json]

Numbers depend on the machine; the script prints its CPU count and load with them.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np

REPO = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


class Server:
    """``python -m app.cli serve`` on a free loopback port, in its own process group."""

    def __init__(self, data_dir: Path, **env: str) -> None:
        self.port = _free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        environ = {**os.environ, "BIOPLAN_LOG_LEVEL": "warning", **env}
        environ.pop("BIOPLAN_API_TOKEN", None)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "app.cli", "serve", "--port", str(self.port),
             "--data-dir", str(data_dir)],
            cwd=REPO, env=environ, start_new_session=True,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            try:
                if httpx.get(self.url + "/api/health", timeout=1).status_code == 200:
                    return
            except httpx.HTTPError:
                time.sleep(0.1)
        self.stop()
        raise RuntimeError("server did not start")

    def stop(self) -> None:
        try:
            os.killpg(self.proc.pid, signal.SIGTERM)
            self.proc.wait(timeout=15)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(timeout=10)


def _csv(rows: int, rate: float = 2000.0) -> bytes:
    rng = np.random.default_rng(0)
    t = np.arange(rows) / rate
    emg = rng.normal(0, 1e-4, size=(rows, 4))
    lines = [b"time,deltoid,triceps,biceps,forearm\n"]
    block = 100_000
    for i in range(0, rows, block):
        chunk = np.column_stack([t[i : i + block], emg[i : i + block]])
        lines.append("\n".join(",".join(f"{v:.7g}" for v in row) for row in chunk).encode())
        lines.append(b"\n")
    return b"".join(lines)


def bench_list_latency(
    server: Server, *, clients: int, seconds: float, n_recordings: int, writes_per_s: float = 0
) -> dict[str, Any]:
    """Latency of the recordings list; ``writes_per_s`` uploads meanwhile (each one drops the
    server's cached pages, so most reads then hit the database)."""
    small = _csv(2000)
    with httpx.Client(base_url=server.url, timeout=30) as c:
        have = c.get("/api/recordings").json()["total"]
        for i in range(have, n_recordings):
            r = c.post("/api/recordings", files=[("files", (f"r{i}.csv", small))],
                       data={"subject": f"s{i % 5}", "task": "curl"})  # fmt: skip
            r.raise_for_status()
    # 16 clients, each with its own keep-alive connection, driven by one asyncio loop: the
    # client side costs as little CPU as possible on the same (2-core) machine.
    latencies: list[float] = []
    errors = [0]

    async def client_loop(stop: float) -> None:
        async with httpx.AsyncClient(base_url=server.url, timeout=30) as c:
            while time.monotonic() < stop:
                t0 = time.perf_counter()
                r = await c.get("/api/recordings", params={"limit": 50})
                latencies.append(time.perf_counter() - t0)
                if r.status_code != 200:
                    errors[0] += 1

    writes = [0]

    async def writer(stop: float) -> None:
        async with httpx.AsyncClient(base_url=server.url, timeout=30) as c:
            while time.monotonic() < stop:
                await asyncio.sleep(1 / writes_per_s)
                r = await c.post("/api/recordings", files=[("files", ("w.csv", small))])
                writes[0] += r.status_code == 201

    async def run() -> float:
        t0 = time.monotonic()
        tasks = [client_loop(t0 + seconds) for _ in range(clients)]
        if writes_per_s > 0:
            tasks.append(writer(t0 + seconds))
        await asyncio.gather(*tasks)
        return time.monotonic() - t0

    wall = asyncio.run(run())
    lat = np.array(latencies) * 1000
    return {
        "clients": clients,
        "recordings": n_recordings,
        "uploads_meanwhile": writes[0],
        "requests": len(lat),
        "errors": errors[0],
        "requests_per_s": len(lat) / wall,
        "p50_ms": float(np.percentile(lat, 50)),
        "p99_ms": float(np.percentile(lat, 99)),
        "max_ms": float(lat.max()),
    }


def bench_upload(server: Server, *, megabytes: float) -> dict[str, Any]:
    rows = int(megabytes * 1e6 / 55)  # about 55 bytes per row
    data = _csv(rows)
    with httpx.Client(base_url=server.url, timeout=300) as c:
        t0 = time.perf_counter()
        r = c.post("/api/recordings", files=[("files", ("big.csv", data))])
        seconds = time.perf_counter() - t0
        r.raise_for_status()
        rec = r.json()
    channels = rec["files"][0]["channels"]
    return {
        "megabytes": len(data) / 1e6,
        "rows": rows,
        "channels": len(channels),
        "samples_stored": sum(ch["n_samples"] for ch in channels),
        "seconds": seconds,
    }


def bench_jobs(server: Server, *, n: int, body: dict[str, Any]) -> dict[str, Any]:
    with httpx.Client(base_url=server.url, timeout=60) as c:
        t0 = time.monotonic()
        ids = [c.post("/api/plans", json={**body, "seed": i}).json()["id"] for i in range(n)]
        pending = set(ids)
        states: dict[str, int] = {}
        while pending:
            time.sleep(0.25)
            page = c.get("/api/jobs", params={"kind": "plan", "limit": 500}).json()["items"]
            for job in page:
                if job["id"] in pending and job["state"] in ("succeeded", "failed", "cancelled"):
                    pending.discard(job["id"])
                    states[job["state"]] = states.get(job["state"], 0) + 1
        wall = time.monotonic() - t0
        info = c.get("/api/health").json()
    return {
        "jobs": n,
        "executor": info["executor"],
        "workers": info["workers"],
        "seconds": wall,
        "jobs_per_minute": 60 * n / wall,
        "states": states,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller runs (smoke test)")
    parser.add_argument("--skip-dask", action="store_true")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    n_jobs = 20 if args.quick else 100
    plan_body = {"robot": "human_arm_2dof", "duration": 1.0, "particles": 40, "iterations": 100}
    out: dict[str, Any] = {
        "machine": {"cpus": os.cpu_count(), "load_1min": os.getloadavg()[0]},
        "plan_request": plan_body,
    }
    with tempfile.TemporaryDirectory(prefix="bioplan-bench-") as tmp:
        server = Server(Path(tmp) / "local", BIOPLAN_MAX_WORKERS="2")
        try:
            secs = 3 if args.quick else 10
            out["list_latency"] = bench_list_latency(
                server, clients=16, seconds=secs, n_recordings=50
            )
            out["list_latency_with_uploads"] = bench_list_latency(
                server, clients=16, seconds=secs, n_recordings=50, writes_per_s=5
            )
            out["upload_50mb"] = bench_upload(server, megabytes=5 if args.quick else 50)
            out["jobs_local"] = bench_jobs(server, n=n_jobs, body=plan_body)
        finally:
            server.stop()
        if not args.skip_dask:
            from distributed import LocalCluster

            with LocalCluster(
                n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                dashboard_address=None,
            ) as cluster:  # fmt: skip
                address = cluster.scheduler_address.replace("tcp://", "dask://")
                server = Server(Path(tmp) / "dask", BIOPLAN_EXECUTOR=address)
                try:
                    out["jobs_dask"] = bench_jobs(server, n=n_jobs, body=plan_body)
                finally:
                    server.stop()
    out["machine"]["load_1min_after"] = os.getloadavg()[0]
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    up = out["upload_50mb"]
    print(f"machine: {out['machine']}")
    for key in ("list_latency", "list_latency_with_uploads"):
        lat = out[key]
        print(f"GET /api/recordings, {lat['clients']} clients, {lat['uploads_meanwhile']} uploads "
              f"meanwhile: p50 {lat['p50_ms']:.1f} ms, p99 {lat['p99_ms']:.1f} ms (target < 50), "
              f"{lat['requests_per_s']:.0f} req/s, {lat['errors']} errors")  # fmt: skip
    print(f"upload {up['megabytes']:.1f} MB CSV ({up['rows']} rows x {up['channels']} channels): "
          f"{up['seconds']:.2f} s (target < 5)")  # fmt: skip
    for key in ("jobs_local", "jobs_dask"):
        if key in out:
            j = out[key]
            print(f"{j['jobs']} plans on {j['executor']} ({j['workers']} workers): "
                  f"{j['seconds']:.1f} s, {j['jobs_per_minute']:.0f} jobs/min, "
                  f"{j['states']}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
