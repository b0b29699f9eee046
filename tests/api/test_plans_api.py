"""Plans through the API: the CLI's JSON, arrays for plots, comparison, cancel, bad requests."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest

from app.names import METHODS
from tests.utils.api import TestClient, assert_problem, wait_job

TINY = {
    "robot": "human_arm_2dof",
    "duration": 1.0,
    "particles": 8,
    "iterations": 5,
    "methods": ["quintic", "paper"],
}


def _without_timing(result: dict[str, Any]) -> dict[str, Any]:
    """The result without wall-clock fields (PSO and IPOPT seconds) and the motion block."""
    out = {k: v for k, v in result.items() if k != "motion"}
    if out.get("optimizer"):
        out["optimizer"] = {k: v for k, v in result["optimizer"].items() if k != "seconds"}
    methods = {}
    for name, m in result.get("methods", {}).items():
        m = dict(m)
        if isinstance(m.get("solver"), dict):
            m["solver"] = {k: v for k, v in m["solver"].items() if k != "seconds"}
        methods[name] = m
    out["methods"] = methods
    return out


def _run(client: TestClient, **body: Any) -> dict[str, Any]:
    r = client.post("/api/plans", json={**TINY, **body})
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"])
    assert job["state"] == "succeeded", job
    out: dict[str, Any] = client.get(job["result_url"]).json()
    return out


def test_objectives_match_the_planner() -> None:
    from typing import get_args

    from app.api.schemas import Objective
    from app.planning.energy import OBJECTIVES

    assert set(get_args(Objective)) == set(OBJECTIVES)


def test_plan_result_is_the_cli_json_of_the_same_plan(shared_client: TestClient) -> None:
    from app.db.crud import json_safe
    from app.planning import load_robot, plan

    out = _run(shared_client, seed=3, objective="abs_work", payload=10.0)
    expected = plan(
        load_robot("human_arm_2dof", payload=10.0),
        duration=1.0,
        objective="abs_work",
        seed=3,
        particles=8,
        iterations=5,
    )
    result = out["result"]
    assert set(result) >= {
        "standard", "optimized", "floors", "improvement_pct", "peak_velocity_angle_deg", "optimizer"
    }  # fmt: skip
    assert _without_timing(result) == _without_timing(json_safe(expected.to_dict()))
    # A physical floor holds end to end: no rest-to-rest lift does less positive work than dPE.
    assert result["optimized"]["pos_work"] >= result["floors"]["delta_potential"] * (1 - 1e-9)

    arrays = shared_client.get(f"/api/plans/{out['id']}/arrays", params={"points": 50}).json()
    ref = expected.arrays()
    idx = np.unique(np.linspace(0, len(ref["t"]) - 1, 50).round().astype(int))
    assert arrays["points"] == len(idx)
    np.testing.assert_allclose(arrays["arrays"]["t"], ref["t"][idx])
    np.testing.assert_allclose(arrays["arrays"]["optimized_q"], ref["optimized_q"][idx])
    only = shared_client.get(
        f"/api/plans/{out['id']}/arrays", params={"name": ["t", "standard_energy"]}
    ).json()
    assert set(only["arrays"]) == {"t", "standard_energy"}
    assert_problem(  # no such array in this plan
        shared_client.get(f"/api/plans/{out['id']}/arrays", params={"name": "nope"}),
        404,
        field="name",
    )


def test_compare_two_plans(shared_client: TestClient) -> None:
    a = _run(shared_client, seed=1, duration=1.0)
    b = _run(shared_client, seed=1, duration=1.5)
    cmp = shared_client.get("/api/plans/compare", params={"a": a["id"], "b": b["id"]}).json()
    assert cmp["conditions"]["a"]["duration"] == 1.0 and cmp["conditions"]["b"]["duration"] == 1.5
    for traj in ("standard", "optimized"):
        for metric in ("abs_work", "tau_sq", "peak_power"):
            va, vb = a["result"][traj][metric], b["result"][traj][metric]
            d = cmp[traj][metric]
            assert (d["a"], d["b"]) == (va, vb)
            assert d["diff"] == pytest.approx(vb - va)
            assert d["diff_pct"] == pytest.approx(100 * (vb - va) / abs(va))
    listed = shared_client.get("/api/plans", params={"robot": "human_arm_2dof"}).json()
    assert {a["id"], b["id"]} <= {p["id"] for p in listed["items"]}
    assert_problem(shared_client.get("/api/plans/compare", params={"a": a["id"], "b": 9999}), 404)


def test_cancel_a_running_plan(shared_client: TestClient) -> None:
    big = {"particles": 400, "iterations": 2000, "n_samples": 2000, "robot": "curtain_wall_6dof"}
    job = shared_client.post("/api/plans", json={**TINY, **big}).json()
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        now = shared_client.get(f"/api/jobs/{job['id']}").json()
        if now["state"] == "running":
            break
        time.sleep(0.05)
    assert now["state"] == "running", now
    t0 = time.monotonic()
    r = shared_client.post(f"/api/jobs/{job['id']}/cancel")
    assert r.status_code == 200 and r.json()["state"] == "cancelled"
    assert time.monotonic() - t0 < 5
    assert shared_client.get(f"/api/plans/{job['id']}").json()["result"] is None
    deadline = time.monotonic() + 5
    while shared_client.get("/api/health").json()["running"] and time.monotonic() < deadline:
        time.sleep(0.05)
    assert shared_client.get("/api/health").json()["running"] == 0  # its process is gone


def test_bad_plan_requests_name_the_field(shared_client: TestClient) -> None:
    """A value the planner refuses is a 422; a name in the body that names nothing is a 404
    (the same answer as for the missing resource itself); both say which field."""
    post = shared_client.post
    assert_problem(post("/api/plans", json={**TINY, "robot": "r2d2"}), 404, field="robot")
    assert_problem(post("/api/plans", json={**TINY, "objective": "speed"}), 422, field="objective")
    assert_problem(post("/api/plans", json={**TINY, "duration": 0}), 422, field="duration")
    r = post("/api/plans", json={**TINY, "start_deg": [0, 0, 0]})
    assert "needs 2 angles" in assert_problem(r, 422, field="start_deg")["detail"]
    r = post("/api/plans", json={**TINY, "template": {"peak_velocity_angle_deg": 500}})
    assert_problem(r, 422, field="template")
    r = post("/api/plans", json={**TINY, "template_analysis_id": 777})
    assert (
        "analysis 777 does not exist"
        in assert_problem(r, 404, field="template_analysis_id")["detail"]
    )


@pytest.mark.api_contract
def test_template_and_angles_reach_the_planner(shared_client: TestClient) -> None:
    out = _run(
        shared_client,
        template={"peak_velocity_angle_deg": 70.0, "source": "api test"},
        start_deg=[0.0, 10.0],
        goal_deg=[30.0, 140.0],
    )
    cond = out["result"]["conditions"]
    assert cond["template"] == "api test"
    assert out["result"]["target_peak_velocity_angle_deg"] == pytest.approx(70.0)
    np.testing.assert_allclose(cond["start_deg"], [0.0, 10.0])
    np.testing.assert_allclose(cond["goal_deg"], [30.0, 140.0])


@pytest.mark.api_contract
def test_methods_and_their_options_reach_the_planner(shared_client: TestClient) -> None:
    """Every method option of the request is the library's: the same plan, option by option."""
    from app.db.crud import json_safe
    from app.planning import load_robot, plan

    options = {
        "methods": ["quintic", "human_optimal", "bound"],
        "human_constraint": "phases",
        "no_reversal": False,
        "n_intervals": 16,
    }
    out = _run(shared_client, seed=4, **options)
    expected = plan(
        load_robot("human_arm_2dof"),
        duration=1.0,
        seed=4,
        particles=8,
        iterations=5,
        **options,  # type: ignore[arg-type]
    )
    result = out["result"]
    assert _without_timing(result) == _without_timing(json_safe(expected.to_dict()))
    assert set(result["methods"]) == {"quintic", "human_optimal", "bound"}
    assert result["methods"]["bound"]["solver"]["n_intervals"] == 16
    assert result["conditions"]["human_constraint"] == "phases"
    assert result["conditions"]["no_reversal"] is False
    # The bound captures the whole achievable saving by definition; the quintic none.
    assert result["share_of_achievable_pct"]["bound"] == pytest.approx(100.0)
    assert result["share_of_achievable_pct"]["quintic"] == pytest.approx(0.0)
    # Issue 12: joint names, the task in degrees and the duration in every plan's JSON.
    assert result["joint_names"] == list(load_robot("human_arm_2dof").joint_names)
    assert result["duration"] == 1.0
    np.testing.assert_allclose(result["task"]["goal_deg"], np.degrees(expected.task.goal))
    arrays = shared_client.get(f"/api/plans/{out['id']}/arrays", params={"points": 20}).json()
    for name in ("quintic", "human_optimal", "bound"):
        assert {f"{name}_q", f"{name}_tau", f"{name}_power", f"{name}_energy"} <= set(
            arrays["arrays"]
        )
    # A different constraint gives a different human-like optimum (the option is not ignored).
    other = _run(shared_client, seed=4, **{**options, "human_constraint": "none"})
    assert (
        other["result"]["methods"]["human_optimal"]["objective_value"]
        != result["methods"]["human_optimal"]["objective_value"]
    )


