"""Every id the API takes is bounded: a 2**63 id is a 422 naming the field, never a 500.

``POST /api/analyses {"recording_id": 9223372036854775808}`` answered 500 (an OverflowError in
the database driver). The test walks the OpenAPI document, so a route added later with an
unbounded id fails here too.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from tests.utils.api import make_client

HUGE = 2**63  # one past SQLite's and PostgreSQL's BIGINT


def _resolve(spec: dict[str, Any], schema: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in schema:
        name = schema["$ref"].rsplit("/", 1)[-1]
        schema = spec["components"]["schemas"][name]
    return schema


def _is_int(schema: dict[str, Any]) -> bool:
    options = schema.get("anyOf", [schema])
    return any(option.get("type") == "integer" for option in options)


def _valid(spec: dict[str, Any], schema: dict[str, Any]) -> Any:
    """A value of this path parameter that passes validation."""
    schema = _resolve(spec, schema)
    if "enum" in schema:
        return schema["enum"][0]
    return 1 if _is_int(schema) else "x"


def _id_path_cases(spec: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(method, url with one id param huge and the others 1, param name)."""
    cases = []
    for path, ops in spec["paths"].items():
        for method, op in ops.items():
            params = [p for p in op.get("parameters", []) if p["in"] == "path"]
            int_params = [p["name"] for p in params if _is_int(p.get("schema", {}))]
            for name in int_params:
                url = path
                for other in params:
                    value = HUGE if other["name"] == name else _valid(spec, other["schema"])
                    url = url.replace("{" + other["name"] + "}", str(value))
                cases.append((method.upper(), url, name))
    return cases


def _id_body_cases(spec: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(method, path, field) for every integer ``*_id`` field of a JSON request body."""
    cases = []
    for path, ops in spec["paths"].items():
        if "{" in path:
            continue
        for method, op in ops.items():
            content = op.get("requestBody", {}).get("content", {})
            if "application/json" not in content:
                continue
            body = _resolve(spec, content["application/json"]["schema"])
            for field, schema in body.get("properties", {}).items():
                schema = _resolve(spec, schema)
                if re.fullmatch(r"(\w+_)?id", field) and _is_int(schema):
                    cases.append((method.upper(), path, field))
                elif re.fullmatch(r"\w+_ids", field) and _is_int(schema.get("items", {})):
                    cases.append((method.upper(), path, field))  # a list of ids
    return cases


def _id_query_cases(spec: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(method, path, param) for every integer ``*_id`` query parameter of a path without
    path parameters."""
    cases = []
    for path, ops in spec["paths"].items():
        for method, op in ops.items():
            for p in op.get("parameters", []):
                is_id = re.fullmatch(r"(\w+_)?id", p["name"]) and _is_int(p.get("schema", {}))
                if p["in"] == "query" and "{" not in path and is_id:
                    cases.append((method.upper(), path, p["name"]))
    return cases


def test_a_huge_id_anywhere_is_a_422_naming_it(tmp_path: Path) -> None:
    with make_client(tmp_path) as client:
        spec = client.get("/openapi.json").json()
        path_cases, body_cases = _id_path_cases(spec), _id_body_cases(spec)
        # The routes this was found on are among the cases (the walk itself works).
        assert ("POST", "/api/analyses", "recording_id") in body_cases
        assert any(url.startswith("/api/plans/") for _, url, _ in path_cases)
        assert len(path_cases) >= 20, path_cases
        for method, url, name in path_cases:
            r = client.request(method, url, json={})
            assert r.status_code == 422, (method, url, r.status_code, r.text)
            fields = {e["field"] for e in r.json()["errors"]}
            assert any(name in f for f in fields), (method, url, fields)
        query_cases = _id_query_cases(spec)
        assert ("GET", "/api/analyses", "recording_id") in query_cases
        for method, path, name in query_cases:
            r = client.request(method, path, params={name: HUGE})
            assert r.status_code == 422, (method, path, r.status_code, r.text)
        # POST /api/identifications {"log_ids": [-6e30]} answered 500 (found by schemathesis).
        assert ("POST", "/api/identifications", "log_ids") in body_cases
        for method, path, field in body_cases:
            huge = [HUGE] if field.endswith("_ids") else HUGE
            r = client.request(method, path, json={field: huge})
            assert r.status_code == 422, (method, path, r.status_code, r.text)
            fields = {e["field"] for e in r.json()["errors"]}
            assert any(field in f for f in fields), (method, path, field, fields)


def test_every_export_states_its_sample_cap(tmp_path: Path) -> None:
    """``samples`` of every trajectory export says this server's BIOPLAN_MAX_EXPORT_SAMPLES as
    its maximum, as its description promises (a front point's export did not)."""
    with make_client(tmp_path, max_export_samples=1234) as client:
        spec = client.get("/openapi.json").json()
    stated = {
        path: option.get("maximum")
        for path, ops in spec["paths"].items()
        for op in ops.values()
        for p in op.get("parameters", [])
        if p["in"] == "query" and p["name"] == "samples"
        for option in p["schema"].get("anyOf", [p["schema"]])
        if option.get("type") == "integer"
    }
    assert "/api/fronts/{front_id}/points/{pid}/export" in stated
    assert len(stated) >= 3 and set(stated.values()) == {1234}, stated


def test_every_points_parameter_is_capped(tmp_path: Path) -> None:
    """Issue 14 item 11: ``signals?points=100000`` from 16 clients pushed other requests' p99
    to 10.9 s. Every read that decimates takes at most MAX_POINTS samples per series: one more
    is a 422 naming the limit, before any data is read."""
    from app.api.routes._common import MAX_POINTS

    with make_client(tmp_path) as client:
        spec = client.get("/openapi.json").json()
        capped = []
        for path, ops in spec["paths"].items():
            for method, op in ops.items():
                url = path
                for p in op.get("parameters", []):
                    if p["in"] == "path":
                        url = url.replace("{" + p["name"] + "}", str(_valid(spec, p["schema"])))
                for p in op.get("parameters", []):
                    if p["in"] == "query" and p["name"] == "points":
                        assert p["schema"]["maximum"] == MAX_POINTS, (path, p["schema"])
                        capped.append((method.upper(), url))
        assert len(capped) >= 5, capped
        for method, url in capped:
            r = client.request(method, url, params={"points": MAX_POINTS + 1})
            assert r.status_code == 422, (url, r.text)
            assert str(MAX_POINTS) in r.text and "points" in r.json()["field"]
