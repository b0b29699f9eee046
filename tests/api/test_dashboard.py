"""The dashboard served by the real app: pages, assets, shared names, the viewer's routes, and
the demo seed."""

from __future__ import annotations

import colorsys
import json
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, unquote, urlsplit

import numpy as np
import pytest

from app import names
from app.api.routes.dashboard import plotly_js_path
from app.config import Settings
from app.main import create_app
from app.names import TERMINAL_JOB_STATES as TERMINAL
from app.services import DEMO_MUSCLES, seed_demo, seed_into, synthetic_curls_csv
from tests.utils.api import TestClient, make_client
from tests.utils.server import free_port


@pytest.fixture(scope="module")
def dashboard(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, Any]]:
    """The app with its 3-D viewer and the demo seeded (analysis, plan, simulation)."""
    tmp = tmp_path_factory.mktemp("dash")
    with make_client(tmp, viewer=True, viewer_port=free_port()) as client:
        ids = seed_into(client.app.state.services, timeout=300)  # type: ignore[attr-defined]
        yield client, ids


def test_pages_and_assets_are_served(dashboard: tuple[TestClient, Any]) -> None:
    client, _ = dashboard
    index = client.get("/")
    assert index.status_code == 200 and index.headers["content-type"].startswith("text/html")
    assert '<script type="module" src="/js/app.js">' in index.text
    for path, kind in (("/style.css", "text/css"), ("/js/compare.js", "javascript")):
        r = client.get(path)
        assert r.status_code == 200 and kind in r.headers["content-type"], path
    plotly = client.get("/api/viewer/assets/plotly.min.js")  # httpx accepts gzip
    assert plotly.status_code == 200
    assert plotly.content == plotly_js_path().read_bytes()
    # The largest asset goes compressed (issue 15: a first useful paint under 1 s).
    assert plotly.headers["content-encoding"] == "gzip"
    assert plotly.num_bytes_downloaded < 0.4 * len(plotly.content)
    plain = client.get("/api/viewer/assets/plotly.min.js", headers={"Accept-Encoding": "identity"})
    assert "content-encoding" not in plain.headers and plain.content == plotly.content
    again = client.get(
        "/api/viewer/assets/plotly.min.js", headers={"If-None-Match": plotly.headers["etag"]}
    )
    assert again.status_code == 304
    # An unknown API path is still an API problem, not a page.
    missing = client.get("/api/nothing-here")
    assert missing.status_code == 404
    assert missing.headers["content-type"].startswith("application/problem+json")


def test_shared_names_are_served_as_defined(dashboard: tuple[TestClient, Any]) -> None:
    """``GET /api/meta`` is ``app.names`` as JSON (the page reads units, colours, defaults)."""
    client, _ = dashboard
    meta = client.get("/api/meta").json()
    assert meta == json.loads(json.dumps(names.as_json()))
    assert [m["name"] for m in meta["metrics"]] == list(names.OBJECTIVES)
    assert {p["name"]: p["colour"] for p in meta["phases"]} == {
        p.name: p.colour for p in names.PHASES
    }
    assert meta["pso_defaults"]["particles"] == names.PSO_DEFAULTS.particles


def _hue_saturation(colour: str) -> tuple[float, float]:
    r, g, b = (int(colour[i : i + 2], 16) / 255 for i in (1, 3, 5))
    hue, saturation, _ = colorsys.rgb_to_hsv(r, g, b)
    return 360.0 * hue, saturation


def test_muscle_colours_never_read_as_phases() -> None:
    """Issue 15: onset bars reused the phase colours (forearm green as phase A, triceps blue as
    phase C). Every muscle's colour is nearly grey or 30 degrees of hue from every phase's."""
    for muscle, colour in names.MUSCLE_COLOURS.items():
        hue, saturation = _hue_saturation(colour)
        for phase in names.PHASES:
            phase_hue, _ = _hue_saturation(phase.colour)
            apart = min(abs(hue - phase_hue), 360.0 - abs(hue - phase_hue))
            assert saturation < 0.25 or apart >= 30.0, (muscle, phase.name, apart)
    assert len(set(names.MUSCLE_COLOURS.values())) == len(names.MUSCLE_COLOURS)


def test_viewer_address_is_the_real_one(dashboard: tuple[TestClient, Any]) -> None:
    client, _ = dashboard
    info = client.get("/api/viewer").json()
    viewer = client.app.state.services.viewer  # type: ignore[attr-defined]
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
    # The iframe's address carries a capability for this comparison (app.viewer.access).
    websocket = unquote(body["viewer"]["url"].split("websocket=")[1].split("&hideViserLogo")[0])
    assert f"/bioplan/simulation/{sim}?token=" in websocket
    assert len(parse_qs(urlsplit(websocket).query)["token"][0]) >= 32
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
    r = client.get(f"/api/viewer/recordings/{rec}/analysis", params={"t0": 5, "t1": 5})
    assert r.status_code == 200 and r.json()["window"] == [5, 5]  # one instant: no 422


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
    deadline = time.monotonic() + 180
    while client.get(f"/api/jobs/{job['id']}").json()["state"] not in TERMINAL:
        assert time.monotonic() < deadline, "the analysis job did not finish in 180 s"
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
    deadline = time.monotonic() + 180
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


def test_seed_demo_adds_nothing_to_a_database_with_recordings(tmp_path: Path) -> None:
    """``seed_demo`` starts and stops the services itself; with a recording there it adds
    nothing (the full seed runs in the module's fixture)."""
    with make_client(tmp_path) as client:
        settings = client.app.state.services.settings  # type: ignore[attr-defined]
        r = client.post(
            "/api/recordings", files={"files": ("c.csv", synthetic_curls_csv(lifts=1), "text/csv")}
        )
        assert r.status_code == 201, r.text
    said: list[str] = []
    assert seed_demo(settings, say=said.append) is None
    assert said == []
    with make_client(tmp_path) as client:
        assert client.get("/api/jobs").json()["total"] == 0


def test_pages_come_from_the_settings_folder_or_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"no index\.html in"):
        create_app(Settings(data_dir=tmp_path, frontend_dir=tmp_path, viewer=False))
    (tmp_path / "pages").mkdir()
    (tmp_path / "pages" / "index.html").write_text("<title>mine</title>")
    with make_client(tmp_path, frontend_dir=tmp_path / "pages") as client:
        assert client.get("/").text == "<title>mine</title>"
