"""Trajectory export through the API: the library's bytes, media types, file names, bad input."""

from __future__ import annotations

import csv
import io
import json
from typing import Any

import numpy as np
import pytest
import yaml

from tests.utils.api import TestClient, assert_problem, wait_job

BODY = {
    "robot": "human_arm_2dof",
    "duration": 1.0,
    "particles": 8,
    "iterations": 5,
    "seed": 5,
    "payload": 8.0,
    "methods": ["quintic", "paper"],
}


def _finished(client: TestClient, path: str, body: dict[str, Any]) -> dict[str, Any]:
    r = client.post(path, json=body)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"])
    assert job["state"] == "succeeded", job
    out: dict[str, Any] = client.get(job["result_url"]).json()
    return out


def test_the_api_knows_every_export_format_and_the_rate_limit() -> None:
    """The route's media types and rate bound are the library's formats and MAX_RATE_HZ."""
    from app.api.routes._common import EXPORT_MEDIA_TYPES, MAX_EXPORT_RATE_HZ
    from app.names import HUMAN_CONSTRAINTS, OPTIMAL_INTERVALS
    from app.planning.export import FORMATS, MAX_RATE_HZ
    from app.planning.optimal import DEFAULT_INTERVALS
    from app.planning.optimal import HUMAN_CONSTRAINTS as LIBRARY_CONSTRAINTS

    assert set(EXPORT_MEDIA_TYPES) == set(FORMATS)
    assert all(f.extension == f".{name}" for name, f in FORMATS.items())  # the file names
    assert MAX_EXPORT_RATE_HZ == MAX_RATE_HZ
    assert HUMAN_CONSTRAINTS == LIBRARY_CONSTRAINTS and OPTIMAL_INTERVALS == DEFAULT_INTERVALS


@pytest.fixture(scope="module")
def planned(shared_client: TestClient) -> dict[str, Any]:
    return _finished(shared_client, "/api/plans", BODY)


def test_export_is_the_library_export_of_the_same_plan(
    shared_client: TestClient, planned: dict[str, Any]
) -> None:
    """Each format's bytes equal ``export_bytes`` of the same plan made by the library."""
    from app.planning import load_robot, plan
    from app.planning.export import export_bytes, plan_motion

    robot = load_robot("human_arm_2dof", payload=8.0)
    ref = plan(robot, duration=1.0, particles=8, iterations=5, seed=5, methods=["quintic", "paper"])
    motion = plan_motion(ref, robot)
    url = f"/api/plans/{planned['id']}/trajectory"
    media = {"csv": "text/csv", "yaml": "application/yaml", "mot": "text/plain"}
    for fmt, kind in media.items():
        r = shared_client.get(url, params={"format": fmt, "rate": 200, "method": "quintic"})
        assert r.status_code == 200, r.text
        assert r.headers["content-type"].startswith(kind)
        name = f'filename="plan-{planned["id"]}-quintic.{fmt}"'
        assert name in r.headers["content-disposition"]
        assert r.content == export_bytes(motion, fmt, method="quintic", rate=200.0, robot=robot)
    # Read back: 201 samples at 200 Hz, columns named by the robot's joints.
    text = shared_client.get(url, params={"format": "csv", "rate": 200}).text
    rows = [row for row in csv.reader(io.StringIO(text)) if row and not row[0].startswith("#")]
    header, data = rows[0], np.array(rows[1:], dtype=float)
    assert data.shape[0] == 201
    assert any(robot.joint_names[0] in h for h in header)
    # The default method is the optimised one; its positions are the planned knots' values.
    q_paper = ref.methods["paper"].trajectory
    np.testing.assert_allclose(data[-1, 1 : 1 + robot.n_joints], q_paper.q[-1], atol=1e-9)
    ros = yaml.safe_load(shared_client.get(url, params={"format": "yaml"}).text)
    assert ros["joint_names"] == list(robot.joint_names)


def test_stored_result_carries_the_motion_block(planned: dict[str, Any]) -> None:
    motion = planned["result"]["motion"]
    assert set(motion["methods"]) == {"quintic", "paper"}
    assert motion["default_method"] == "paper"
    assert motion["joint_names"] == planned["result"]["joint_names"]


def test_bad_export_requests_name_the_field(
    shared_client: TestClient, planned: dict[str, Any]
) -> None:
    url = f"/api/plans/{planned['id']}/trajectory"
    get = shared_client.get
    assert_problem(get(url, params={"format": "xls"}), 422, field="format")
    assert_problem(get(url), 422, field="format")
    assert_problem(get(url, params={"format": "csv", "rate": 0}), 422, field="rate")
    assert_problem(get(url, params={"format": "csv", "rate": 1e9}), 422, field="rate")
    r = get(url, params={"format": "csv", "method": "bound"})  # a method, not in this plan
    assert "expected one of quintic, paper" in assert_problem(r, 404, field="method")["detail"]
    assert_problem(get(url, params={"format": "csv", "method": "warp"}), 422, field="method")
    # URScript needs a six-joint arm: the library's one-line refusal, a 422.
    assert_problem(get(url, params={"format": "script"}), 422)
    assert_problem(get("/api/plans/999999/trajectory", params={"format": "csv"}), 404)


def test_simulation_export(shared_client: TestClient) -> None:
    """A simulation's plan exports too (JSON: the samples plus task, robot and method)."""
    out = _finished(shared_client, "/api/simulations", BODY)
    r = shared_client.get(
        f"/api/simulations/{out['id']}/trajectory",
        params={"format": "json", "rate": 100, "method": "paper"},
    )
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("application/json")
    doc = json.loads(r.content)
    assert doc["method"] == "paper"
    assert out["result"]["motion"]["joint_names"] == doc["joint_names"]