def test_infeasible_requests_are_422_before_a_job(shared_client: TestClient) -> None:
    """Cheap checks name the field, the joint and the smallest feasible value; no job queued."""
    from app.planning import load_robot

    post = shared_client.post
    before = shared_client.get("/api/jobs").json()["total"]
    robot = load_robot("curtain_wall_6dof")
    dq = np.abs(robot.default_goal - robot.default_start)
    shortest = float(np.max(dq / robot.qd_max))  # no rest-to-rest motion averages more
    r = post("/api/plans", json={**TINY, "robot": "curtain_wall_6dof", "duration": shortest * 0.9})
    detail = assert_problem(r, 422, field="duration")["detail"]
    assert f"at least {shortest:.3f} s" in detail, detail
    assert robot.joint_names[int(np.argmax(dq / robot.qd_max))] in detail
    r = post("/api/simulations", json={**TINY, "robot": "curtain_wall_6dof", "duration": 0.01})
    assert_problem(r, 422, field="duration")
    hi = float(np.degrees(load_robot("human_arm_2dof").q_max[1]))
    r = post("/api/plans", json={**TINY, "goal_deg": [20.0, hi + 5.0]})
    assert "outside its limits" in assert_problem(r, 422, field="goal_deg")["detail"]
    r = post("/api/plans", json={**TINY, "start_deg": [0.0, 0.0], "goal_deg": [30.0, 0.0]})
    assert "elbow" in assert_problem(r, 422, field="goal_deg")["detail"]
    assert_problem(post("/api/plans", json={**TINY, "methods": ["warp"]}), 422, field="methods.0")
    assert_problem(post("/api/plans", json={**TINY, "methods": []}), 422, field="methods")
    r = post("/api/plans", json={**TINY, "human_constraint": "tight"})
    assert_problem(r, 422, field="human_constraint")
    assert_problem(post("/api/plans", json={**TINY, "n_intervals": 2}), 422, field="n_intervals")
    assert shared_client.get("/api/jobs").json()["total"] == before
    # Just above the shortest duration is accepted (202), so the bound is the right one.
    r = post("/api/plans", json={**TINY, "robot": "curtain_wall_6dof", "duration": shortest * 1.05})
    assert r.status_code == 202, r.text
    shared_client.post(f"/api/jobs/{r.json()['id']}/cancel")


