"""Pareto fronts through the API (issue 26 item 4): the job with per-point progress and cancel,
the result against the library's own front, the references, the CSV, a point's export read
back against the stored trajectory, the viewer address and the comparison it shows, bad
requests named, and every request option visible in the stored result."""

from __future__ import annotations

import csv
import io
import json
import time
from collections.abc import Iterator
from typing import Any
from urllib.parse import unquote

import numpy as np
import pytest

from tests.utils.api import TestClient, assert_problem, make_client, read_sse, wait_job
from tests.utils.server import free_port

#: A cheap front: the 2-DOF arm, three points, a coarse first mesh and a loose tolerance.
SMALL = {
    "robot": "human_arm_2dof",
    "payload_mass": 5.0,
    "objectives": ["tau_sq", "jerk"],
    "points": 3,
    "intervals": 20,
    "tolerance": 0.01,
}
#: The axes as written out by hand (the schema's list is checked against them).
AXES = (
    "tau_sq",
    "abs_work",
    "pos_work",
    "electrical_energy",
    "peak_power",
    "peak_torque",
    "jerk",
    "duration",
)


@pytest.fixture(scope="module")
def viewer_client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """The app with its 3-D viewer running."""
    with make_client(
        tmp_path_factory.mktemp("fronts"), viewer=True, viewer_port=free_port()
    ) as client:
        yield client


def _submit(client: TestClient, **body: Any) -> dict[str, Any]:
    r = client.post("/api/fronts", json={**SMALL, **body})
    assert r.status_code == 202, r.text
    job: dict[str, Any] = r.json()
    assert job["kind"] == "front" and job["result_url"] == f"/api/fronts/{job['id']}"
    assert r.headers["location"] == job["result_url"]
    return job


def _front(client: TestClient, **body: Any) -> dict[str, Any]:
    """A finished front's ``ResultOut``."""
    job = wait_job(client, _submit(client, **body)["id"], timeout=600)
    assert job["state"] == "succeeded", job
    out: dict[str, Any] = client.get(job["result_url"]).json()
    return out


@pytest.fixture(scope="module")
def small(viewer_client: TestClient) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The small front (its ``ResultOut``) and its job's events."""
    job = _submit(viewer_client, label="arm trade-off")
    events = [e for _, e in read_sse(viewer_client, job["events_url"])]
    assert events[-1]["state"] == "succeeded", events[-1]
    return viewer_client.get(job["result_url"]).json(), events


def _arrays(client: TestClient, front_id: int, *names: str) -> dict[str, np.ndarray]:
    r = client.get(f"/api/fronts/{front_id}/arrays", params={"points": 10_000, "name": list(names)})
    assert r.status_code == 200, r.text
    return {k: np.asarray(v, dtype=float) for k, v in r.json()["arrays"].items()}


def test_the_job_reports_every_point_and_equals_the_library(
    small: tuple[dict[str, Any], list[dict[str, Any]]],
) -> None:
    from app.planning import load_robot
    from app.planning.front import pareto_front
    from app.services.jobs import job_summary

    out, events = small
    assert out["label"] == "arm trade-off" and out["robot"] == "human_arm_2dof"
    # The jobs drawer's line for it.
    assert job_summary(out["job"])["about"] == "human_arm_2dof, 5 kg, tau_sq vs jerk, 3 points"
    # The stream shows the job's latest state when it is read, so a point's report can be
    # overtaken by the next (the library's own calls are checked below): the points it shows
    # count up to 3.
    per_point = [(e["done"], e["of"]) for e in events if e["stage"] == "front"]
    assert per_point and {of for _, of in per_point} == {3}, per_point
    assert [d for d, _ in per_point] == sorted(d for d, _ in per_point)
    fractions = [e["progress"] for e in events]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    result = out["result"]
    assert "motions" not in result  # the exports' internal block is not served
    reports: list[tuple[int, int]] = []
    ref = pareto_front(
        load_robot("human_arm_2dof", payload=5.0),
        objectives=("tau_sq", "jerk"),
        points=3,
        n_intervals=20,
        tolerance=0.01,
        progress=lambda p: reports.append((p.done, p.of)) if p.stage == "front" else None,
    ).to_dict()
    assert reports == [(1, 3), (2, 3), (3, 3)]  # one report per point
    assert [p["id"] for p in result["points"]] == ["p0", "p1", "p2"]
    for got, want in zip(result["points"], ref["points"], strict=True):
        for axis in AXES:
            assert got[axis] == pytest.approx(want[axis], rel=1e-9), axis
    assert result["knee"] == ref["knee"] == "p1"
    assert result["methods"] == ["quintic", "p0", "p1", "p2"]


