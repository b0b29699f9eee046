"""Service benchmarks on loopback (a real ``bioplan serve`` process each time).

1. p50/p99 latency of ``GET /api/recordings`` under 16 concurrent clients (target p99 < 50 ms).
2. A 50 MB CSV upload (4 EMG channels), parsed and stored (target < 5 s).
3. Jobs per minute for a batch of 100 plans, on the local runner and on a 2-worker Dask
   ``LocalCluster`` (scheduler and workers over loopback).
4. ``faults``: SIGKILL the server while a plan and a two-worker sweep run; the time until every
   process it left (fork server, job processes, their group reapers, the sweep's pool) is gone,
   measured from the server's death (target < 2 s), with ``--hogs N`` CPU hogs running.
5. ``make-run``: ``git clone`` this repository into a temporary folder and ``make run``: the time
   until the URL is printed and the page answers (target < 2 min; uv's cache as it is).
6. ``load``: p50/p99 of ``GET /api/recordings`` with 16 and then 64 clients while two 50 MB
   uploads are parsed and a sweep runs (issue 14; target p99 < 100 ms at 16 clients).

    .venv/bin/python benchmarks/bench_api.py [--quick] [--skip-dask] [--json]
    .venv/bin/python benchmarks/bench_api.py --only faults --runs 5 --hogs 2
    .venv/bin/python benchmarks/bench_api.py --only make-run --runs 3
    .venv/bin/python benchmarks/bench_api.py --only load

Numbers depend on the machine; the script prints its CPU count and load with them.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.utils.server import Server, free_port  # noqa: E402


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


# ------------------------------------------------------------------------------------ faults


def _hogs(n: int) -> list[subprocess.Popen[bytes]]:
    """``n`` processes that each keep one CPU busy (stopped by the caller, by pid)."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def _stop(procs: list[subprocess.Popen[bytes]]) -> None:
    for proc in procs:
        proc.kill()
        proc.wait()


def _gone(pid: int) -> bool:
    import psutil

    try:
        return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


def _fault_once(tmp: Path) -> dict[str, Any]:
    """One server killed under a plan and a two-worker sweep: seconds until each is gone."""
    plan = {"robot": "curtain_wall_6dof", "particles": 1000, "iterations": 10000}
    sweep = {"robot": "human_arm_2dof", "durations": [0.6, 0.9, 1.2, 1.5], "payloads": [0, 5],
             "particles": 200, "iterations": 1000, "workers": 2}  # fmt: skip
    server = Server(tmp).start()
    try:
        ids = [server.post(path, json=body).json()["id"]
               for path, body in (("/api/plans", plan), ("/api/sweeps", sweep))]  # fmt: skip
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            running = all(server.get(f"/api/jobs/{i}")["state"] == "running" for i in ids)
            procs = server.descendants()
            pool = [p for p in procs if "multiprocessing.spawn" in " ".join(p.cmdline())]
            if running and len(pool) >= 2:
                break
            time.sleep(0.1)
        else:
            raise RuntimeError("the jobs never ran together")
        # multiprocessing's resource tracker is no job process: it leaves on its own.
        watched = {p.pid for p in procs if "resource_tracker" not in " ".join(p.cmdline())}
        died = server.sigkill()
        left: dict[int, float] = {}
        while len(left) < len(watched) and time.monotonic() - died < 60:
            for pid in watched - set(left):
                if _gone(pid):
                    left[pid] = time.monotonic() - died
            time.sleep(0.002)
    finally:
        server.cleanup()
    return {"processes": len(watched), "all_gone_s": max(left.values(), default=float("nan")),
            "gone_s": sorted(left.values()), "never_gone": len(watched) - len(left)}  # fmt: skip


def bench_faults(*, runs: int, hogs: int) -> dict[str, Any]:
    """Median over ``runs`` of the time until a killed server's processes are all gone."""
    load = _hogs(hogs)
    try:
        time.sleep(1.0 if hogs else 0.0)
        with tempfile.TemporaryDirectory(prefix="bioplan-faults-") as tmp:
            results = [_fault_once(Path(tmp) / f"run{i}") for i in range(runs)]
    finally:
        _stop(load)
    times = [r["all_gone_s"] for r in results]
    return {
        "runs": runs,
        "hogs": hogs,
        "processes": [r["processes"] for r in results],
        "all_gone_s": times,
        "median_all_gone_s": float(np.median(times)),
        "max_all_gone_s": float(np.max(times)),
        "never_gone": sum(r["never_gone"] for r in results),
    }


