"""DaskRunner on a real LocalCluster: worker processes, scheduler and workers over loopback."""

from __future__ import annotations

import contextlib
import os
import queue
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from app.errors import BioPlanError
from app.jobs.runner import DaskRunner
from app.logs import MAX_LINES
from app.names import TERMINAL_JOB_STATES as TERMINAL
from tests.utils.data import shared_file
from tests.utils.db import DB_KINDS
from tests.utils.jobs import Collector, log_target, target


@pytest.fixture(scope="module")
def cluster() -> Iterator[Any]:
    from distributed import LocalCluster

    with LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=":0",  # any free port: other test processes may hold 8787
        silence_logs=40,
    ) as c:
        yield c


@pytest.fixture(scope="module")
def runner(cluster: Any) -> Iterator[tuple[DaskRunner, Collector]]:
    sink = Collector()
    r = DaskRunner(cluster.scheduler_address, target=target)
    r.start(sink)
    yield r, sink
    r.shutdown()


def test_scheduler_and_workers_listen_on_loopback(cluster: Any) -> None:
    assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
    workers = cluster.scheduler_info["workers"]
    assert len(workers) == 2
    assert all(addr.startswith("tcp://127.0.0.1:") for addr in workers)


def test_jobs_run_in_worker_processes(runner: tuple[DaskRunner, Collector]) -> None:
    r, sink = runner
    r.submit(1, "echo", {"x": 1})
    r.submit(2, "echo", {"x": 2})
    results = []
    for job_id in (1, 2):
        done = sink.wait_for(job_id, TERMINAL)
        assert done.type == "succeeded"
        assert done.result is not None
        results.append(done.result["result"])
    assert [res["echo"] for res in results] == [{"x": 1}, {"x": 2}]
    assert all(res["pid"] != os.getpid() for res in results)
    assert r.info()["workers"] == 2


def test_progress_and_failure_come_back(runner: tuple[DaskRunner, Collector]) -> None:
    r, sink = runner
    r.submit(3, "count", {"n": 4, "dt": 0.3})
    r.submit(4, "fail", {"why": "no EMG channel"})
    assert sink.wait_for(3, TERMINAL).type == "succeeded"
    assert any(e.type == "started" for e in sink.of(3))
    fractions = [e.progress for e in sink.of(3) if e.type == "progress"]
    assert fractions and fractions == sorted(fractions)
    failed = sink.wait_for(4, TERMINAL)
    assert failed.type == "failed"
    assert failed.error == "bad input: no EMG channel"


def test_cancel_stops_a_running_task(runner: tuple[DaskRunner, Collector], tmp_path: Path) -> None:
    r, sink = runner
    beat = tmp_path / "heartbeat"
    r.submit(5, "sleep", {"seconds": 60, "heartbeat": str(beat)})
    sink.wait_for(5, {"progress"})
    deadline = time.monotonic() + 10
    while not beat.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert beat.exists()
    assert r.cancel(5)
    assert sink.wait_for(5, TERMINAL).type == "cancelled"
    # Dask cannot interrupt a thread: the task stops at its next progress report, after which
    # its heartbeat file no longer changes.
    time.sleep(1.0)
    last = beat.read_text()
    time.sleep(1.0)
    assert beat.read_text() == last, "the cancelled task kept running"


@pytest.fixture(scope="module")
def log_runner(cluster: Any) -> Iterator[tuple[DaskRunner, Collector]]:
    sink = Collector()
    r = DaskRunner(cluster.scheduler_address, target=log_target)
    r.start(sink)
    yield r, sink
    r.shutdown()


def test_a_dask_job_keeps_its_last_lines_as_a_local_one(
    log_runner: tuple[DaskRunner, Collector],
) -> None:
    """The same bound as the local runner's (``app.logs.LogTail``), through worker events and
    the task's return value: lines sent with progress and the rest with the outcome."""
    r, sink = log_runner
    r.submit(11, "plan", {"n": MAX_LINES + 150})
    ev = sink.wait_for(11, {"succeeded", "failed"})
    assert ev.type == "succeeded" and ev.result == {"result": {"n": MAX_LINES + 150}}
    assert ev.log is not None and len(ev.log) == MAX_LINES + 1
    assert "150 earlier line(s) left out" in ev.log[0]
    assert ev.log[1].endswith("INFO bioplan.planning: line 150 of 650")
    assert ev.log[-1].endswith("line 649 of 650")
    assert not any("detail" in line for line in ev.log)  # DEBUG is not kept
    assert all(e.log is None for e in sink.of(11) if e.type != "succeeded")


def test_a_failed_dask_job_logs_its_error_last(log_runner: tuple[DaskRunner, Collector]) -> None:
    r, sink = log_runner
    r.submit(12, "plan", {"n": 3, "fail": "no trajectory in 0.1 s"})
    ev = sink.wait_for(12, {"failed", "succeeded"})
    assert ev.type == "failed" and ev.error == "no trajectory in 0.1 s"
    assert ev.log is not None and [line.split(" ", 1)[1] for line in ev.log] == [
        "INFO bioplan.planning: line 0 of 3",
        "INFO bioplan.planning: line 1 of 3",
        "INFO bioplan.planning: line 2 of 3",
        "ERROR bioplan: job failed: no trajectory in 0.1 s",
    ]


