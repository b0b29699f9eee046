"""Issue 23 item 12: no answer about a stored result names a folder of the server.

A plan of an uploaded robot keeps how to rebuild that robot (``motion.robot_spec``) with the
files' places in the data directory; the API serves the plan with file names only.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from tests.utils.api import TestClient, wait_job


def _server_paths(value: Any) -> Iterator[str]:
    """Every string in a JSON document that is an absolute file path (the API's own URLs
    are no file paths)."""
    if isinstance(value, dict):
        for item in value.values():
            yield from _server_paths(item)
    elif isinstance(value, list):
        for item in value:
            yield from _server_paths(item)
    elif isinstance(value, str) and value.startswith("/") and not value.startswith("/api/"):
        yield value


def test_a_plan_of_an_uploaded_robot_names_no_server_folder(
    client: TestClient, two_link_urdf: str, tmp_path: Path
) -> None:
    files = {"urdf": ("arm.urdf", two_link_urdf.encode(), "application/xml")}
    r = client.post("/api/robots", data={"name": "lab_arm", "payload": "1.0"}, files=files)
    assert r.status_code == 201, r.text
    body = {"robot": "lab_arm", "duration": 1.0, "methods": ["quintic", "jerk_limited"]}
    r = client.post("/api/plans", json=body)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"], timeout=300)
    assert job["state"] == "succeeded", job
    folder = str(tmp_path)
    for url in (job["result_url"], "/api/plans", f"/api/jobs/{job['id']}"):
        r = client.get(url)
        assert r.status_code == 200, r.text
        assert folder not in r.text, url
        assert list(_server_paths(r.json())) == [], url
    spec = client.get(job["result_url"]).json()["result"]["motion"]["robot_spec"]
    assert spec["source"] == Path(spec["source"]).name
    # The stored result still rebuilds the robot: the comparison and an export work.
    r = client.get(f"{job['result_url']}/trajectory", params={"format": "json"})
    assert r.status_code == 200, r.text
    assert folder not in json.dumps(r.json())
    assert list(_server_paths(r.json())) == []


def test_a_failed_jobs_error_names_files_not_their_folders() -> None:
    """A job's error and message come from its task (a library's own text can name the file it
    failed on, an ImportError its site-packages): the API shows the file name only."""
    from app.db.models import JobRecord
    from app.services.jobs import job_to_dict

    job = JobRecord(
        id=7, kind="plan", state="failed", progress=0.0, attempts=1, params={},
        error="cannot load /srv/bioplan/data/robots/ab12/arm.urdf: no <robot> (rad/s, m/s^2)",
        message="failed reading /usr/lib/python3/site-packages/casadi/libipopt.so",
    )  # fmt: skip
    shown = job_to_dict(job)
    assert shown["error"] == "cannot load arm.urdf: no <robot> (rad/s, m/s^2)"
    assert shown["message"] == "failed reading libipopt.so"