def test_the_references_are_the_planner_at_the_fronts_duration(
    small: tuple[dict[str, Any], list[dict[str, Any]]], viewer_client: TestClient
) -> None:
    """The quintic's point is the closed form's, at the front's 1 s; every reference has every
    axis (or its error)."""
    from app.planning import load_robot
    from app.planning.evaluation import PlanTask, evaluate_trajectory
    from app.planning.methods import objective_value
    from app.planning.profiles import quintic

    out, _ = small
    refs = out["result"]["references"]
    assert set(refs) == {"quintic", "paper", "jerk_limited"}
    for name, values in refs.items():
        assert "error" in values or set(AXES) <= set(values), (name, values)
    assert refs["quintic"]["duration"] == 1.0
    robot = load_robot("human_arm_2dof", payload=5.0)
    task = PlanTask.default(robot)
    ev = evaluate_trajectory(robot, quintic(task.start, task.goal, 1.0, n_samples=1000), task)
    assert refs["quintic"]["tau_sq"] == pytest.approx(objective_value(robot, ev, "tau_sq"), 1e-9)
    # The paper's PSO minimises the front's A (tau_sq, a planner objective): below the quintic.
    assert refs["paper"]["tau_sq"] < refs["quintic"]["tau_sq"]
    # The stored quintic's torque is the closed form's (its own grid, ``quintic_t``).
    arrays = _arrays(viewer_client, out["id"], "quintic_t", "quintic_tau")
    np.testing.assert_allclose(arrays["quintic_t"], ev.trajectory.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(arrays["quintic_tau"], ev.tau, rtol=1e-9, atol=1e-9)


def test_the_csv_is_the_json(
    small: tuple[dict[str, Any], list[dict[str, Any]]], viewer_client: TestClient
) -> None:
    out, _ = small
    r = viewer_client.get(f"/api/fronts/{out['id']}/csv")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    assert f'filename="bioplan-front-{out["id"]}.csv"' in r.headers["content-disposition"]
    rows = list(csv.reader(io.StringIO(r.text)))
    others = [a for a in AXES if a not in ("tau_sq", "jerk")]
    assert rows[0] == ["id", "tau_sq", "jerk", *others, "human_likeness", "knee", "end"]
    points = out["result"]["points"]
    assert [row[0] for row in rows[1:]] == [p["id"] for p in points]
    for row, point in zip(rows[1:], points, strict=True):
        for column, cell in zip(rows[0][1:-2], row[1:-2], strict=True):
            assert float(cell) == point[column], column  # the shortest text of the same float
        assert row[-2] == ("true" if point["knee"] else "false")
        assert row[-1] == (point["end"] or "")


def test_a_point_exports_as_its_stored_trajectory(
    small: tuple[dict[str, Any], list[dict[str, Any]]], viewer_client: TestClient
) -> None:
    out, _ = small
    fid = out["id"]
    stored = _arrays(viewer_client, fid, "p1_t", "p1_q", "p1_qd", "p1_tau")
    n = stored["p1_t"].size
    r = viewer_client.get(
        f"/api/fronts/{fid}/points/p1/export", params={"format": "json", "samples": n}
    )
    assert r.status_code == 200, r.text
    assert f'filename="front-{fid}-p1.json"' in r.headers["content-disposition"]
    doc = json.loads(r.content)
    assert doc["method"] == "p1" and doc["method_kind"] == "piecewise_quintic"
    t = np.asarray(doc["t"])
    np.testing.assert_allclose(t, stored["p1_t"], rtol=0, atol=1e-12)
    # The file joins the optimum's knots by quintic Hermite segments: its samples are the
    # stored ones up to the solver's continuity tolerance (1e-8 rad here; the torque, through
    # the acceleration, to 0.2 mNm of torques up to tens of Nm).
    np.testing.assert_allclose(np.asarray(doc["q"]), stored["p1_q"], rtol=0, atol=1e-7)
    np.testing.assert_allclose(np.asarray(doc["qd"]), stored["p1_qd"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.asarray(doc["tau"]), stored["p1_tau"], rtol=0, atol=1e-3)
    assert np.abs(stored["p1_tau"]).max() > 1.0
    # CSV too, with the plan export's options (a rate).
    r = viewer_client.get(
        f"/api/fronts/{fid}/points/quintic/export", params={"format": "csv", "rate": 100}
    )
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    body = [line for line in r.text.splitlines() if not line.startswith("#")]
    assert len(body) == 1 + 101  # header, then 0 .. 1 s at 100 Hz
    # An unknown point is a 404 naming pid; a bad option a 422 naming it, as for plans.
    missing = viewer_client.get(f"/api/fronts/{fid}/points/p9/export", params={"format": "csv"})
    assert_problem(missing, 404, field="pid")
    both = viewer_client.get(
        f"/api/fronts/{fid}/points/p1/export", params={"format": "csv", "rate": 10, "samples": 5}
    )
    assert_problem(both, 422, field="samples")
    assert_problem(viewer_client.get(f"/api/fronts/{fid + 999}/csv"), 404)


def test_the_view_plays_the_point_beside_the_quintic(
    small: tuple[dict[str, Any], list[dict[str, Any]]], viewer_client: TestClient
) -> None:
    out, _ = small
    fid = out["id"]
    r = viewer_client.get(f"/api/fronts/{fid}/points/p2/view")
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["point"] == out["result"]["points"][2]
    viewer = body["viewer"]
    assert viewer["enabled"] and viewer["path"] == f"/bioplan/front/{fid}"
    websocket = unquote(viewer["url"].split("websocket=")[1].split("&hideViserLogo")[0])
    # The point solid, the quintic its ghost.
    assert f"/bioplan/front/{fid}?token=" in websocket and "methods=p2,quintic" in websocket
    assert_problem(viewer_client.get(f"/api/fronts/{fid}/points/p7/view"), 404, field="pid")
    # The quintic reference is viewable too: beside the knee, at the same duration.
    quintic = viewer_client.get(f"/api/fronts/{fid}/points/quintic/view").json()
    assert quintic["point"] == {"id": "quintic", **out["result"]["references"]["quintic"]}
    assert "%26methods%3Dquintic%2Cp1&" in quintic["viewer"]["url"]
    # The comparison the viewer shows: the point on its own grid beside the quintic.
    services = viewer_client.app.state.services  # type: ignore[attr-defined]
    comparison = services.comparisons("front", fid, ("p2", "quintic")).comparison
    stored = _arrays(viewer_client, fid, "p2_t", "p2_q", "quintic_q")
    np.testing.assert_array_equal(comparison.t, stored["p2_t"])
    np.testing.assert_array_equal(comparison.q["p2"], stored["p2_q"])
    np.testing.assert_array_equal(comparison.q["quintic"], stored["quintic_q"])
    assert comparison.shown == ("p2", "quintic") and comparison.choices == ("p2", "quintic")
    np.testing.assert_array_equal(comparison.q["standard"], stored["p2_q"])  # the solid robot
    from app.services.errors import NotFoundError

    with pytest.raises(NotFoundError, match="beside the quintic"):
        services.comparisons("front", fid, ("p2", "p1"))


def test_every_option_shows_in_the_result(viewer_client: TestClient) -> None:
    """method, points, intervals, tolerance, allow_reversal, payload_mass, duration, start and
    goal each change the stored front (against the small front's defaults)."""
    base = _front(viewer_client)["result"]
    options = {
        "method": "human_optimal",
        "points": 2,
        "intervals": 16,
        "tolerance": 0.05,
        "allow_reversal": True,
        "payload_mass": 3.0,
        "duration": 1.2,
        "start_deg": [0.0, 10.0],
        "goal_deg": [0.0, 100.0],
    }
    other = _front(viewer_client, **options)["result"]
    # template: human_optimal's elbow peak where the template says (40 deg, not the paper's 62).
    early = _front(viewer_client, **options, template={"peak_velocity_angle_deg": 40.0})["result"]
    assert early["points"][0]["tau_sq"] != pytest.approx(other["points"][0]["tau_sq"], rel=1e-3)
    assert early["points"][0]["human_likeness"] != other["points"][0]["human_likeness"]
    assert (base["method"], other["method"]) == ("bound", "human_optimal")
    assert any(r.startswith("human-like") for r in other["rules"])
    assert (len(base["points"]), len(other["points"])) == (3, 2)
    first = [r["points"][0]["convergence"] for r in (base, other)]
    assert [c["sequence"][0]["n_intervals"] for c in first] == [20, 16]
    assert [c["tolerance"] for c in first] == [0.01, 0.05]
    assert "no joint reversal" in base["rules"] and "no joint reversal" not in other["rules"]
    assert (base["payload_mass"], other["payload_mass"]) == (5.0, 3.0)
    assert (base["duration"], other["duration"]) == (1.0, 1.2)
    assert other["references"]["quintic"]["duration"] == 1.2
    assert other["conditions"]["start_deg"] == pytest.approx([0.0, 10.0])
    assert other["conditions"]["goal_deg"] == pytest.approx([0.0, 100.0])
    assert base["conditions"]["goal_deg"] != other["conditions"]["goal_deg"]


def test_a_duration_axis_and_its_longest_duration(viewer_client: TestClient) -> None:
    """max_duration ends the duration axis; each point is viewed beside the quintic at its own
    duration (the closed-form quintic on the point's grid)."""
    from app.planning import load_robot
    from app.planning.evaluation import PlanTask

    out = _front(
        viewer_client,
        objectives=["duration", "tau_sq"],
        points=2,
        intervals=8,
        tolerance=0.05,
        max_duration=1.5,
    )
    result = out["result"]
    durations = [p["duration"] for p in result["points"]]
    assert durations[-1] == pytest.approx(1.5, rel=1e-12)
    assert durations[0] == pytest.approx(result["shortest_duration"]["duration"], rel=1e-12)
    assert result["knee"] is None and result["references"]["quintic"]["duration"] == 1.0
    services = viewer_client.app.state.services  # type: ignore[attr-defined]
    comparison = services.comparisons("front", out["id"], ("p0", "quintic")).comparison
    assert comparison.duration == pytest.approx(durations[0], rel=1e-12)
    task = PlanTask.default(load_robot("human_arm_2dof", payload=5.0))
    s = (comparison.t / comparison.t[-1])[:, None]
    closed = task.start + (task.goal - task.start) * s**3 * (10 - 15 * s + 6 * s**2)
    np.testing.assert_allclose(comparison.q["quintic"], closed, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"objectives": ["tau_sq", "energy"]}, "objectives.1"),
        ({"objectives": ["jerk", "jerk"]}, "objectives"),
        ({"objectives": ["jerk"]}, "objectives"),
        ({"points": 1}, "points"),
        ({"objectives": ["duration", "tau_sq"], "duration": 1.2}, "duration"),
        ({"max_duration": 3.0}, "max_duration"),
        ({"intervals": 4}, "intervals"),
        ({"start_deg": [0.0]}, "start_deg"),
        ({"template": {"peak_velocity_angle_deg": "high"}}, "template"),
        ({"template": {}, "template_analysis_id": 3}, "template"),
    ],
)
def test_bad_fronts_are_refused_naming_the_field(
    viewer_client: TestClient, body: dict[str, Any], field: str
) -> None:
    before = viewer_client.get("/api/jobs").json()["total"]
    assert_problem(viewer_client.post("/api/fronts", json={**SMALL, **body}), 422, field=field)
    assert viewer_client.get("/api/jobs").json()["total"] == before  # nothing queued
    unknown = viewer_client.post("/api/fronts", json={**SMALL, "robot": "r2d2"})
    assert_problem(unknown, 404, field="robot")
    no_analysis = viewer_client.post("/api/fronts", json={**SMALL, "template_analysis_id": 999})
    assert_problem(no_analysis, 404, field="template_analysis_id")