def test_a_cancelled_dask_job_keeps_what_it_said_by_its_last_progress(
    log_runner: tuple[DaskRunner, Collector],
) -> None:
    r, sink = log_runner
    # 100 lines with a progress report after each 50, then it sleeps (a few seconds: Dask
    # cannot interrupt the task's thread, which finishes its sleep on the worker).
    r.submit(13, "plan", {"n": 100, "every": 50, "sleep": 3})
    deadline = time.monotonic() + 60
    while not any(e.detail and e.detail["done"] == 100 for e in sink.of(13)):  # now it sleeps
        assert time.monotonic() < deadline, sink.of(13)
        with contextlib.suppress(queue.Empty):
            sink.seen.append(sink.events.get(timeout=0.1))
    assert r.cancel(13)
    ev = sink.wait_for(13, {"cancelled", "succeeded"})
    assert ev.type == "cancelled"
    assert ev.log is not None and len(ev.log) == 100
    assert ev.log[-1].endswith("line 99 of 100")


@pytest.mark.parametrize("db_kind", DB_KINDS)
def test_real_plan_and_analysis_jobs_through_the_api_on_dask(
    cluster: Any, tmp_path: Path, db_kind: str
) -> None:
    """The compose configuration without Docker: API + Dask cluster (+ PostgreSQL when set)."""
    from app.db.crud import json_safe
    from app.planning import load_robot, plan
    from tests.utils.api import make_client, read_sse, wait_job

    address = cluster.scheduler_address.replace("tcp://", "dask://")
    with make_client(tmp_path, executor=address, db_kind=db_kind) as client:
        health = client.get("/api/health").json()
        assert health["executor"] == address and health["workers"] == 2
        body = {"robot": "human_arm_2dof", "duration": 1.2, "seed": 5, "particles": 8,
                "iterations": 5, "methods": ["quintic", "paper"]}  # fmt: skip
        job = client.post("/api/plans", json=body).json()
        done = wait_job(client, job["id"])
        assert done["state"] == "succeeded", done
        got = client.get(done["result_url"]).json()["result"]
        ref = json_safe(
            plan(
                load_robot("human_arm_2dof"), duration=1.2, seed=5, particles=8, iterations=5
            ).to_dict()
        )
        for key in ("standard", "optimized", "floors", "improvement_pct"):
            assert got[key] == ref[key]

        # A sweep fans out one Dask task per cell (the job submits them from its own task),
        # reports per-cell progress, and both workers run cells.
        sweep = {"robot": "human_arm_2dof", "durations": [0.8, 1.0, 1.2], "payloads": [0, 5],
                 "particles": 6, "iterations": 4, "workers": 2,
                 "methods": ["quintic", "paper"]}  # fmt: skip
        job = client.post("/api/sweeps", json=sweep).json()
        events = read_sse(client, job["events_url"])
        assert events[-1][1]["state"] == "succeeded", events[-1]
        # Per-cell progress reaches the API (intermediate updates may be merged on a busy
        # machine, but the last one before success is always published).
        cells = [e for _, e in events if e["stage"] == "sweep" and e["of"] == 6]
        done = [e["done"] for e in cells]
        assert any(1 <= d <= 6 for d in done) and done == sorted(done), events
        result = client.get(job["result_url"]).json()["result"]
        assert len(result["cells"]) == 6
        used = result["conditions"]["cells_per_worker"]
        assert set(used) == set(cluster.scheduler_info["workers"]), used
        assert sum(used.values()) == 6

        path = shared_file("noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv")
        rec = client.post(
            "/api/recordings", files=[("files", (path.name, path.read_bytes()))]
        ).json()
        job = client.post("/api/analyses", json={"recording_id": rec["id"]}).json()
        done = wait_job(client, job["id"])
        assert done["state"] == "succeeded", done
        assert client.get(f"/api/analyses/{job['id']}/template").json()["source"]


def test_run_sweep_on_dask_equals_the_local_pool_and_uses_both_workers(cluster: Any) -> None:
    """The library's executor: one task per cell on the cluster, the same cells as locally."""
    from app.planning import load_robot
    from app.simulation import run_sweep

    grid = {"durations": [0.8, 1.2], "payloads": [0.0, 4.0, 8.0], "particles": 6,
            "iterations": 4, "methods": ["quintic", "paper"], "seed": 1}  # fmt: skip
    robot = load_robot("human_arm_2dof")
    seen: list[int] = []
    address = cluster.scheduler_address.replace("tcp://", "dask://")
    on_dask = run_sweep(
        robot=robot, executor=address, progress=lambda p: seen.append(p.done), **grid
    )
    local = run_sweep(robot=robot, workers=1, **grid)
    assert on_dask.conditions["executor"] == address
    used = on_dask.conditions["cells_per_worker"]
    assert set(used) == set(cluster.scheduler_info["workers"]) and sum(used.values()) == 6
    assert seen[-1] == 6 and sorted(seen) == seen  # per-cell progress, in order
    for a, b in zip(on_dask.cells, local.cells, strict=True):
        assert (a.duration, a.payload, a.status) == (b.duration, b.payload, b.status)
        assert a.change_pct == b.change_pct
    with pytest.raises(BioPlanError, match="executor"):
        run_sweep(robot=robot, executor="spark://x", **grid)


def test_cli_sweep_executor(cluster: Any, capsys: pytest.CaptureFixture[str]) -> None:
    """``bioplan sweep --executor dask://HOST:PORT`` runs the cells on that cluster."""
    import json

    from app.cli import main

    address = cluster.scheduler_address.replace("tcp://", "dask://")
    args = ["sweep", "--robot", "human_arm_2dof", "--durations", "0.8,1.2", "--payloads", "0",
            "--particles", "6", "--iterations", "4", "--method", "quintic,paper",
            "--json"]  # fmt: skip
    assert main([*args, "--executor", address]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["conditions"]["executor"] == address
    assert sum(data["conditions"]["cells_per_worker"].values()) == 2
    assert set(data["conditions"]["cells_per_worker"]) <= set(cluster.scheduler_info["workers"])
    assert main([*args, "--executor", "yarn://x"]) == 2
    err = capsys.readouterr().err.strip()
    assert "yarn://x" in err and len(err.splitlines()) == 1