def test_a_plan_the_planner_refuses_fails_its_job_with_one_line(
    shared_client: TestClient,
) -> None:
    """What is not cheap to check (a peak angle outside the stroke) fails the job with the line."""
    body = {**TINY, "peak_angle_deg": 179.0, "start_deg": [0, 10], "goal_deg": [20, 40]}
    r = shared_client.post("/api/plans", json=body)
    assert r.status_code == 202, r.text
    job = wait_job(shared_client, r.json()["id"])
    assert job["state"] == "failed"
    assert "outside the elbow's stroke" in job["error"] and "\n" not in job["error"]


@pytest.mark.api_contract
def test_the_comparison_shows_any_two_planned_methods(shared_client: TestClient) -> None:
    """``methods=a,b`` on the Compare page's data: a's curves as standard, b's as optimized."""
    out = _run(shared_client, seed=6, methods=["quintic", "paper", "bound"], n_intervals=16)
    url = f"/api/viewer/comparisons/plan/{out['id']}"
    arrays = shared_client.get(f"/api/plans/{out['id']}/arrays", params={"points": 50}).json()
    default = shared_client.get(url, params={"points": 50}).json()
    assert default["methods"] == {"standard": "quintic", "optimized": "paper"}
    np.testing.assert_allclose(default["curves"]["optimized"]["q"], arrays["arrays"]["paper_q"])
    chosen = shared_client.get(url, params={"points": 50, "methods": "paper,bound"}).json()
    assert chosen["methods"] == {"standard": "paper", "optimized": "bound"}
    curves = chosen["curves"]
    np.testing.assert_allclose(curves["standard"]["q"], arrays["arrays"]["paper_q"])
    np.testing.assert_allclose(curves["optimized"]["q"], arrays["arrays"]["bound_q"])
    np.testing.assert_allclose(curves["optimized"]["energy"], arrays["arrays"]["bound_energy"])
    assert "methods=paper,bound" in chosen["exports"]["report"]
    report = shared_client.get(chosen["exports"]["report"])
    assert report.status_code == 200
    for bad in ("bound", "bound,bound", "quintic,warp"):
        assert_problem(shared_client.get(url, params={"methods": bad}), 422, field="methods")
    r = shared_client.get(url, params={"methods": "quintic,human_optimal"})
    assert "not planned" in assert_problem(r, 404, field="methods")["detail"]  # not in this plan
    pairs = shared_client.get("/openapi.json").json()["paths"][
        "/api/viewer/comparisons/{kind}/{result_id}"
    ]["get"]["parameters"]
    listed = next(p for p in pairs if p["name"] == "methods")["schema"]["anyOf"][0]["enum"]
    n_pairs = len(METHODS) * (len(METHODS) - 1)  # every ordered pair of two methods
    assert len(listed) == n_pairs and "paper,bound" in listed and "bound,bound" not in listed
    # An array this plan lacks is missing here (404), as a recording's channel; a name that
    # no array could have is refused by the schema (found by schemathesis over HTTP).
    arrays_url = f"/api/plans/{out['id']}/arrays"
    r = shared_client.get(arrays_url, params={"name": ["paper_q", "human_optimal_q"]})
    assert "human_optimal_q" in assert_problem(r, 404, field="name")["detail"]
    assert_problem(shared_client.get(arrays_url, params={"name": ""}), 422, field="name.0")
    # Each export format's media type is documented (mot was text/plain, documented text/csv).
    spec = shared_client.get("/openapi.json").json()["paths"]
    for path in ("/api/plans/{plan_id}/trajectory", "/api/simulations/{simulation_id}/trajectory"):
        documented = set(spec[path]["get"]["responses"]["200"]["content"])
        assert {"text/csv", "text/plain", "application/json", "application/yaml"} <= documented
    mot = shared_client.get(f"/api/plans/{out['id']}/trajectory", params={"format": "mot"})
    assert mot.headers["content-type"].split(";")[0] in documented


