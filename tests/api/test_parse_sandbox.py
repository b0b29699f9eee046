"""Issue 14 item 7: untrusted files were parsed in the API process, so a file that costs more
than it declares could take the whole server down. Each is now read in a child process with a
memory and a time limit: past either, 413 with the file and the limit named, and the server
goes on serving. What a reader raises comes back unchanged (bad input a 4xx, a bug a 500)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from app.errors import BioPlanError
from app.jobs.tasks import parse_recording
from app.services.demo import synthetic_curls_csv
from app.services.errors import ParseLimitError
from app.services.sandbox import ParseSandbox
from tests.utils.api import assert_problem, make_client


def test_memory_past_the_limit_is_refused_naming_it() -> None:
    sandbox = ParseSandbox(memory_mb=64, seconds=120)
    with pytest.raises(ParseLimitError, match=r"big\.mat: .*more than 64 MB.*PARSE_MEMORY_MB"):
        sandbox.run(np.ones, 10**9, what="big.mat")  # 8 GB
    assert sandbox.run(np.ones, 10**6, what="small").sum() == 10**6  # 8 MB fits


def test_time_past_the_limit_is_refused_and_the_child_killed() -> None:
    sandbox = ParseSandbox(memory_mb=256, seconds=0.5)
    started = time.monotonic()
    with pytest.raises(ParseLimitError, match=r"slow\.c3d: .*longer than 0\.5 s"):
        sandbox.run(time.sleep, 60, what="slow.c3d")
    assert time.monotonic() - started < 45  # the 60 s sleep was not waited for


def test_a_readers_answer_and_errors_come_back_unchanged() -> None:
    sandbox = ParseSandbox(memory_mb=1024, seconds=120)
    csv = synthetic_curls_csv()
    inside = sandbox.run(parse_recording, csv, "curls.csv", {}, None, what="curls.csv")
    here = parse_recording(csv, "curls.csv", {}, None)
    assert [c["name"] for c in inside["channels"]] == [c["name"] for c in here["channels"]]
    for a, b in zip(inside["channels"], here["channels"], strict=True):
        np.testing.assert_array_equal(a["data"], b["data"])
    with pytest.raises(BioPlanError):  # bad input stays bad input (a 4xx)
        sandbox.run(parse_recording, b"\x00\x01 not a recording", "x.csv", {}, None, what="x")
    with pytest.raises(ValueError, match="invalid literal"):  # a bug stays a bug (a 500)
        sandbox.run(int, "not a number", what="x")


def _big_csv() -> bytes:
    """About 50 MB of two EMG channels (6 million rows; the rate is given with the upload):
    some 200 MB once read into columns."""
    rng = np.random.default_rng(0)
    block = "".join(f"{a:.5f},{b:.5f}\n" for a, b in rng.normal(0, 1e-4, (1000, 2)))
    return b"biceps,triceps\n" + block.encode() * 6000


def test_an_upload_past_the_limit_is_413_and_nothing_is_stored(tmp_path: Path) -> None:
    with make_client(tmp_path, parse_memory_mb=128) as client:
        files = [("files", ("long.csv", _big_csv()))]
        r = client.post("/api/recordings", files=files, data={"rate": "2000"})
        problem = assert_problem(r, 413, file="long.csv")
        assert "128 MB" in problem["detail"] and "BIOPLAN_PARSE_MEMORY_MB" in problem["detail"]
        assert client.get("/api/recordings").json()["total"] == 0  # nothing half-stored
        # The server is unaffected: a small file is read and stored.
        small = client.post("/api/recordings", files=[("files", ("a.csv", synthetic_curls_csv()))])
        assert small.status_code == 201, small.text
        assert client.get("/api/health").json()["status"] == "ok"


def test_a_robot_model_past_the_time_limit_is_413(tmp_path: Path) -> None:
    from tests.utils.example_robots import UR5, robot_file

    urdf = robot_file(UR5)
    with make_client(tmp_path, parse_seconds=0.001) as client:
        r = client.post(
            "/api/robots",
            data={"name": "ur5_slow"},
            files=[("urdf", (urdf.name, urdf.read_bytes()))],
        )
        assert_problem(r, 413)
        assert "BIOPLAN_PARSE_SECONDS" in r.json()["detail"]
        assert all(x["name"] != "ur5_slow" for x in client.get("/api/robots").json())


def test_stopping_one_server_leaves_anothers_sandbox_in_use() -> None:
    """Services of one process start and stop in any order (tests do): a stop releases only
    the sandbox it set, so a server still running keeps reading uploads in a child."""
    from app.services import sandbox

    mine, theirs = ParseSandbox(memory_mb=64, seconds=1), ParseSandbox(memory_mb=64, seconds=1)
    before = sandbox._active
    try:
        sandbox.use(theirs)
        sandbox.release(mine)
        assert sandbox._active is theirs
        sandbox.release(theirs)
        assert sandbox._active is None
    finally:
        sandbox._active = before