# ---------------------------------------------------------------------------------- make run


def _make_run_once(tmp: Path) -> dict[str, Any]:
    """``git clone`` + ``make run`` in ``tmp``: seconds to the URL line and to a served page."""
    clone = tmp / "fresh"
    port = free_port()
    env = {**os.environ, "BIOPLAN_PORT": str(port), "BIOPLAN_VIEWER_PORT": str(free_port())}
    env = {k: v for k, v in env.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    t0 = time.monotonic()
    subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], check=True)
    proc = subprocess.Popen(
        ["make", "run"], cwd=clone, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, start_new_session=True,
    )  # fmt: skip
    marks: dict[str, float] = {}
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            now = time.monotonic() - t0
            if line.startswith("==> done:"):
                marks["installed_s"] = now
            if line.startswith("BioPlan dashboard:"):
                marks["url_s"] = now
                page = httpx.get(f"http://127.0.0.1:{port}/", timeout=30)
                marks["page_s"] = time.monotonic() - t0
                marks["page_status"] = page.status_code
                break
    finally:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    if "url_s" not in marks:
        raise RuntimeError("make run never printed the URL")
    return marks


def bench_make_run(*, runs: int) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="bioplan-make-run-") as tmp:
        results = [_make_run_once(Path(tmp) / f"run{i}") for i in range(runs)]
    return {
        "runs": runs,
        "installed_s": [r.get("installed_s") for r in results],
        "url_s": [r["url_s"] for r in results],
        "median_url_s": float(np.median([r["url_s"] for r in results])),
        "median_page_s": float(np.median([r["page_s"] for r in results])),
        "page_status": [r["page_status"] for r in results],
    }


# ------------------------------------------------------------------------------------- main


def bench_service(args: argparse.Namespace) -> dict[str, Any]:
    """Benchmarks 1-3: list latency, upload, jobs per minute (local, then Dask)."""
    n_jobs = 20 if args.quick else 100
    plan_body = {"robot": "human_arm_2dof", "duration": 1.0, "particles": 40, "iterations": 100}
    out: dict[str, Any] = {"plan_request": plan_body}
    with tempfile.TemporaryDirectory(prefix="bioplan-bench-") as tmp:
        server = Server(Path(tmp) / "local", BIOPLAN_MAX_WORKERS="2").start()
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
            out["jobs_dask"] = _jobs_on_dask(Path(tmp) / "dask", n_jobs, plan_body)
    return out


def bench_load(*, seconds: float) -> dict[str, Any]:
    """List latency at 16 and 64 clients while two 50 MB uploads are parsed and a sweep runs
    (the uploads are sent again whenever they finish, so the window is loaded throughout)."""
    import threading

    big = _csv(int(50e6 / 55))
    sweep = {"robot": "curtain_wall_6dof", "durations": [0.8, 1.0, 1.2, 1.4],
             "payloads": [0, 4, 8], "objectives": ["abs_work"]}  # fmt: skip
    out: dict[str, Any] = {"upload_mb": len(big) / 1e6, "sweep": sweep}
    with tempfile.TemporaryDirectory(prefix="bioplan-load-") as tmp:
        server = Server(Path(tmp) / "data", BIOPLAN_MAX_WORKERS="2").start()
        try:
            for clients in (16, 64):
                with httpx.Client(base_url=server.url, timeout=60) as c:
                    job = c.post("/api/sweeps", json=sweep).json()
                stop = threading.Event()
                parsed = [0]

                def uploader(
                    k: int, stop: threading.Event = stop, parsed: list[int] = parsed
                ) -> None:
                    with httpx.Client(base_url=server.url, timeout=600) as c:
                        while not stop.is_set():
                            data = big.replace(b"0,", f"{k},".encode(), 1)
                            r = c.post("/api/recordings", files=[("files", ("big.csv", data))])
                            parsed[0] += r.status_code == 201

                threads = [threading.Thread(target=uploader, args=(k,)) for k in range(2)]
                for t in threads:
                    t.start()
                time.sleep(1.0)  # both uploads under way
                result = bench_list_latency(server, clients=clients, seconds=seconds,
                                            n_recordings=0)  # fmt: skip
                with httpx.Client(base_url=server.url, timeout=60) as c:
                    state = c.get(f"/api/jobs/{job['id']}").json()["state"]
                    c.post(f"/api/jobs/{job['id']}/cancel")
                stop.set()
                for t in threads:
                    t.join(600)
                result.update(uploads_parsed=parsed[0], sweep_state_at_end=state)
                out[f"clients_{clients}"] = result
        finally:
            server.stop()
    return out