def test_profiles_by_rest_are_the_library_comparison(shared_client: TestClient) -> None:
    """``POST /api/profiles``: the classical profiles and methods, as ``bioplan profiles``."""
    from app.db.crud import json_safe
    from app.planning import load_robot
    from app.planning.comparison import compare_profiles

    body = {"robot": "human_arm_2dof", "duration": 1.2, "mtc_intervals": 16,
            "methods": ["quintic", "paper"], "particles": 8, "iterations": 5}  # fmt: skip
    r = shared_client.post("/api/profiles", json=body)
    assert r.status_code == 202, r.text
    job = wait_job(shared_client, r.json()["id"])
    assert job["state"] == "succeeded", job
    assert job["result_url"] == f"/api/profiles/{job['id']}"
    result = shared_client.get(job["result_url"]).json()["result"]
    ref = json_safe(
        compare_profiles(load_robot("human_arm_2dof"), duration=1.2, mtc_intervals=16).to_dict()
    )
    assert result["profiles"] == ref["profiles"]
    assert result["floors"] == ref["floors"]
    assert set(result["methods"]) == {"quintic", "paper"}
    listed = shared_client.get("/api/profiles", params={"robot": "human_arm_2dof"}).json()
    assert job["id"] in [p["id"] for p in listed["items"]]
    # Options change the result: no minimum-torque-change solve, no planning methods.
    r = shared_client.post(
        "/api/profiles", json={**body, "min_torque_change": False, "methods": []}
    )
    job = wait_job(shared_client, r.json()["id"])
    other = shared_client.get(job["result_url"]).json()["result"]
    assert "min_torque_change" in result["profiles"]
    assert "min_torque_change" not in other["profiles"] and "methods" not in other
    r = shared_client.post("/api/profiles", json={**body, "start_deg": [1.0]})
    assert_problem(r, 422, field="start_deg")
    assert_problem(
        shared_client.post("/api/profiles", json={**body, "robot": "x"}), 404, field="robot"
    )
