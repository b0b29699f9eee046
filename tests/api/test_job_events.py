"""Issue 15 item 4: every job's changes as one Server-Sent Events stream (the job drawer).

Against a real ``bioplan serve``, because the stream never ends and an HTTP client must be able
to hang up on it: the snapshot comes first, then each job's changes from queued to its end, for
jobs submitted and cancelled by other clients."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from tests.utils.server import Server

TINY = {
    "robot": "human_arm_2dof",
    "particles": 8,
    "iterations": 5,
    "methods": ["quintic", "paper"],
}
#: A plan that runs long enough to be cancelled while running.
LONG = {**TINY, "robot": "curtain_wall_6dof", "particles": 400, "iterations": 2000}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    s = Server(tmp_path_factory.mktemp("events") / "data")
    s.start()
    try:
        yield s
    finally:
        s.cleanup()


class Stream:
    """An open ``GET /api/events/jobs``: (event, data) pairs one at a time."""

    def __init__(self, response: httpx.Response) -> None:
        self.lines = response.iter_lines()

    def next(self, deadline: float = float("inf")) -> tuple[str, Any]:
        """The next event (keep-alive comments skipped) before ``deadline`` [monotonic s]."""
        name = None
        for line in self.lines:
            if time.monotonic() > deadline:
                raise AssertionError("no event before the deadline")
            if line.startswith("event: "):
                name = line.removeprefix("event: ")
            elif line.startswith("data: ") and name is not None:
                return name, json.loads(line.removeprefix("data: "))
        raise AssertionError("the stream ended")

    def until(self, job_id: int, state: str, deadline_s: float = 240.0) -> list[dict[str, Any]]:
        """This job's ``job`` events up to the first in ``state``."""
        seen: list[dict[str, Any]] = []
        deadline = time.monotonic() + deadline_s
        while True:
            name, data = self.next(deadline)
            if name == "job" and data["id"] == job_id:
                seen.append(data)
                if data["state"] == state:
                    return seen
                assert data["state"] not in {"succeeded", "failed", "cancelled"}, seen[-3:]


def _open(server: Server, client: httpx.Client, **params: Any) -> Any:
    return client.stream("GET", server.url + "/api/events/jobs", params=params)


def test_the_stream_follows_every_job_from_queued_to_its_end(server: Server) -> None:
    with httpx.Client(timeout=httpx.Timeout(60.0)) as client, _open(server, client) as r:
        assert r.status_code == 200
        assert r.headers["content-type"].startswith("text/event-stream")
        stream = Stream(r)
        name, snapshot = stream.next()
        assert name == "jobs" and isinstance(snapshot, list)

        job = server.post("/api/plans", json=TINY).json()
        seen = stream.until(job["id"], "succeeded")
        states = [s["state"] for s in seen]
        assert states[0] == "queued" and "running" in states  # submitted by another client
        assert seen[-1]["progress"] == 1.0
        assert seen[-1]["about"] == "human_arm_2dof, 1 s, abs_work"
        assert seen[-1]["result_url"] == f"/api/plans/{job['id']}"
        assert "params" not in seen[-1]  # the drawer's form: no request (templates are large)

        long = server.post("/api/plans", json=LONG).json()
        stream.until(long["id"], "running")
        assert server.post(f"/api/jobs/{long['id']}/cancel").status_code == 200
        assert stream.until(long["id"], "cancelled")[-1]["message"] == "cancelled by request"


def test_the_snapshot_lists_recent_jobs_and_every_active_one(server: Server) -> None:
    for _ in range(2):
        job = server.post("/api/plans", json=TINY).json()
        while server.get(f"/api/jobs/{job['id']}")["state"] not in {"succeeded", "failed"}:
            time.sleep(0.2)
    running = server.post("/api/plans", json=LONG).json()
    try:
        with httpx.Client(timeout=httpx.Timeout(60.0)) as client:
            snapshots = {}
            for recent in (1, 3):
                with _open(server, client, recent=recent) as r:
                    name, snapshots[recent] = Stream(r).next()
                    assert name == "jobs"
        one = [j["id"] for j in snapshots[1]]
        three = [j["id"] for j in snapshots[3]]
        assert running["id"] in one and running["id"] in three  # active jobs always listed
        assert len(one) < len(three) and three == sorted(three, reverse=True)
    finally:
        server.post(f"/api/jobs/{running['id']}/cancel")
    with httpx.Client() as client:
        bad = client.get(server.url + "/api/events/jobs", params={"recent": 0})
    assert bad.status_code == 422 and "recent" in bad.text
