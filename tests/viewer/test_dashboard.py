"""The dashboard attached to the real app: pages, assets, viewer routes, the demo seed."""

from __future__ import annotations

import json
import socket
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from starlette.exceptions import StarletteDeprecationWarning

from app.config import Settings
from app.main import create_app
from app.viewer import attach_dashboard, seed_demo
from app.viewer.demo_seed import seed_into
from app.viewer.routes import plotly_js_path

with warnings.catch_warnings():
    warnings.simplefilter("ignore", StarletteDeprecationWarning)
    from fastapi.testclient import TestClient


TERMINAL = ("succeeded", "failed", "cancelled")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def dashboard(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, Any]]:
    settings = Settings(
        data_dir=tmp_path_factory.mktemp("dash"), viewer_port=free_port(), max_workers=2
    )
    app = create_app(settings)
    attach_dashboard(app, settings)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StarletteDeprecationWarning)
        client = TestClient(app)
    with client:
        ids = seed_into(app.state.services, timeout=120)
        yield client, ids


def test_pages_and_assets_are_served(dashboard: tuple[TestClient, Any]) -> None:
    client, _ = dashboard
    index = client.get("/")
    assert index.status_code == 200 and index.headers["content-type"].startswith("text/html")
    assert '<script type="module" src="/js/app.js">' in index.text
    for path, kind in (("/style.css", "text/css"), ("/js/compare.js", "javascript")):
        r = client.get(path)
        assert r.status_code == 200 and kind in r.headers["content-type"], path
    plotly = client.get("/api/viewer/assets/plotly.min.js")
    assert plotly.status_code == 200
    assert plotly.content == plotly_js_path().read_bytes()
    again = client.get(
        "/api/viewer/assets/plotly.min.js", headers={"If-None-Match": plotly.headers["etag"]}
    )
    assert again.status_code == 304
    # An unknown API path is still an API problem, not a page.
    missing = client.get("/api/nothing-here")
    assert missing.status_code == 404
    assert missing.headers["content-type"].startswith("application/problem+json")


def test_viewer_address_is_the_real_one(dashboard: tuple[TestClient, Any]) -> None:
    client, _ = dashboard
    info = client.get("/api/viewer").json()
    viewer = client.app.state.dashboard.viewer  # type: ignore[attr-defined]
    assert info["enabled"] and info["port"] == viewer.port
    with socket.create_connection(("127.0.0.1", info["port"]), timeout=5):
        pass
    assert client.get("/api/viewer/sessions").json() == []


def test_comparison_curves_and_viewer_link(dashboard: tuple[TestClient, Any]) -> None:
    client, ids = dashboard
    sim = ids["simulation"]
    body = client.get(f"/api/viewer/comparisons/simulation/{sim}", params={"points": 120}).json()
    assert body["kind"] == "simulation" and body["id"] == sim
    assert len(body["curves"]["t"]) == 120
    assert len(body["curves"]["optimized"]["tau"][0]) == len(body["joint_names"]) == 6
    result = client.get(f"/api/simulations/{sim}").json()["result"]
    assert body["result"] == result
    a, b = body["phase_times"]["optimized"]
    assert 0.0 < a < b < body["duration"]
    assert body["viewer"]["enabled"]
    assert body["viewer"]["url"].endswith(f"/bioplan/simulation/{sim}&hideViserLogo")
    plan = client.get(f"/api/viewer/comparisons/plan/{ids['plan']}").json()
    # The demo plan used the demo recording's template (not the paper's defaults).
    assert plan["result"]["conditions"]["template_lifts"] == 4


def test_comparison_errors(dashboard: tuple[TestClient, Any]) -> None:
    from app.db import crud

    client, _ = dashboard
    r = client.get("/api/viewer/comparisons/plan/999")
    assert r.status_code == 404 and "plan 999 does not exist" in r.json()["detail"]
    r = client.get("/api/viewer/comparisons/sweep/1")
    assert r.status_code == 422 and r.headers["content-type"].startswith("application/problem")
    services = client.app.state.services  # type: ignore[attr-defined]
    with services.sessions() as session:
        # A job row that no runner picks up: queued for ever.
        job = crud.create_job(
            session=session,
            kind="plan",
            params={"robot": "curtain_wall_6dof"},
            resource={"robot": "curtain_wall_6dof"},
        )
        queued = job.id
    r = client.get(f"/api/viewer/comparisons/plan/{queued}")
    assert r.status_code == 409 and "job state queued" in r.json()["detail"]


@pytest.mark.parametrize("fmt", ["scene", "report"])
def test_exports(dashboard: tuple[TestClient, Any], fmt: str) -> None:
    client, ids = dashboard
    r = client.get(f"/api/viewer/comparisons/plan/{ids['plan']}/export", params={"format": fmt})
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/html")
    name = f"bioplan-plan-{ids['plan']}-{fmt}.html"
    assert r.headers["content-disposition"] == f'attachment; filename="{name}"'
    marker = "__VISER_EMBED_DATA__" if fmt == "scene" else "Physical floors"
    assert marker in r.text


