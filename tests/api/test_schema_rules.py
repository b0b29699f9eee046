"""The OpenAPI document states the rules a request must follow, and the API keeps to them.

Found by schemathesis's ``positive_data_acceptance`` check (issue 14, item 15): requests the
schema allowed were refused with 422 for rules it did not state (repeated methods, a robot
upload without a model, ``methods=a,b`` naming no method, a job over this server's caps, a
window of one instant). Each rule is now in the schema, or the request is accepted, or a name
in the body that names nothing is a 404 naming the field. The fuzz test
(``test_schemathesis.py``) lists the few rules no schema can state.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.utils.api import TestClient, assert_problem, make_client
from tests.utils.jobs import RecordingRunner

CSV = b"time,emg\n" + b"".join(f"{i / 1000},{(i % 7) / 1e4}\n".encode() for i in range(500))


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """A server whose jobs are only recorded (none runs), with caps below the defaults."""
    tmp = tmp_path_factory.mktemp("schema_rules")
    with make_client(tmp, runner=RecordingRunner(), max_particles=50, max_samples=300) as c:
        yield c


@pytest.fixture(scope="module")
def openapi(client: TestClient) -> dict[str, Any]:
    out: dict[str, Any] = client.get("/openapi.json").json()
    return out


def _component(openapi: dict[str, Any], path: str, media: str) -> dict[str, Any]:
    ref = openapi["paths"][path]["post"]["requestBody"]["content"][media]["schema"]["$ref"]
    out: dict[str, Any] = openapi["components"]["schemas"][ref.rpartition("/")[2]]
    return out


def test_repeats_are_stated_and_refused(client: TestClient, openapi: dict[str, Any]) -> None:
    schemas = openapi["components"]["schemas"]
    stated = {
        (name, field)
        for name, body in schemas.items()
        for field, prop in body.get("properties", {}).items()
        if prop.get("uniqueItems")
    }
    assert {
        ("PlanRequest", "methods"),
        ("SimulationRequest", "methods"),
        ("ProfilesRequest", "methods"),
        ("SweepRequest", "methods"),
        ("SweepRequest", "objectives"),
        ("SweepRequest", "durations"),
        ("SweepRequest", "payloads"),
    } <= stated
    twice = ["quintic", "paper", "paper"]
    for url in ("/api/plans", "/api/simulations", "/api/profiles", "/api/sweeps"):
        body = {"robot": "human_arm_2dof", "methods": twice}
        detail = assert_problem(client.post(url, json=body), 422, field="methods")["detail"]
        assert "must not repeat (repeated: ['paper'])" in detail, (url, detail)
    r = client.post("/api/sweeps", json={"objectives": ["abs_work", "abs_work"]})
    assert_problem(r, 422, field="objectives")


def test_the_schema_states_this_servers_job_caps(
    client: TestClient, openapi: dict[str, Any]
) -> None:
    """``BIOPLAN_MAX_PARTICLES=50`` here: the schema says 50, and 51 is refused naming it."""
    plan = openapi["components"]["schemas"]["PlanRequest"]["properties"]
    assert plan["particles"]["maximum"] == 50
    assert plan["n_samples"]["maximum"] == 300
    assert plan["iterations"]["maximum"] == 2000  # the default cap, below the type's 10000
    sweep = openapi["components"]["schemas"]["SweepRequest"]["properties"]
    assert sweep["workers"]["anyOf"][0]["maximum"] == 2  # make_client's max_workers
    body = {"robot": "human_arm_2dof", "particles": 50, "n_samples": 300}
    assert client.post("/api/plans", json=body).status_code == 202
    r = client.post("/api/plans", json={**body, "particles": 51})
    assert "BIOPLAN_MAX_PARTICLES" in assert_problem(r, 422, field="particles")["detail"]
    with make_client(client.app.state.services.settings.data_dir.parent / "other") as other:
        default = other.get("/openapi.json").json()["components"]["schemas"]["PlanRequest"]
        assert default["properties"]["particles"]["maximum"] == 400  # the server's own caps


def test_a_cap_below_a_default_lowers_the_default(tmp_path: Path) -> None:
    """Found by schemathesis over HTTP on a server with ``BIOPLAN_MAX_PARTICLES=20``: ``POST
    /api/plans {}`` was refused ("particles 40 exceeds the limit 20"), though it asked for
    nothing. A field the request leaves out gets the cap; one it gives above it is refused."""
    with make_client(tmp_path, runner=RecordingRunner(), max_particles=20) as capped:
        plan = capped.get("/openapi.json").json()["components"]["schemas"]["PlanRequest"]
        assert plan["properties"]["particles"]["default"] == 20
        for url in ("/api/plans", "/api/simulations", "/api/profiles"):
            r = capped.post(url, json={"robot": "human_arm_2dof"})
            assert r.status_code == 202, (url, r.text)
            assert r.json()["params"]["particles"] == 20  # what the job runs with
            r = capped.post(url, json={"robot": "human_arm_2dof", "particles": 21})
            assert_problem(r, 422, field="particles")
        r = capped.post("/api/plans", json={"robot": "human_arm_2dof", "particles": 8})
        assert r.json()["params"]["particles"] == 8  # below the cap: as asked


def test_names_in_the_body_that_name_nothing_are_404(client: TestClient) -> None:
    r = client.post("/api/analyses", json={"recording_id": 4242})
    assert "recording 4242 does not exist" in assert_problem(r, 404, field="recording_id")["detail"]
    for url in ("/api/plans", "/api/simulations", "/api/profiles", "/api/sweeps"):
        detail = assert_problem(client.post(url, json={"robot": "r2d2"}), 404, field="robot")
        assert "unknown robot 'r2d2'" in detail["detail"] and "human_arm_2dof" in detail["detail"]


def test_a_template_still_being_computed_is_a_conflict(client: TestClient) -> None:
    """An analysis that exists but has not finished: 409 naming the field, not 404 or 422."""
    rid = client.post("/api/recordings", files=[("files", ("a.csv", CSV))]).json()["id"]
    job = client.post("/api/analyses", json={"recording_id": rid}).json()["id"]
    r = client.post("/api/plans", json={"robot": "human_arm_2dof", "template_analysis_id": job})
    assert "has no template yet" in assert_problem(r, 409, field="template_analysis_id")["detail"]


def test_a_robot_upload_needs_a_model_and_forms_have_no_null(
    client: TestClient, openapi: dict[str, Any]
) -> None:
    body = _component(openapi, "/api/robots", "multipart/form-data")
    # A form field is sent or left out: the text "null" is no file and no number.
    for name in ("urdf", "mjcf", "package", "sidecar", "payload", "shoulder_joint"):
        assert "anyOf" not in body["properties"][name], name
    needs = openapi["paths"]["/api/robots"]["post"]["requestBody"]["content"][
        "multipart/form-data"
    ]["schema"]["anyOf"]
    assert needs == [{"required": ["urdf"]}, {"required": ["mjcf"]}, {"required": ["package"]}]
    r = client.post("/api/robots", data={"name": "bare"}, files={"sidecar": ("s.yaml", b"a: 1")})
    assert "give a urdf, an mjcf or a package" in assert_problem(r, 422, field="urdf")["detail"]
    upload = _component(openapi, "/api/recordings", "multipart/form-data")
    assert upload["properties"]["files"]["minItems"] == 1
    assert "anyOf" not in upload["properties"]["load_kg"]


def test_reader_and_image_size_are_stated(client: TestClient, openapi: dict[str, Any]) -> None:
    upload = _component(openapi, "/api/recordings", "multipart/form-data")["properties"]
    assert "c3d" in upload["format"]["enum"] and "mediapipe_csv" in upload["format"]["enum"]
    assert upload["image_size"]["pattern"]
    files = [("files", ("a.csv", CSV))]
    r = client.post("/api/recordings", files=files, data={"format": "xlsx"})
    assert_problem(r, 422, field="format")
    for bad in ("640x", "0x480", "640*480", "100000x1"):
        r = client.post("/api/recordings", files=files, data={"image_size": bad})
        assert "WIDTHxHEIGHT" in assert_problem(r, 422, field="image_size")["detail"]
    for good, stored in (("640x480", [640, 480]), (" 1920 X 1080 ", [1920, 1080]), ("", None)):
        r = client.post("/api/recordings", files=files, data={"image_size": good})
        assert r.status_code == 201, (good, r.text)
        assert r.json()["options"].get("image_size") == stored
    patch = openapi["components"]["schemas"]["RecordingPatch"]["properties"]
    assert "csv" in patch["format"]["anyOf"][0]["enum"]


def test_analysis_ranges_are_stated(client: TestClient, openapi: dict[str, Any]) -> None:
    props = openapi["components"]["schemas"]["AnalysisRequest"]["properties"]
    assert props["offset"]["anyOf"][0] == {"type": "number", "minimum": -3600, "maximum": 3600}
    bounds = props["phase_bounds_deg"]["prefixItems"]
    assert all(b["exclusiveMinimum"] == 0 and b["exclusiveMaximum"] == 180 for b in bounds)
    rid = client.post("/api/recordings", files=[("files", ("b.csv", CSV))]).json()["id"]
    r = client.post("/api/analyses", json={"recording_id": rid, "offset": 3601})
    assert_problem(r, 422, field="offset")
    r = client.post("/api/analyses", json={"recording_id": rid, "phase_bounds_deg": [90, 30]})
    assert "0 < A/B < B/C < 180" in assert_problem(r, 422, field="phase_bounds_deg")["detail"]