def test_list_rename_cancel_delete_and_no_viewer(client: TestClient) -> None:
    """Without a viewer the view says so; a running front is cancelled by the jobs' route and
    keeps no result; rename and delete work on a front as on the other results."""
    done = _front(client)
    view = client.get(f"/api/fronts/{done['id']}/points/p0/view").json()
    assert view["viewer"] == {"enabled": False} and view["point"]["id"] == "p0"
    renamed = client.patch(f"/api/fronts/{done['id']}", json={"label": "knee hunt"})
    assert renamed.status_code == 200 and renamed.json()["label"] == "knee hunt"
    assert "motions" not in renamed.json()["result"]

    # A front on the 6-DOF arm with many points and a tight tolerance runs for minutes.
    long = _submit(
        client,
        robot="curtain_wall_6dof",
        payload_mass=None,
        objectives=["peak_power", "abs_work"],
        points=25,
        intervals=40,
        tolerance=1e-4,
    )
    deadline = time.monotonic() + 300
    while client.get(f"/api/jobs/{long['id']}").json()["state"] == "queued":
        assert time.monotonic() < deadline, "the long front never started"
        time.sleep(0.1)
    assert client.get(f"/api/jobs/{long['id']}").json()["state"] == "running"
    r = client.post(f"/api/jobs/{long['id']}/cancel")
    assert r.status_code == 200 and r.json()["state"] == "cancelled", r.text
    cancelled = client.get(f"/api/fronts/{long['id']}").json()
    assert cancelled["job"]["state"] == "cancelled" and cancelled["result"] is None
    assert_problem(client.get(f"/api/fronts/{long['id']}/csv"), 409)

    listed = client.get("/api/fronts", params={"state": "succeeded"}).json()
    assert [item["id"] for item in listed["items"]] == [done["id"]] and listed["total"] == 1
    assert all("motions" not in item["result"] for item in listed["items"])
    assert client.get("/api/fronts").json()["total"] == 2

    for fid in (long["id"], done["id"]):
        assert client.delete(f"/api/fronts/{fid}").status_code == 204
        assert_problem(client.get(f"/api/fronts/{fid}"), 404)
    assert client.get("/api/fronts").json()["total"] == 0


def test_the_schema_axes_are_the_librarys() -> None:
    from app.api.schemas import FRONT_AXES as API_AXES
    from app.planning.front import FRONT_AXES

    assert API_AXES == FRONT_AXES == AXES
