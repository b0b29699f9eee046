"""Simulations and sweeps through the API equal the library's results; sweeps report cells."""

from __future__ import annotations

import json

import numpy as np

from tests.utils.api import TestClient, assert_problem, read_sse, wait_job

COMPARED = ("standard", "optimized", "tracking", "floors", "improvement_pct")


def _json(value: object) -> object:
    from app.db.crud import json_safe

    return json.loads(json.dumps(json_safe(value)))


def test_simulation_equals_the_library(shared_client: TestClient) -> None:
    from app.planning import load_robot
    from app.simulation import simulate_comparison

    body = {"robot": "human_arm_2dof", "duration": 1.0, "seed": 2, "particles": 8,
            "iterations": 5, "payload": 6.0, "methods": ["quintic", "paper"]}  # fmt: skip
    r = shared_client.post("/api/simulations", json=body)
    assert r.status_code == 202, r.text
    done = wait_job(shared_client, r.json()["id"])
    assert done["state"] == "succeeded", done
    out = shared_client.get(done["result_url"]).json()
    ref = simulate_comparison(
        load_robot("human_arm_2dof", payload=6.0),
        duration=1.0,
        seed=2,
        particles=8,
        iterations=5,
    )
    expected = _json(ref.to_dict())
    assert isinstance(expected, dict)
    for key in COMPARED:
        assert out["result"][key] == expected[key], key
    arrays = shared_client.get(
        f"/api/simulations/{done['id']}/arrays", params={"name": ["t", "optimized_energy"]}
    ).json()
    ref_arrays = ref.arrays()
    idx = np.unique(np.linspace(0, len(ref_arrays["t"]) - 1, 500).round().astype(int))
    np.testing.assert_allclose(
        arrays["arrays"]["optimized_energy"], ref_arrays["optimized_energy"][idx]
    )


def test_sweep_equals_the_library_and_reports_cells(shared_client: TestClient) -> None:
    from app.planning import load_robot
    from app.simulation import run_sweep

    body = {"robot": "human_arm_2dof", "durations": [0.8, 1.0, 1.2, 1.5], "payloads": [0, 4, 8],
            "objectives": ["abs_work"], "seed": 0, "particles": 10, "iterations": 30,
            "methods": ["quintic", "paper"]}  # fmt: skip
    r = shared_client.post("/api/sweeps", json=body)
    assert r.status_code == 202, r.text
    events = read_sse(shared_client, r.json()["events_url"])
    assert events[-1][0] == "done" and events[-1][1]["state"] == "succeeded"
    messages = [e["message"] for _, e in events]
    assert any(m.startswith("cell ") for m in messages), messages
    out = shared_client.get(r.json()["result_url"]).json()
    ref = run_sweep(
        robot=load_robot("human_arm_2dof"),
        durations=body["durations"],
        payloads=body["payloads"],
        objectives=["abs_work"],
        seed=0,
        particles=10,
        iterations=30,
        workers=1,
    )
    expected = _json(ref.to_dict())
    assert isinstance(expected, dict)
    for key in ("durations", "payloads", "objectives", "metrics", "tables"):
        assert out["result"][key] == expected[key], key
    # The range is in the schema: the item at fault is named.
    assert_problem(shared_client.post("/api/sweeps", json={**body, "durations": [0]}), 422,
                   field="durations.0")  # fmt: skip
    assert_problem(shared_client.get(f"/api/sweeps/{r.json()['id']}/arrays"), 404)
