"""Cohorts through the API (issue 29 item 1): stored recordings in groups (explicit, or by
their condition) compared in a background job; the stored result equals ``cohort_statistics``
run here on the same files, read independently; refused requests store nothing."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

import pytest

from app.jsonsafe import json_safe
from app.services.demo import synthetic_curls_csv
from tests.utils.api import TestClient, assert_problem, make_client, read_sse, wait_job
from tests.utils.data import SHARED_DATA
from tests.utils.jobs import RecordingRunner

#: Two conditions, three recordings each: slow lifts and quick lifts.
FILES = {
    "slow": [(f"slow_{i}.csv", synthetic_curls_csv(lifts=2, seed=i, up=1.6)) for i in range(3)],
    "quick": [
        (f"quick_{i}.csv", synthetic_curls_csv(lifts=2, seed=10 + i, up=0.9)) for i in range(3)
    ],
}


def _upload(client: TestClient, name: str, data: bytes, **form: str) -> int:
    r = client.post("/api/recordings", files=[("files", (name, data))], data=form)
    assert r.status_code == 201, r.text
    rid: int = r.json()["id"]
    return rid


@pytest.fixture(scope="module")
def stored(shared_client: TestClient) -> dict[str, list[int]]:
    """The six recordings uploaded with their condition."""
    return {
        cond: [_upload(shared_client, name, data, condition=cond) for name, data in files]
        for cond, files in FILES.items()
    }


def _close(a: Any, b: Any, path: str = "") -> None:
    """Equal, floats to 1e-12 relative (the job ran in another process)."""
    if isinstance(a, float) and isinstance(b, float):
        assert math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-15), (path, a, b)
    elif isinstance(a, dict) and isinstance(b, dict):
        assert list(a) == list(b), (path, list(a), list(b))
        for k in a:
            _close(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list) and isinstance(b, list):
        assert len(a) == len(b), (path, len(a), len(b))
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _close(x, y, f"{path}.{i}")
    else:
        assert a == b, (path, a, b)


def _direct(files: dict[str, list[tuple[str, bytes]]], **options: Any) -> dict[str, Any]:
    """``cohort_statistics`` on the same bytes, read here (the library's own path)."""
    from app.analysis.cohort import CohortOptions, cohort_statistics
    from app.recordings import read_bytes

    recordings = {g: [read_bytes(data, name) for name, data in fs] for g, fs in files.items()}
    out: dict[str, Any] = json_safe(
        cohort_statistics(recordings, CohortOptions(**options)).to_dict()
    )
    return out


def _run(client: TestClient, body: dict[str, Any]) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    r = client.post("/api/cohorts", json=body)
    assert r.status_code == 202, r.text
    job = r.json()
    assert job["kind"] == "cohort" and r.headers["location"] == f"/api/cohorts/{job['id']}"
    events = [e for _, e in read_sse(client, job["events_url"])]
    assert events[-1]["state"] == "succeeded", events[-1]
    out = client.get(f"/api/cohorts/{job['id']}").json()
    return out, events


@pytest.mark.api_contract
def test_grouped_by_condition_equals_the_library(
    shared_client: TestClient, stored: dict[str, list[int]]
) -> None:
    ids = stored["slow"] + stored["quick"]
    body = {"group_by": "condition", "recording_ids": ids, "options": {"correction": "bonferroni"}}
    out, events = _run(shared_client, body)
    assert out["groups"] == stored
    result = out["result"]
    assert result["recording_ids"] == ids
    want = _direct(FILES, correction="bonferroni")
    _close({k: v for k, v in result.items() if k != "recording_ids"}, want)
    assert result["groups"]["slow"]["n"] == 3 and result["correction"]["method"] == "bonferroni"
    tested = [t for t in result["tests"] if t["p"] is not None]
    assert tested and all(t["test"] in ("welch_t", "mann_whitney_u") for t in tested)
    # Progress: one unit per recording file.
    analyse = [e for e in events if e["stage"] == "analyse"]
    assert analyse and {e["of"] for e in analyse} == {6}
    # The table: one row per recording, with its id and every measure.
    r = shared_client.get(f"/api/cohorts/{out['id']}/csv")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert [int(row["recording_id"]) for row in rows] == ids
    assert float(rows[0]["lift_duration_s"]) == pytest.approx(
        result["recordings"][0]["measures"]["lift_duration_s"], rel=1e-12
    )
    listed = shared_client.get("/api/cohorts").json()
    assert out["id"] in [c["id"] for c in listed["items"]]
    assert shared_client.get("/api/jobs", params={"kind": "cohort"}).json()["total"] >= 1


def test_explicit_groups_and_stored_subjects(
    shared_client: TestClient, stored: dict[str, list[int]]
) -> None:
    """Explicit groups ignore conditions; a stored subject is the one paired on."""
    a, b = stored["slow"], stored["quick"]
    for i, (x, y) in enumerate(zip(a, b, strict=True)):
        for rid in (x, y):
            r = shared_client.patch(
                f"/api/recordings/{rid}", json={"subject": f"S{i}", "analyse": False}
            )
            assert r.status_code == 200, r.text
    try:
        out, _ = _run(shared_client, {"groups": {"A": a, "B": b}, "label": "paired"})
        result = out["result"]
        assert out["label"] == "paired" and out["groups"] == {"A": a, "B": b}
        assert [r["subject"] for r in result["recordings"]] == ["S0", "S1", "S2"] * 2
        assert result["pairings"][0]["design"] == "paired"
        assert "stored subject" in result["subject_rule"]
    finally:
        for rid in a + b:
            shared_client.patch(f"/api/recordings/{rid}", json={"subject": None, "analyse": False})


def test_bad_requests_name_the_field_and_store_nothing(
    shared_client: TestClient, stored: dict[str, list[int]]
) -> None:
    post = shared_client.post
    a, b = stored["slow"], stored["quick"]
    before = shared_client.get("/api/jobs").json()["total"]
    assert_problem(post("/api/cohorts", json={"groups": {"A": a, "B": [999999]}}), 404,
                   field="groups.B.0")  # fmt: skip
    assert_problem(post("/api/cohorts", json={"recording_ids": [a[0], 999999]}), 404,
                   field="recording_ids.1")  # fmt: skip
    assert_problem(post("/api/cohorts", json={"groups": {"A": a}}), 422, field="groups")
    assert_problem(post("/api/cohorts", json={"groups": {"A": a, "B": []}}), 422, field="groups.B")
    two = {"groups": {"A": a, "B": [b[0], a[1]]}}
    body = assert_problem(post("/api/cohorts", json=two), 422, field="groups")
    assert str(a[1]) in body["detail"] and "'A' and 'B'" in body["detail"]
    assert_problem(post("/api/cohorts", json={"groups": {" ": a, "B": b}}), 422, field="groups")
    both = {"groups": {"A": a, "B": b}, "group_by": "condition"}
    assert_problem(post("/api/cohorts", json=both), 422, field="group_by")
    bad = {"groups": {"A": a, "B": b}, "options": {"alpha": 1.5}}
    assert_problem(post("/api/cohorts", json=bad), 422, field="options.alpha")
    bad = {"groups": {"A": a, "B": b}, "options": {"subject_pattern": "("}}
    assert_problem(post("/api/cohorts", json=bad), 422, field="options.subject_pattern")
    bad = {"groups": {"A": a, "B": b}, "options": {"paired": "maybe"}}
    assert_problem(post("/api/cohorts", json=bad), 422, field="options.paired")
    one = {"recording_ids": a}  # all of one condition
    assert_problem(post("/api/cohorts", json=one), 409, field="group_by")
    assert shared_client.get("/api/jobs").json()["total"] == before
    assert_problem(shared_client.get("/api/cohorts/999999"), 404)


def test_condition_is_stored_searched_and_cleared(
    shared_client: TestClient, stored: dict[str, list[int]]
) -> None:
    rid = stored["slow"][0]
    detail = shared_client.get(f"/api/recordings/{rid}").json()
    assert detail["condition"] == "slow"
    found = shared_client.get("/api/recordings", params={"q": "quick"}).json()
    assert {r["id"] for r in found["items"]} == set(stored["quick"])
    assert all(r["condition"] == "quick" for r in found["items"])
    extra = _upload(shared_client, "extra.csv", FILES["slow"][0][1])
    try:
        r = shared_client.patch(
            f"/api/recordings/{extra}", json={"condition": " x ", "analyse": False}
        )
        assert r.json()["condition"] == "x"
        r = shared_client.patch(
            f"/api/recordings/{extra}", json={"condition": "", "analyse": False}
        )
        assert r.json()["condition"] is None
        # Without a condition it cannot be grouped by one (409 naming it) ...
        r = shared_client.post("/api/cohorts", json={"recording_ids": [stored["slow"][0], extra]})
        assert_problem(r, 409, field="recording_ids.1")
    finally:
        shared_client.delete(f"/api/recordings/{extra}")


def test_delete_removes_the_result(shared_client: TestClient, stored: dict[str, list[int]]) -> None:
    r = shared_client.post(
        "/api/cohorts", json={"groups": {"A": stored["slow"][:1], "B": stored["quick"][:1]}}
    )
    assert r.status_code == 202, r.text
    cid = r.json()["id"]
    wait_job(shared_client, cid)
    assert shared_client.delete(f"/api/cohorts/{cid}").status_code == 204
    assert_problem(shared_client.get(f"/api/cohorts/{cid}"), 404)
    assert_problem(shared_client.get(f"/api/jobs/{cid}"), 404)
    assert_problem(shared_client.delete(f"/api/cohorts/{cid}"), 404)


def test_options_come_from_the_library(shared_client: TestClient) -> None:
    from dataclasses import fields

    from app.analysis.cohort import CohortOptions

    got = shared_client.get("/api/cohorts/options").json()
    assert [o["name"] for o in got] == [f.name for f in fields(CohortOptions)]
    assert {o["name"]: o["default"] for o in got} == CohortOptions.defaults()
    schema = shared_client.get("/openapi.json").json()["components"]["schemas"]["CohortOptionsIn"]
    assert schema["properties"]["alpha"]["exclusiveMaximum"] == 1.0
    assert schema["properties"]["correction"]["enum"] == ["holm", "bonferroni", "fdr_bh", "none"]
    assert schema["properties"]["min_n"]["minimum"] == 2
    assert schema["properties"]["subject_pattern"]["maxLength"] == 200
    # The page's names for the bounds (low/high exclusive, minimum inclusive) and JSON types.
    info = {o["name"]: o for o in got}
    assert (info["alpha"]["low"], info["alpha"]["high"]) == (0.0, 1.0)
    assert (info["emg_rate"]["low"], info["emg_rate"]["unit"]) == (0.0, "Hz")
    assert (info["min_n"]["minimum"], info["min_n"]["type"]) == (2, "integer")
    assert info["paired"]["choices"] == ["auto", "yes", "no"]
    assert info["alpha"]["type"] == "number" and info["test"]["type"] == "string"


def test_real_noraxon_recordings(client: TestClient) -> None:
    """The two shared Noraxon curls (two grips) as one-recording groups: measured, no test
    (too few values), each skipped comparison saying why."""
    folder = SHARED_DATA / "noraxon_curls_biceps_brachioradialis"
    names = ["2023-04-20-15-06_BR_posredni.csv", "2023-04-20-15-07_BR_podchwyt.csv"]
    if not all((folder / n).is_file() for n in names):
        pytest.skip(f"real test data not found: {folder}")
    files = {n.rsplit("_", 1)[1][:-4]: [(n, (folder / n).read_bytes())] for n in names}
    ids = {g: [_upload(client, n, data, condition=g)] for g, [(n, data)] in files.items()}
    r = client.post("/api/cohorts", json={"group_by": "condition"})
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"], timeout=600)
    assert job["state"] == "succeeded", job
    out = client.get(f"/api/cohorts/{job['id']}").json()
    assert out["groups"] == ids
    result = out["result"]
    _close({k: v for k, v in result.items() if k != "recording_ids"}, _direct(files))
    assert all(t["p"] is None and "too few" in t["skipped"] for t in result["tests"])


def test_cancel_and_delete_a_waiting_cohort(tmp_path: Path) -> None:
    """Cancel works as for every job (the runner is told, the job ends cancelled, no result);
    deleting one still queued cancels it first."""
    runner = RecordingRunner()
    with make_client(tmp_path, runner=runner) as client:
        a = _upload(client, *FILES["slow"][0], condition="slow")
        b = _upload(client, *FILES["quick"][0], condition="quick")
        first = client.post("/api/cohorts", json={"group_by": "condition"}).json()
        assert (first["id"], "cohort") in runner.submitted
        r = client.post(f"/api/jobs/{first['id']}/cancel")
        assert r.status_code == 200 and r.json()["state"] == "cancelled"
        assert runner.cancelled == [first["id"]]
        out = client.get(f"/api/cohorts/{first['id']}").json()
        assert out["job"]["state"] == "cancelled" and out["result"] is None
        assert out["groups"] == {"slow": [a], "quick": [b]}
        assert_problem(client.get(f"/api/cohorts/{first['id']}/csv"), 409)
        second = client.post("/api/cohorts", json={"groups": {"x": [a], "y": [b]}}).json()
        assert client.delete(f"/api/cohorts/{second['id']}").status_code == 204
        assert runner.cancelled == [first["id"], second["id"]]
        assert [c["id"] for c in client.get("/api/cohorts").json()["items"]] == [first["id"]]
