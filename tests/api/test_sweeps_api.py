"""Sweeps through the API: methods per cell, the convergence check, cells fanned out locally."""

from __future__ import annotations

from typing import Any

import pytest

from tests.utils.api import TestClient, assert_problem, read_sse

GRID = {
    "robot": "human_arm_2dof",
    "durations": [1.0, 1.5],
    "payloads": [4.0],
    "objectives": ["abs_work"],
    "seed": 2,
    "particles": 6,
    "iterations": 4,
}


def _sweep(client: TestClient, **body: Any) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    r = client.post("/api/sweeps", json={**GRID, **body})
    assert r.status_code == 202, r.text
    events = [e for _, e in read_sse(client, r.json()["events_url"])]
    assert events[-1]["state"] == "succeeded", events[-1]
    out: dict[str, Any] = client.get(r.json()["result_url"]).json()["result"]
    return out, events


@pytest.mark.api_contract
def test_every_cell_reports_every_method_and_its_check(shared_client: TestClient) -> None:
    """Methods reach each cell; the check seed is the one asked; per-cell progress is sent."""
    from app.planning import load_robot
    from app.simulation import run_sweep

    methods = ["quintic", "paper", "bound"]
    out, events = _sweep(shared_client, methods=methods, check_seed=9, workers=1)
    ref = run_sweep(
        robot=load_robot("human_arm_2dof"),
        durations=GRID["durations"],
        payloads=GRID["payloads"],
        seed=2,
        particles=6,
        iterations=4,
        methods=methods,
        check_seed=9,
        workers=1,
    ).to_dict()
    assert out["conditions"]["methods"] == methods and out["conditions"]["check_seed"] == 9
    assert len(out["cells"]) == 2
    for got, want in zip(out["cells"], ref["cells"], strict=True):
        assert set(got["methods_change_pct"]) == set(methods)
        assert "bound" in got["share_of_achievable_pct"]
        assert got["unconverged"] == want["unconverged"]
        assert got["check_planned_change_pct"] == want["check_planned_change_pct"]
    cells = [e for e in events if e["stage"] == "sweep"]
    assert any(e["of"] == 2 and e["done"] >= 1 for e in cells), cells


def test_no_check_and_the_local_fan_out(shared_client: TestClient) -> None:
    """``no_check`` drops the second PSO run; without ``workers`` the cells use the runner's
    processes (two in the test service)."""
    out, _ = _sweep(shared_client, methods=["quintic", "paper"], no_check=True)
    assert out["conditions"]["check_seed"] is None
    assert all(c["unconverged"] == [] and c["check_planned_change_pct"] == {} for c in out["cells"])
    assert out["conditions"]["executor"] == "local"
    runner_workers = shared_client.get("/api/health").json()["workers"]
    assert out["conditions"]["workers"] == min(runner_workers, 2)


def test_bad_sweeps_are_422(shared_client: TestClient) -> None:
    post = shared_client.post
    assert_problem(post("/api/sweeps", json={**GRID, "methods": ["warp"]}), 422, field="methods.0")
    r = post("/api/sweeps", json={**GRID, "methods": ["paper", "paper"]})
    assert_problem(r, 422, field="methods")
    assert_problem(post("/api/sweeps", json={**GRID, "check_seed": -2}), 422, field="check_seed")
    assert_problem(post("/api/sweeps", json={**GRID, "robot": "r2d2"}), 404, field="robot")


def test_a_repeated_grid_value_is_refused_before_a_job(shared_client: TestClient) -> None:
    """Issue 14: ``durations: [1.0, 1.0]`` was accepted (202) and failed in the job."""
    jobs_before = shared_client.get("/api/jobs").json()["total"]
    for field, values in (
        ("durations", [0.8, 0.8]),
        ("payloads", [0.0, 2.0, 0.0]),
        ("objectives", ["tau_sq", "tau_sq"]),
    ):
        r = shared_client.post("/api/sweeps", json={**GRID, field: values})
        assert "must not repeat" in assert_problem(r, 422, field=field)["detail"]
    assert shared_client.get("/api/jobs").json()["total"] == jobs_before  # no job queued
