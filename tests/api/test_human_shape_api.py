"""``human_constraint: "shape"`` through the API: accepted, changes the human-like optimum, and
refused with a clear message without a recorded template (issue 25, item 4)."""

from __future__ import annotations

from typing import Any

import pytest

from app.analysis import analyze_recordings
from tests.analysis._data import pyomeca_c3d
from tests.utils.api import TestClient, assert_problem, wait_job

BODY = {
    "robot": "human_arm_2dof",
    "duration": 1.0,
    "objective": "tau_sq",
    "methods": ["quintic", "human_optimal"],
}


@pytest.fixture(scope="module")
def template() -> dict[str, Any]:
    """The template of the real pyomeca trial (three curls with elbow kinematics)."""
    return analyze_recordings([pyomeca_c3d()], load_mass=2.0).template.to_dict()


def _job(client: TestClient, **body: Any) -> dict[str, Any]:
    r = client.post("/api/plans", json={**BODY, **body})
    assert r.status_code == 202, r.text
    return wait_job(client, r.json()["id"])


@pytest.mark.api_contract
def test_shape_reaches_the_planner_and_changes_the_optimum(
    shared_client: TestClient, template: dict[str, Any]
) -> None:
    results = {}
    for kind in ("peak", "shape"):
        job = _job(shared_client, template=template, human_constraint=kind)
        assert job["state"] == "succeeded", job
        results[kind] = shared_client.get(job["result_url"]).json()["result"]
    shape, peak = results["shape"], results["peak"]
    assert shape["conditions"]["human_constraint"] == "shape"
    assert (
        shape["methods"]["human_optimal"]["tau_sq"]
        < 0.9 * peak["methods"]["human_optimal"]["tau_sq"]
    )


def test_shape_on_the_paper_default_is_422_naming_why(shared_client: TestClient) -> None:
    before = shared_client.get("/api/jobs").json()["total"]
    r = shared_client.post("/api/plans", json={**BODY, "human_constraint": "shape"})
    detail = assert_problem(r, 422, field="human_constraint")["detail"]
    assert "shape needs the elbow-speed profile" in detail and "paper default" in detail
    one_lift = {"normalized_time": [0.0, 0.5, 1.0], "velocity_mean": [0.1, 1.0, 0.1],
                "velocity_sd": [0.0, 0.0, 0.0], "n_lifts": 1}  # fmt: skip
    r = shared_client.post(
        "/api/plans", json={**BODY, "human_constraint": "shape", "template": one_lift}
    )
    assert "at least 2 lifts" in assert_problem(r, 422, field="human_constraint")["detail"]
    # Without human_optimal the constraint is not used, so not refused.
    r = shared_client.post(
        "/api/plans", json={**BODY, "methods": ["quintic"], "human_constraint": "shape"}
    )
    assert r.status_code == 202, r.text
    wait_job(shared_client, r.json()["id"])
    assert shared_client.get("/api/jobs").json()["total"] == before + 1
