"""``bioplan serve`` / ``bioplan submit`` against a real server, and live SSE over HTTP."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from app.cli.serve import serve
from tests.utils.data import shared_file
from tests.utils.server import Server, free_port


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    s = Server(tmp_path_factory.mktemp("cli") / "data").start()
    yield s
    s.cleanup()


def bioplan(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_a_busy_port_is_one_line_naming_the_port_and_the_option(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        out = bioplan("serve", "--port", str(port), "--data-dir", str(tmp_path / "d"))
    assert out.returncode == 2, out.stderr
    errors = [line for line in out.stderr.splitlines() if "error" in line]
    assert errors == [
        f"bioplan serve: error: port {port} on 127.0.0.1 is already in use: "
        "choose another with --port or BIOPLAN_PORT"
    ]
    assert out.stdout == ""
    assert not (tmp_path / "d").exists()  # nothing was started, migrated or written


def test_a_second_server_on_the_same_data_directory_refuses_naming_the_first(
    server: Server,
) -> None:
    """Issue 14: a second server on one folder deleted the first's uncommitted files and re-ran
    its jobs. Now it refuses before migrating or cleaning anything, naming the first's pid."""
    csv = shared_file("noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv")
    with csv.open("rb") as f:
        up = server.post("/api/recordings", files={"files": (csv.name, f)}, data={"subject": "s"})
    assert up.status_code == 201, up.text
    stored = sorted(p.name for p in (server.data_dir).rglob("*") if p.is_file())
    out = bioplan("serve", "--port", str(free_port()), "--data-dir", str(server.data_dir))
    assert out.returncode == 2, out.stderr
    errors = [line for line in out.stderr.splitlines() if "error" in line]
    assert len(errors) == 1 and f"is in use by process {server.pid}" in errors[0], errors
    assert "--data-dir or BIOPLAN_DATA_DIR" in errors[0]
    assert sorted(p.name for p in (server.data_dir).rglob("*") if p.is_file()) == stored
    rec = up.json()
    file_id = rec["files"][0]["id"]
    blob = httpx.get(f"{server.url}/api/recordings/{rec['id']}/files/{file_id}", timeout=60)
    assert blob.status_code == 200 and blob.content == csv.read_bytes()


def test_an_unreachable_database_is_one_line_without_its_password(tmp_path: Path) -> None:
    env = {**os.environ, "BIOPLAN_DATABASE_URL": "postgresql+psycopg://u:s3cret@127.0.0.1:9/x"}
    out = subprocess.run(
        [sys.executable, "-m", "app.cli", "serve", "--port", str(free_port())],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert out.returncode == 1, out.stderr
    assert "s3cret" not in out.stderr and "u:***@127.0.0.1:9/x" in out.stderr
    errors = [line for line in out.stderr.splitlines() if "error" in line]
    assert len(errors) == 1 and errors[0].startswith(
        "bioplan serve: error: cannot use the database"
    )
    assert out.stdout == ""


def test_serve_json_prints_one_object_once_the_server_answers(tmp_path: Path) -> None:
    port, viewer_port = free_port(), free_port()
    env = {**os.environ, "BIOPLAN_VIEWER_PORT": str(viewer_port), "BIOPLAN_LOG_LEVEL": "info"}
    env.pop("BIOPLAN_VIEWER", None)  # the viewer runs (and prints its banner elsewhere)
    args = [sys.executable, "-m", "app.cli", "serve", "--json", "--port", str(port)]
    proc = subprocess.Popen(
        [*args, "--data-dir", str(tmp_path / "data")],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        start_new_session=True,
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()  # blocks until the server prints
        # Printed only after the server answered: it answers now, without any wait.
        assert httpx.get(f"http://127.0.0.1:{port}/api/health", timeout=10).status_code == 200
        ready = json.loads(line)
        assert ready == {
            "url": f"http://127.0.0.1:{port}/",
            "viewer": {
                "enabled": True,
                "url": f"http://127.0.0.1:{viewer_port}",
                "host": "127.0.0.1",
                "port": viewer_port,
            },
        }
        assert httpx.get(ready["url"], timeout=10).text.startswith("<!doctype html>")
    finally:
        proc.terminate()
        out, _ = proc.communicate(timeout=60)
    assert out == ""  # exactly one JSON object on stdout


def test_serve_refuses_an_open_bind_without_token(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.delenv("BIOPLAN_API_TOKEN", raising=False)
    assert serve(host="0.0.0.0", port=8123) == 2
    assert "BIOPLAN_API_TOKEN" in capsys.readouterr().err


def test_submit_plan_prints_the_cli_json(server: Server) -> None:
    out = bioplan("submit", "--server", server.url, "--json", "plan", "--robot", "human_arm_2dof",
                  "--particles", "8", "--iterations", "5", "--seed", "1")  # fmt: skip
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    jobs = server.get("/api/jobs", params={"kind": "plan"})
    latest = server.get(jobs["items"][0]["result_url"])
    assert result == latest["result"]
    assert set(result) >= {"standard", "optimized", "floors", "improvement_pct", "optimizer"}
    assert latest["job"]["params"]["seed"] == 1


def test_submit_analyze_uploads_and_writes_the_template(server: Server, tmp_path: Path) -> None:
    path = shared_file("noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv")
    target = tmp_path / "template.json"
    out = bioplan("submit", "--server", server.url, "--out", str(target), "analyze", str(path),
                  "--subject", "s07", "--load-kg", "12")  # fmt: skip
    assert out.returncode == 0, out.stderr
    recs = server.get("/api/recordings", params={"subject": "s07"})
    assert recs["total"] == 1 and recs["items"][0]["load_kg"] == 12
    analyses = server.get("/api/analyses")
    template = server.get(f"/api/analyses/{analyses['items'][0]['id']}/template")
    assert json.loads(target.read_text()) == template


def test_submit_bad_input_exits_2(server: Server) -> None:
    out = bioplan("submit", "--server", server.url, "plan", "--robot", "nope")
    assert out.returncode == 2
    assert "unknown robot 'nope'" in out.stderr and "robot" in out.stderr
    out = bioplan("submit", "--server", "http://127.0.0.1:9", "plan")
    assert out.returncode == 1 and "cannot reach" in out.stderr


def test_sse_streams_while_the_job_runs(server: Server) -> None:
    body = {"robot": "curtain_wall_6dof", "particles": 400, "iterations": 2000,
            "n_samples": 1000}  # fmt: skip
    job = httpx.post(server.url + "/api/plans", json=body, timeout=30).json()
    seen, names = [], []
    cancelled = False
    t0 = time.monotonic()
    with httpx.stream("GET", server.url + job["events_url"], timeout=60) as r:
        assert r.headers["content-type"].startswith("text/event-stream")
        for line in r.iter_lines():
            if line.startswith("event: "):
                names.append(line.removeprefix("event: "))
            elif line.startswith("data: "):
                ev = json.loads(line.removeprefix("data: "))
                seen.append(ev)
                if names[-1] == "done":
                    break
                if not cancelled and ev["state"] == "running" and ev["progress"] > 0:
                    # Live: updates arrive while the job runs; cancelling ends the stream.
                    url = f"{server.url}/api/jobs/{job['id']}/cancel"
                    assert httpx.post(url).status_code == 200
                    cancelled = True
    assert time.monotonic() - t0 < 60
    assert any(e["state"] == "running" and 0 < e["progress"] < 1 for e in seen)
    assert cancelled and names[-1] == "done" and seen[-1]["state"] == "cancelled"
