"""Jobs through the API: analysis results equal the library's, SSE progress, errors, cancel."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from tests.utils.api import TestClient, assert_problem, read_sse, wait_job
from tests.utils.data import shared_file

NORAXON = "noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv"


def _json(value: Any) -> Any:
    """What a value looks like after a JSON round trip (tuples -> lists, NaN -> null)."""
    from app.db.crud import json_safe

    return json.loads(json.dumps(json_safe(value)))


def _upload(client: TestClient, path: Path, **form: str) -> int:
    r = client.post("/api/recordings", files=[("files", (path.name, path.read_bytes()))], data=form)
    assert r.status_code == 201, r.text
    rid: int = r.json()["id"]
    return rid


def test_analysis_result_and_template_equal_the_library(client: TestClient) -> None:
    from app.analysis import analyze_recordings
    from app.recordings import read_bytes

    path = shared_file(NORAXON)
    rid = _upload(client, path, load_kg="12")
    r = client.post("/api/analyses", json={"recording_id": rid})
    assert r.status_code == 202, r.text
    job = r.json()
    assert job["kind"] == "analysis" and job["state"] in {"queued", "running"}
    assert r.headers["location"] == job["result_url"] == f"/api/analyses/{job['id']}"

    events = read_sse(client, job["events_url"])
    names = [n for n, _ in events]
    assert names[-1] == "done" and names.count("done") == 1
    assert set(names[:-1]) == {"progress"}
    done = events[-1][1]
    assert done["state"] == "succeeded" and done["progress"] == 1.0
    assert done["started_at"] is not None and done["run_seconds"] >= 0
    progress = [e["progress"] for _, e in events]
    assert progress == sorted(progress)

    expected = analyze_recordings([read_bytes(path.read_bytes(), path.name)], load_mass=12.0)
    out = client.get(job["result_url"]).json()
    assert out["recording_id"] == rid and out["job"]["state"] == "succeeded"
    # The service echoes the reader options it read the files with, beside the library's.
    expected.settings.update(
        rate_hz=None, frame_rate_hz=None, image_size_px=None, format=None, side="auto"
    )
    assert out["result"] == _json(expected.to_dict())
    template = client.get(f"/api/analyses/{job['id']}/template").json()
    assert template == _json(expected.template.to_dict())
    listed = client.get("/api/analyses", params={"state": "succeeded"}).json()
    assert [a["id"] for a in listed["items"]] == [job["id"]]


def test_job_errors_are_problems(client: TestClient, tmp_path: Path) -> None:
    assert_problem(
        client.post("/api/analyses", json={"recording_id": 42}), 404, field="recording_id"
    )
    assert_problem(client.post("/api/analyses", json={"recording_id": 1, "x": 1}), 422, field="x")
    assert_problem(client.get("/api/jobs/999"), 404)
    assert_problem(client.get("/api/jobs/999/events"), 404)
    assert_problem(client.post("/api/jobs/999/cancel"), 404)
    assert_problem(client.get("/api/analyses/999"), 404)
    assert_problem(client.get("/api/jobs/0"), 422)
    r = client.post("/api/analyses", json={"recording_id": 1, "phase_bounds_deg": [90, 40]})
    assert_problem(r, 422, field="phase_bounds_deg")


def test_a_job_whose_input_vanished_fails_with_the_reason(
    client: TestClient, tmp_path: Path
) -> None:
    path = shared_file(NORAXON)
    rid = _upload(client, path)
    detail = client.get(f"/api/recordings/{rid}").json()
    sha = detail["files"][0]["sha256"]
    (tmp_path / "data" / "blobs" / sha[:2] / sha).unlink()  # behind the server's back
    job = client.post("/api/analyses", json={"recording_id": rid}).json()
    done = wait_job(client, job["id"])
    assert done["state"] == "failed"
    assert sha in done["error"] and "missing" in done["error"]
    assert_problem(client.get(f"/api/analyses/{job['id']}/template"), 409)
    # A finished job cannot be cancelled.
    assert_problem(client.post(f"/api/jobs/{job['id']}/cancel"), 409)
    events = read_sse(client, job["events_url"])
    assert [n for n, _ in events] == ["progress", "done"]
    assert events[-1][1]["state"] == "failed"
    jobs = client.get("/api/jobs", params={"state": "failed", "kind": "analysis"}).json()
    assert jobs["total"] == 1 and jobs["items"][0]["id"] == job["id"]


def test_session_of_two_files_analysed_together(client: TestClient) -> None:
    from app.analysis import analyze_recordings
    from app.recordings import read_bytes

    emg = shared_file(NORAXON)
    pose = shared_file("mediapipe_bicep_curl_frames/test.csv")
    files = [("files", (p.name, p.read_bytes())) for p in (emg, pose)]
    r = client.post("/api/recordings", files=files, data={"frame_rate": "30", "load_kg": "12"})
    assert r.status_code == 201, r.text
    body = {"recording_id": r.json()["id"], "together": True, "offset": 0.0, "body_mass": 80}
    job = client.post("/api/analyses", json=body).json()
    done = wait_job(client, job["id"])
    assert done["state"] == "succeeded", done
    recs = [
        read_bytes(emg.read_bytes(), emg.name),
        read_bytes(pose.read_bytes(), pose.name, frame_rate=30.0),
    ]
    expected = analyze_recordings(recs, together=True, offset=0.0, body_mass=80.0, load_mass=12.0)
    expected.settings.update(
        rate_hz=None, frame_rate_hz=30.0, image_size_px=None, format=None, side="auto"
    )
    assert client.get(done["result_url"]).json()["result"] == _json(expected.to_dict())
