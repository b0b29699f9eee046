"""``bioplan submit front`` against a real server: every option of ``bioplan front`` reaches the
job's params under the API's name, the printed result is the stored one, and bad input is
refused before anything is queued, naming the option."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from app.planning.human_template import HumanTemplate
from tests.utils.server import Server


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    s = Server(tmp_path_factory.mktemp("submit-front") / "data").start()
    yield s
    s.cleanup()


def bioplan(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, timeout=600
    )


def _front_jobs(server: Server) -> list[dict[str, Any]]:
    items: list[dict[str, Any]] = server.get("/api/jobs", params={"kind": "front"})["items"]
    return items


def _cancel(server: Server, job_id: int) -> dict[str, Any]:
    """Cancel a job (it is not needed to run) and wait until it ended."""
    server.post(f"/api/jobs/{job_id}/cancel")
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        job: dict[str, Any] = server.get(f"/api/jobs/{job_id}")
        if job["state"] in ("succeeded", "failed", "cancelled"):
            return job
        time.sleep(0.2)
    raise AssertionError(f"job {job_id} did not end after cancel")


def test_submit_front_prints_the_stored_result(server: Server) -> None:
    out = bioplan("submit", "--server", server.url, "--json", "front", "--robot",
                  "human_arm_2dof", "--payload", "5", "--objectives", "tau_sq,jerk",
                  "--points", "3", "--intervals", "20", "--tolerance", "0.01")  # fmt: skip
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    job = _front_jobs(server)[0]
    stored = server.get(job["result_url"])
    assert job["kind"] == "front" and job["state"] == "succeeded"
    assert result == stored["result"]
    assert result["objectives"] == ["tau_sq", "jerk"] and len(result["points"]) == 3
    assert set(result["references"]) == {"quintic", "paper", "jerk_limited"}
    # The front's ends: least tau_sq at the first point, least jerk at the last.
    tau = [p["tau_sq"] for p in result["points"]]
    jerk = [p["jerk"] for p in result["points"]]
    assert tau[0] == min(tau) and jerk[-1] == min(jerk)


def test_every_option_reaches_the_jobs_params(server: Server, tmp_path: Path) -> None:
    template = tmp_path / "template.json"
    template.write_text(HumanTemplate(peak_velocity_angle_deg=75.0, n_lifts=2).to_json())
    out = bioplan("submit", "--server", server.url, "--no-wait", "front",
                  "--robot", "human_arm_2dof", "--payload", "3.5",
                  "--objectives", "duration,abs_work", "--max-duration", "2.5",
                  "--points", "4", "--method", "human_optimal", "--template", str(template),
                  "--intervals", "16", "--tolerance", "0.02", "--allow-reversal",
                  "--start-deg", "-5,10", "--goal-deg", "60,100")  # fmt: skip
    assert out.returncode == 0, out.stderr
    job = json.loads(out.stdout)
    assert job["kind"] == "front" and job["result_url"] == f"/api/fronts/{job['id']}"
    _cancel(server, job["id"])
    params = server.get(f"/api/jobs/{job['id']}")["params"]
    expected = {
        "robot": "human_arm_2dof",
        "payload_mass": 3.5,
        "objectives": ["duration", "abs_work"],
        "max_duration": 2.5,
        "points": 4,
        "method": "human_optimal",
        "intervals": 16,
        "tolerance": 0.02,
        "allow_reversal": True,
        "start_deg": [-5.0, 10.0],
        "goal_deg": [60.0, 100.0],
    }
    assert {k: params.get(k) for k in expected} == expected
    assert params["duration"] is None
    assert params["template"]["peak_velocity_angle_deg"] == 75.0
    assert params["template"]["n_lifts"] == 2

    # --duration on a front with duration not an axis; the defaults otherwise.
    out = bioplan("submit", "--server", server.url, "--no-wait", "front",
                  "--robot", "human_arm_2dof", "--objectives", "tau_sq,peak_power",
                  "--duration", "1.5")  # fmt: skip
    assert out.returncode == 0, out.stderr
    job = json.loads(out.stdout)
    _cancel(server, job["id"])
    params = server.get(f"/api/jobs/{job['id']}")["params"]
    assert params["duration"] == 1.5 and params["objectives"] == ["tau_sq", "peak_power"]
    assert (params["points"], params["method"], params["allow_reversal"]) == (9, "bound", False)
    assert params["template"] is None and params["max_duration"] is None


@pytest.mark.parametrize(
    "args, says",
    [
        (("--objectives", "jerk,jerk"), "--objectives: the same metric twice (jerk)"),
        (("--objectives", "jerk,speed"), "--objectives: unknown metric 'speed'"),
        (("--objectives", "jerk,duration", "--duration", "2"), "--duration is fixed"),
        (("--objectives", "jerk,tau_sq", "--max-duration", "2"), "--max-duration given"),
        (("--objectives", "jerk,tau_sq", "--points", "1"), "--points 1"),
        (("--objectives", "jerk,tau_sq", "--intervals", "4"), "--intervals must be >= 8"),
    ],
)
def test_bad_input_exits_2_naming_the_option_and_queues_nothing(
    server: Server, args: tuple[str, ...], says: str
) -> None:
    before = len(_front_jobs(server))
    out = bioplan("submit", "--server", server.url, "front", "--robot", "human_arm_2dof", *args)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bioplan submit: error: "), out.stderr
    assert says in lines[0]
    assert len(_front_jobs(server)) == before


def test_the_servers_refusal_names_the_field(server: Server) -> None:
    """What only the server knows (the robot's joints) is its 422, exit 2, naming the field."""
    out = bioplan("submit", "--server", server.url, "front", "--robot", "human_arm_2dof",
                  "--objectives", "jerk,tau_sq", "--start-deg", "1,2,3")  # fmt: skip
    assert out.returncode == 2, out.stderr
    assert "start_deg needs 2 angles for human_arm_2dof" in out.stderr
    assert "(field: start_deg)" in out.stderr