def _jobs_on_dask(data: Path, n_jobs: int, plan_body: dict[str, Any]) -> dict[str, Any]:
    from distributed import LocalCluster

    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:  # fmt: skip
        address = cluster.scheduler_address.replace("tcp://", "dask://")
        server = Server(data, BIOPLAN_EXECUTOR=address).start()
        try:
            return bench_jobs(server, n=n_jobs, body=plan_body)
        finally:
            server.stop()


def _print(out: dict[str, Any]) -> None:
    print(f"machine: {out['machine']}")
    for key, lat in out.get("load", {}).items():
        if key.startswith("clients_"):
            print(
                f"load, {lat['clients']} clients listing while 2 x 50 MB uploads parse and a "
                f"sweep runs: p50 {lat['p50_ms']:.1f} ms, p99 {lat['p99_ms']:.1f} ms, max "
                f"{lat['max_ms']:.0f} ms, {lat['requests']} requests, {lat['errors']} errors; "
                f"{lat['uploads_parsed']} uploads parsed, sweep {lat['sweep_state_at_end']}"
            )
    for key in ("list_latency", "list_latency_with_uploads"):
        if key in out:
            lat = out[key]
            print(
                f"GET /api/recordings, {lat['clients']} clients, {lat['uploads_meanwhile']} "
                f"uploads meanwhile: p50 {lat['p50_ms']:.1f} ms, p99 {lat['p99_ms']:.1f} ms "
                f"(target < 50), {lat['requests_per_s']:.0f} req/s, {lat['errors']} errors"
            )
    if "upload_50mb" in out:
        up = out["upload_50mb"]
        print(f"upload {up['megabytes']:.1f} MB CSV ({up['rows']} rows x {up['channels']} "
              f"channels): {up['seconds']:.2f} s (target < 5)")  # fmt: skip
    for key in ("jobs_local", "jobs_dask"):
        if key in out:
            j = out[key]
            print(f"{j['jobs']} plans on {j['executor']} ({j['workers']} workers): "
                  f"{j['seconds']:.1f} s, {j['jobs_per_minute']:.0f} jobs/min, "
                  f"{j['states']}")  # fmt: skip
    if "faults" in out:
        f = out["faults"]
        print(f"server SIGKILLed under a plan and a 2-worker sweep, {f['hogs']} CPU hogs: all "
              f"{f['processes']} processes gone after median {f['median_all_gone_s']:.3f} s, "
              f"max {f['max_all_gone_s']:.3f} s over {f['runs']} runs (target < 2 s); "
              f"never gone: {f['never_gone']}")  # fmt: skip
    if "make_run" in out:
        m = out["make_run"]
        print(f"fresh clone, make run: URL after median {m['median_url_s']:.1f} s, page after "
              f"{m['median_page_s']:.1f} s over {m['runs']} runs {m['url_s']} "
              f"(installed after {m['installed_s']}) (target < 120 s)")  # fmt: skip


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller runs (smoke test)")
    parser.add_argument("--skip-dask", action="store_true", help="leave out the Dask run")
    parser.add_argument(
        "--only",
        choices=("service", "faults", "make-run", "load"),
        default=None,
        help="one benchmark",
    )
    parser.add_argument("--runs", type=int, default=3, help="repetitions (faults, make-run)")
    parser.add_argument("--hogs", type=int, default=2, help="CPU hogs beside the faults runs")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    out: dict[str, Any] = {"machine": {"cpus": os.cpu_count(), "load_1min": os.getloadavg()[0]}}
    if args.only in (None, "service"):
        out.update(bench_service(args))
    if args.only in (None, "faults"):
        out["faults"] = bench_faults(runs=args.runs, hogs=args.hogs)
    if args.only == "make-run":  # slow and it clones: only when asked for
        out["make_run"] = bench_make_run(runs=args.runs)
    if args.only == "load":
        out["load"] = bench_load(seconds=5 if args.quick else 20)
    out["machine"]["load_1min_after"] = os.getloadavg()[0]
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        _print(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
