"""Exports through the API: a capped number of samples (stated in the schema), the default
method pair of a plan without the paper's method, and no server folder in any answer."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from tests.conftest import TWO_LINK_URDF
from tests.utils.api import TestClient, assert_problem, make_client, wait_job

CAP = 500
WITHOUT_PAPER = {
    "robot": "human_arm_2dof",
    "duration": 1.0,
    "seed": 1,
    "methods": ["quintic", "jerk_limited"],
}


@pytest.fixture(scope="module")
def capped(tmp_path_factory: pytest.TempPathFactory) -> Any:
    folder = tmp_path_factory.mktemp("capped")
    with make_client(folder, max_export_samples=CAP) as client:
        yield client, folder


def _finished(client: TestClient, path: str, body: dict[str, Any]) -> int:
    r = client.post(path, json=body)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"])
    assert job["state"] == "succeeded", job
    return int(r.json()["id"])


@pytest.fixture(scope="module")
def without_paper(capped: Any) -> int:
    client, _ = capped
    return _finished(client, "/api/plans", WITHOUT_PAPER)


def test_the_schema_states_the_export_cap(capped: Any) -> None:
    client, _ = capped
    paths = client.get("/openapi.json").json()["paths"]
    for route in ("/api/plans/{plan_id}/trajectory", "/api/simulations/{simulation_id}/trajectory"):
        (param,) = [p for p in paths[route]["get"]["parameters"] if p["name"] == "samples"]
        branches = param["schema"].get("anyOf", [param["schema"]])
        assert [b["maximum"] for b in branches if b.get("type") == "integer"] == [CAP]


def test_an_export_above_the_cap_is_422_naming_the_field(capped: Any, without_paper: int) -> None:
    client, _ = capped
    url = f"/api/plans/{without_paper}/trajectory"
    problem = assert_problem(client.get(url, params={"format": "yaml", "rate": 1000}), 422)
    assert problem["field"] == "rate" and "1001 samples" in problem["detail"]
    problem = assert_problem(client.get(url, params={"format": "csv", "samples": CAP + 1}), 422)
    assert problem["field"] == "samples" and str(CAP) in problem["detail"]
    both = client.get(url, params={"format": "csv", "samples": 100, "rate": 10})
    assert assert_problem(both, 422)["field"] == "samples"
    r = client.get(url, params={"format": "csv", "samples": CAP})
    assert r.status_code == 200, r.text
    rows = [x for x in r.text.splitlines() if not x.startswith("#")]  # after the record
    assert len(rows) == 1 + CAP  # the header, then the samples
    r = client.get(url, params={"format": "json", "rate": 400})
    assert r.status_code == 200 and len(r.json()["t"]) == 401  # streamed JSON is one object


def test_compare_and_scene_export_of_a_plan_without_the_paper(
    capped: Any, without_paper: int
) -> None:
    client, _ = capped
    base = f"/api/viewer/comparisons/plan/{without_paper}"
    r = client.get(base)
    assert r.status_code == 200, r.text
    assert r.json()["methods"] == {"standard": "quintic", "optimized": "jerk_limited"}
    for fmt in ("report", "scene"):
        r = client.get(f"{base}/export", params={"format": fmt})
        assert r.status_code == 200, (fmt, r.text[:300])
        assert r.headers["content-type"].startswith("text/html")
    r = client.get(base, params={"methods": "quintic,paper"})
    assert assert_problem(r, 404)["field"] == "methods"


def test_no_server_folder_in_exports_or_errors(capped: Any) -> None:
    client, folder = capped
    files = {"urdf": ("arm.urdf", TWO_LINK_URDF.encode(), "application/xml")}
    assert client.post("/api/robots", data={"name": "lab_arm"}, files=files).status_code == 201
    body = {**WITHOUT_PAPER, "robot": "lab_arm"}
    plan_id = _finished(client, "/api/plans", body)
    r = client.get(f"/api/plans/{plan_id}/trajectory", params={"format": "json", "rate": 100})
    assert r.status_code == 200, r.text
    spec = r.json()["robot_spec"]
    assert not spec["source"].startswith("/") and spec["source"].endswith(".urdf")
    for text in (r.text, *(str(v) for v in spec.values())):
        assert str(folder) not in text and "/tmp" not in text
    # The robot's files gone from the data folder: the answers name no folder either.
    for path in Path(folder).rglob("*.urdf"):
        path.unlink()
    answers = [
        client.get(f"/api/viewer/comparisons/plan/{plan_id}/export", params={"format": "scene"}),
        client.get(f"/api/viewer/comparisons/plan/{plan_id}"),
    ]
    for answer in answers:
        assert 400 <= answer.status_code < 500, answer.text
        assert "robot.urdf" in answer.text  # the file's name ...
        assert str(folder) not in answer.text and "/tmp" not in answer.text, answer.text  # only
