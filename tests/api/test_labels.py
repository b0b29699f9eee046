"""Issue 15 item 6: eight Compare entries were all titled "Simulation #N: curtain_wall_6dof, 4
kg, 1 s, abs_work". Plans, simulations and recordings take a label when made and can be
renamed; lists and searches show it; the planner never sees it."""

from __future__ import annotations

from typing import Any

from app.services.demo import synthetic_curls_csv
from tests.utils.api import TestClient, assert_problem, wait_job

TINY = {"robot": "human_arm_2dof", "particles": 8, "iterations": 5, "methods": ["quintic", "paper"]}


def _submit(client: TestClient, kind: str, **body: Any) -> dict[str, Any]:
    r = client.post(f"/api/{kind}", json={**TINY, **body})
    assert r.status_code == 202, r.text
    job: dict[str, Any] = r.json()
    return job


def test_a_plan_is_labelled_when_made_and_renamed_later(shared_client: TestClient) -> None:
    job = _submit(shared_client, "plans", label="  slow, heavy  ")
    assert job["label"] == "slow, heavy"  # surrounding blanks dropped
    assert "label" not in job["params"]  # a name, not part of the request planned
    wait_job(shared_client, job["id"])
    plan = shared_client.get(f"/api/plans/{job['id']}").json()
    assert plan["label"] == plan["job"]["label"] == "slow, heavy"
    listed = shared_client.get("/api/plans").json()["items"]
    assert {p["id"]: p["label"] for p in listed}[job["id"]] == "slow, heavy"

    renamed = shared_client.patch(f"/api/plans/{job['id']}", json={"label": "UR-like, 4 kg"})
    assert renamed.status_code == 200 and renamed.json()["label"] == "UR-like, 4 kg"
    assert shared_client.get(f"/api/jobs/{job['id']}").json()["label"] == "UR-like, 4 kg"
    assert renamed.json()["result"] == plan["result"]  # only the name changed
    cleared = shared_client.patch(f"/api/plans/{job['id']}", json={"label": None})
    assert cleared.json()["label"] is None

    unnamed = _submit(shared_client, "plans", label="   ")
    assert unnamed["label"] is None


def test_a_simulation_is_renamed_and_bad_labels_are_422(shared_client: TestClient) -> None:
    job = _submit(shared_client, "simulations")
    assert job["label"] is None
    r = shared_client.patch(f"/api/simulations/{job['id']}", json={"label": "first try"})
    assert r.status_code == 200 and r.json()["label"] == "first try"
    shared_client.post(f"/api/jobs/{job['id']}/cancel")
    assert_problem(
        shared_client.patch(f"/api/simulations/{job['id']}", json={"label": "x" * 201}),
        422,
        field="label",
    )
    assert_problem(shared_client.patch("/api/simulations/999999", json={"label": "x"}), 404)
    # A plan's id is not a simulation's: the kinds stay apart.
    plan = _submit(shared_client, "plans")
    assert_problem(shared_client.patch(f"/api/simulations/{plan['id']}", json={"label": "x"}), 404)
    assert_problem(_raw(shared_client, {**TINY, "label": "y" * 201}), 422, field="label")


def _raw(client: TestClient, body: dict[str, Any]) -> Any:
    return client.post("/api/plans", json=body)


def test_a_recording_is_labelled_searched_and_renamed(shared_client: TestClient) -> None:
    csv = synthetic_curls_csv()
    r = shared_client.post(
        "/api/recordings",
        files=[("files", ("curls.csv", csv))],
        data={"subject": "S01", "label": "warm-up set"},
    )
    assert r.status_code == 201, r.text
    rid = r.json()["id"]
    assert r.json()["label"] == "warm-up set"
    found = shared_client.get("/api/recordings", params={"q": "warm-up"}).json()["items"]
    assert [x["id"] for x in found] == [rid]
    assert shared_client.get("/api/recordings", params={"q": "no such label"}).json()["total"] == 0
    changed = shared_client.patch(f"/api/recordings/{rid}", json={"label": "heavy set"})
    assert changed.status_code == 200 and changed.json()["label"] == "heavy set"
    assert shared_client.get(f"/api/recordings/{rid}").json()["label"] == "heavy set"
