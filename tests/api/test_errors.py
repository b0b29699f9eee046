"""Only bad input is a 4xx: a ``BioPlanError`` (by type: 404, 409, 422) and request validation.
Anything else, a ``ValueError`` included, is a bug: a logged 500 that shows no internals."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from app.errors import BioPlanError
from app.recordings.types import RecordingError
from app.services import AnalysisPending, ConflictError, NotFoundError, ServiceError
from tests.utils.api import TestClient, assert_problem, make_client

SECRET = "token=hunter2 at /srv/internal/path.py line 42"


def _raiser(exc: BaseException):  # type: ignore[no-untyped-def]
    def route() -> None:
        raise exc

    return route


@pytest.fixture
def client(tmp_path: Path) -> TestClient:
    with make_client(tmp_path) as c:
        app = c.app
        cases: dict[str, BaseException] = {
            "value-error": ValueError(SECRET),
            "key-error": KeyError(SECRET),
            "bad-input": BioPlanError("duration must be > 0 s, got -1"),
            "unreadable": RecordingError("a.csv: line 3: expected 4 columns, got 2", file="a.csv"),
            "missing": NotFoundError("plan 9 does not exist"),
            "conflict": ConflictError("job 3 already ended (succeeded)"),
            "field": ServiceError("unknown robot 'x'", field="robot"),
            "pending": AnalysisPending("recording 1 has no analysis yet"),
        }
        routes = app.router.routes  # type: ignore[attr-defined]
        for name, exc in cases.items():
            app.add_api_route(f"/test/{name}", _raiser(exc), methods=["GET"])  # type: ignore[attr-defined]
            routes.insert(0, routes.pop())  # before the pages mounted at /
        yield c


@pytest.mark.parametrize("name", ["value-error", "key-error"])
def test_a_bug_is_a_logged_500_that_shows_nothing_inside(
    client: TestClient, name: str, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.ERROR, logger="app.api.middleware"):
        r = client.get(f"/test/{name}")
    body = assert_problem(r, 500)
    assert "hunter2" not in r.text and "internal" not in r.text
    ref = body["detail"].rsplit("ref ", 1)[1].rstrip(")")
    logged = [rec for rec in caplog.records if ref in rec.getMessage()]
    assert logged and logged[0].exc_info is not None  # the traceback is in the log
    assert SECRET in "".join(logging.Formatter().formatException(logged[0].exc_info))


def test_bad_input_is_a_4xx_by_type(client: TestClient) -> None:
    assert_problem(client.get("/test/bad-input"), 422, title="Invalid input")
    assert_problem(client.get("/test/unreadable"), 422, file="a.csv", title="Unreadable file")
    assert_problem(client.get("/test/missing"), 404, detail="plan 9 does not exist")
    assert_problem(client.get("/test/conflict"), 409)
    assert_problem(client.get("/test/field"), 422, field="robot")
    pending = assert_problem(client.get("/test/pending"), 409, title="No analysis yet")
    assert "job" in pending and pending["job"] is None  # the page can start one


def test_validation_is_422_naming_the_field(client: TestClient) -> None:
    r = client.post("/api/plans", json={"robot": "curtain_wall_6dof", "duration": -1})
    assert_problem(r, 422, field="duration")


def test_a_body_that_cannot_be_parsed_is_a_documented_400(client: TestClient) -> None:
    """Found by the schema fuzz with every check: bytes that are not UTF-8 under a JSON
    Content-Type got an undocumented 400 saying "There was an error parsing the body"."""
    r = client.post(
        "/api/plans", content=b"\x80\x81 not json", headers={"Content-Type": "application/json"}
    )
    problem = assert_problem(r, 400)
    assert "expected UTF-8 JSON" in problem["detail"]
    documented = client.get("/openapi.json").json()["paths"]["/api/plans"]["post"]["responses"]
    assert "400" in documented
    # Without a token, the document says writes need none (an empty security alternative).
    assert {} in client.get("/openapi.json").json()["paths"]["/api/plans"]["post"]["security"]


def test_booleans_and_bare_numbers_are_not_read_as_numbers_or_dates(client: TestClient) -> None:
    """Found by schemathesis with every check: ``true`` was accepted as a duration of 1 s and
    ``created_before=0.5`` as a Unix time."""
    bad = client.post("/api/plans", json={"robot": "human_arm_2dof", "duration": True})
    assert "boolean" in assert_problem(bad, 422, field="duration")["detail"]
    bad = client.post("/api/sweeps", json={"durations": [1.0, True]})
    assert_problem(bad, 422, field="durations")
    bad = client.post("/api/analyses", json={"recording_id": 1, "body_mass": False})
    assert_problem(bad, 422, field="body_mass")
    # ... nor a number as a boolean (schemathesis: ``no_check: 1`` was read as true).
    for number in (1, 0, 1.0):
        bad = client.post("/api/sweeps", json={"no_check": number})
        assert "expected true or false" in assert_problem(bad, 422, field="no_check")["detail"]
    bad = client.post("/api/analyses", json={"recording_id": 1, "together": 1})
    assert_problem(bad, 422, field="together")
    date = client.get("/api/recordings", params={"created_before": "0.5"})
    assert "ISO 8601" in assert_problem(date, 422, field="created_before")["detail"]
    assert client.get("/api/recordings", params={"created_before": "2026-11-26"}).status_code == 200
    # A 0 s duration was allowed by the schema and refused by the route: the schema says so now.
    assert_problem(client.post("/api/sweeps", json={"durations": [0.0]}), 422, field="durations.0")
    grid = client.get("/openapi.json").json()["components"]["schemas"]["SweepRequest"]
    assert grid["properties"]["durations"]["items"]["exclusiveMinimum"] == 0