def test_recording_analysis_series(dashboard: tuple[TestClient, Any]) -> None:
    client, ids = dashboard
    rec = ids["recording"]
    body = client.get(f"/api/viewer/recordings/{rec}/analysis", params={"points": 400}).json()
    assert len(body["lifts"]) == 4
    assert body["template"]["n_lifts"] == 4
    # The same template the stored analysis job produced.
    stored = client.get(f"/api/analyses/{ids['analysis']}/template").json()
    assert body["template"]["peak_velocity_angle_deg"] == pytest.approx(
        stored["peak_velocity_angle_deg"]
    )
    r = client.get("/api/viewer/recordings/999/analysis")
    assert r.status_code == 404
    r = client.get(f"/api/viewer/recordings/{rec}/analysis", params={"t0": 5, "t1": 2})
    assert r.status_code == 422 and r.json()["field"] == "t1"


def test_seed_is_idempotent(dashboard: tuple[TestClient, Any]) -> None:
    client, _ = dashboard
    assert seed_into(client.app.state.services) is None  # type: ignore[attr-defined]
    assert client.get("/api/recordings").json()["total"] == 1
    jobs = client.get("/api/jobs").json()["items"]
    kinds = sorted(j["kind"] for j in jobs if j["state"] == "succeeded")
    assert kinds == ["analysis", "plan", "simulation"]


def test_analysis_overlays_wait_for_the_analysis_job(dashboard: tuple[TestClient, Any]) -> None:
    """A new recording has no overlays (409, no job); its analysis job stores them."""
    import time

    from app.viewer.demo_seed import DEMO_MUSCLES, synthetic_curls_csv

    client, _ = dashboard
    data = synthetic_curls_csv(lifts=2, seed=11)
    r = client.post(
        "/api/recordings",
        files={"files": ("two_lifts.csv", data, "text/csv")},
        data={"muscle_map": json.dumps(DEMO_MUSCLES)},
    )
    assert r.status_code == 201, r.text
    rec = r.json()["id"]
    r = client.get(f"/api/viewer/recordings/{rec}/analysis")
    assert r.status_code == 409
    assert r.json()["job"] is None and "no analysis" in r.json()["detail"]

    job = client.post("/api/analyses", json={"recording_id": rec}).json()
    r = client.get(f"/api/viewer/recordings/{rec}/analysis")
    if r.status_code == 409:  # queued or running: the problem names the job to follow
        assert r.json()["job"]["id"] == job["id"]
    deadline = time.monotonic() + 60
    while client.get(f"/api/jobs/{job['id']}").json()["state"] not in TERMINAL:
        assert time.monotonic() < deadline, "the analysis job did not finish in 60 s"
        time.sleep(0.2)
    body = client.get(f"/api/viewer/recordings/{rec}/analysis", params={"points": 300}).json()
    assert body["analysis_id"] == job["id"] and len(body["lifts"]) == 2
    assert all(len(e["envelope"]["t"]) <= 300 for e in body["emg"])
    mine = client.get("/api/analyses", params={"recording_id": rec}).json()
    assert [a["id"] for a in mine["items"]] == [job["id"]]

    client.delete(f"/api/recordings/{rec}")
    assert client.get(f"/api/viewer/recordings/{rec}/analysis").status_code == 404


def test_a_failed_analysis_is_reported(dashboard: tuple[TestClient, Any]) -> None:
    """A force-only file uploads but cannot be analysed: the 409 carries the failed job."""
    import time

    client, _ = dashboard
    t = np.arange(4000) / 1000.0
    force = "\n".join(["time,Force_N"] + [f"{x:.3f},{np.sin(x):.4f}" for x in t]).encode()
    r = client.post("/api/recordings", files={"files": ("force.csv", force, "text/csv")})
    assert r.status_code == 201, r.text
    rec = r.json()["id"]
    job = client.post("/api/analyses", json={"recording_id": rec}).json()
    deadline = time.monotonic() + 60
    while client.get(f"/api/jobs/{job['id']}").json()["state"] not in TERMINAL:
        assert time.monotonic() < deadline
        time.sleep(0.2)
    r = client.get(f"/api/viewer/recordings/{rec}/analysis")
    assert r.status_code == 409
    problem = r.json()
    assert problem["job"]["id"] == job["id"] and problem["job"]["state"] == "failed"
    assert "nothing to analyse" in problem["job"]["error"]
    assert "failed" in problem["detail"] and "nothing to analyse" in problem["detail"]
    client.delete(f"/api/recordings/{rec}")


def test_seed_demo_on_its_own(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path / "data", max_workers=1)
    seed_demo(settings)
    seed_demo(settings)  # a second start adds nothing
    from app.db import crud
    from app.db.session import make_engine, make_sessionmaker

    engine = make_engine(settings.db_url)
    try:
        with make_sessionmaker(engine)() as session:
            _, recordings = crud.list_recordings(session=session)
            jobs, total = crud.list_jobs(session=session)
        assert recordings == 1 and total == 3
        assert all(j.state == "succeeded" for j in jobs)
    finally:
        engine.dispose()


def test_missing_frontend_is_a_clear_error(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path)
    with pytest.raises(FileNotFoundError, match=r"no index\.html in"):
        attach_dashboard(create_app(settings), settings, frontend_dir=tmp_path)
