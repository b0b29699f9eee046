"""Issue 27 item 4 through the API: a refused export is a 409 naming what blocks it, the
overrides (``force``, ``allow_unsafe``) and the ROS 2 options (``goal``, ``topic``,
``from_position``) each change the file, and a bad option is a 422 naming it.

The stored plan is changed in the database to plant what the tests need: a ``safety`` block
with a contact of the quintic, and a second plan whose quintic runs ten times faster (every
speed x10, beyond the human arm's limits)."""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest
import yaml

from app.db.models import RESULT_MODELS
from tests.utils.api import TestClient, assert_problem, wait_job

BODY = {
    "robot": "human_arm_2dof",
    "duration": 1.0,
    "particles": 6,
    "iterations": 3,
    "seed": 5,
    "methods": ["quintic", "paper"],
}

CONTACT = {
    "ok": False,
    "checked": True,
    "min_clearance": -0.02,
    "findings": [
        {
            "method": "quintic",
            "time": 0.25,
            "kind": "obstacle",
            "links": ["forearm"],
            "obstacle": "table",
            "depth": 0.02,
        }
    ],
}


def _plan(client: TestClient) -> int:
    r = client.post("/api/plans", json=BODY)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"])
    assert job["state"] == "succeeded", job
    return int(r.json()["id"])


def _edit(client: TestClient, plan_id: int, change: Any) -> None:
    """Rewrite a stored plan's result (``change(result) -> result``) in the database."""
    services = client.app.state.services  # type: ignore[attr-defined]
    with services.sessions() as session:
        row = session.get(RESULT_MODELS["plan"], plan_id)
        row.result = change(copy.deepcopy(row.result))
        session.commit()


@pytest.fixture(scope="module")
def plans(shared_client: TestClient) -> dict[str, int]:
    unsafe = _plan(shared_client)
    _edit(shared_client, unsafe, lambda r: {**r, "safety": CONTACT})
    fast = _plan(shared_client)

    def faster(result: dict[str, Any]) -> dict[str, Any]:
        # The quintic ten times faster: t / 10, qd x 10, qdd x 100 (the same curve in time);
        # its stored torque check no longer applies and is dropped.
        result.pop("safety", None)
        method = result["motion"]["methods"]["quintic"]
        method["t"] = [t / 10 for t in method["t"]]
        method["qd"] = (np.array(method["qd"]) * 10).tolist()
        method["qdd"] = (np.array(method["qdd"]) * 100).tolist()
        method["check"] = {"t": [], "tau": []}
        return result

    _edit(shared_client, fast, faster)
    return {"unsafe": unsafe, "fast": fast}


def test_an_unsafe_method_is_409_unless_allowed(
    shared_client: TestClient, plans: dict[str, int]
) -> None:
    url = f"/api/plans/{plans['unsafe']}/trajectory"
    params = {"format": "yaml", "method": "quintic", "rate": 50}
    body = assert_problem(shared_client.get(url, params=params), 409)
    assert "method quintic is not safe to run" in body["detail"]
    assert "at t=0.25 s: link forearm and obstacle table (obstacle), 20.0 mm deep" in body["detail"]
    r = shared_client.get(url, params={**params, "allow_unsafe": True})
    assert r.status_code == 200, r.text
    assert "# safety: UNSAFE, exported with allow_unsafe: first contact at t=0.25 s" in r.text
    # The paper has no contact of its own: exported, and checked.
    r = shared_client.get(url, params={**params, "method": "paper"})
    assert r.status_code == 200 and "# safety: checked, no contact" in r.text


def test_a_limit_exceedance_is_409_unless_forced(
    shared_client: TestClient, plans: dict[str, int]
) -> None:
    from app.planning import load_robot

    robot = load_robot("human_arm_2dof")
    url = f"/api/plans/{plans['fast']}/trajectory"
    params = {"format": "csv", "method": "quintic", "rate": 1000}
    body = assert_problem(shared_client.get(url, params=params), 409)
    assert "method quintic: joint '" in body["detail"] and "exceeds its limit" in body["detail"]
    r = shared_client.get(url, params={**params, "force": True})
    assert r.status_code == 200, r.text
    lines = r.text.splitlines()
    assert any(x.startswith("# limits: FORCED past the robot's limits") for x in lines)
    body_rows = [x for x in lines if not x.startswith("#")]
    table = np.loadtxt(body_rows[1:], delimiter=",")
    qd = table[:, 1 + robot.n_joints : 1 + 2 * robot.n_joints]
    assert np.any(np.abs(qd).max(axis=0) > robot.qd_max)  # what the 409 was about
    # The paper of the same plan is untouched and within limits.
    ok = shared_client.get(url, params={**params, "method": "paper"})
    assert ok.status_code == 200 and "# limits: within the robot's limits" in ok.text


def test_ros_options_change_the_file(shared_client: TestClient, plans: dict[str, int]) -> None:
    url = f"/api/plans/{plans['unsafe']}/trajectory"
    base = {"format": "yaml", "method": "paper", "rate": 50}
    plain = shared_client.get(url, params=base)
    goal = shared_client.get(url, params={**base, "goal": True})
    topic = "/scaled_joint_trajectory_controller/joint_trajectory"
    named = shared_client.get(url, params={**base, "topic": topic})
    approach = shared_client.get(url, params={**base, "from_position": "10,20"})
    for r in (plain, goal, named, approach):
        assert r.status_code == 200, r.text
    assert yaml.safe_load(goal.text)["trajectory"] == yaml.safe_load(plain.text)
    assert f"# topic: {topic}" in named.text and topic not in plain.text
    first = yaml.safe_load(approach.text)["points"][0]["positions"]
    np.testing.assert_allclose(first, [math.radians(10.0), math.radians(20.0)], atol=1e-15)
    assert len(yaml.safe_load(approach.text)["points"]) > len(yaml.safe_load(plain.text)["points"])


def test_bad_ros_options_are_422_naming_the_field(
    shared_client: TestClient, plans: dict[str, int]
) -> None:
    url = f"/api/plans/{plans['unsafe']}/trajectory"
    get = shared_client.get
    base = {"format": "yaml", "method": "paper"}
    assert_problem(get(url, params={**base, "topic": "/9 bad"}), 422, field="topic")
    assert_problem(get(url, params={**base, "format": "csv", "goal": True}), 422, field="goal")
    assert_problem(get(url, params={**base, "from_position": "ten"}), 422, field="from_position")
    r = get(url, params={**base, "from_position": "1,2,3"})
    assert "expected 2" in assert_problem(r, 422, field="from_position")["detail"]
    r = get(url, params={**base, "format": "csv", "from_position": "1,2"})
    assert_problem(r, 422, field="from_position")


def test_the_schema_documents_every_export_option(shared_client: TestClient) -> None:
    schema = shared_client.get("/openapi.json").json()
    for path in ("/api/plans/{plan_id}/trajectory", "/api/simulations/{simulation_id}/trajectory"):
        params = {p["name"]: p for p in schema["paths"][path]["get"]["parameters"]}
        for name in ("force", "allow_unsafe", "goal", "topic", "from_position"):
            assert name in params and params[name].get("description"), (path, name)
