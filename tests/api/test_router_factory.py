"""Issue 24 item 2: one router factory (``app.api.routes._results``) makes the submit, list,
get, relabel, arrays, trajectory and delete routes of every result kind; the routers keep only
their own routes. Checked on the app's routes and OpenAPI document, and by requests."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path
from typing import Any

import pytest
from fastapi import APIRouter, FastAPI
from fastapi.routing import APIRoute

from app.api.routes import _results, robot_logs
from app.api.routes._results import ResultRoutes, add_result_routes
from app.api.schemas import LabelPatch
from tests.utils.api import TestClient, assert_problem

ROUTES_DIR = Path(_results.__file__).parent

#: prefix -> (path parameter, list route name, get route name, routes beside list and get)
KINDS: dict[str, tuple[str, str, str, set[str]]] = {
    "/api/plans": ("plan_id", "list_plans", "get_plan", {"submit", "patch", "arrays", "traj"}),
    "/api/simulations": (
        "simulation_id",
        "list_simulations",
        "get_simulation",
        {"submit", "patch", "arrays", "traj"},
    ),
    "/api/profiles": ("profiles_id", "list_profiles", "get_profiles", {"submit"}),
    "/api/sweeps": ("sweep_id", "list_sweeps", "get_sweep", {"submit"}),
    "/api/cohorts": ("cohort_id", "list_cohorts", "get_cohort", {"submit", "delete"}),
    "/api/fronts": ("front_id", "get_fronts", "get_front", {"submit", "patch", "arrays", "delete"}),
    "/api/analyses": ("analysis_id", "list_analyses", "get_analysis", {"submit"}),
    "/api/poses": ("pose_id", "list_poses", "get_pose", set()),
    "/api/identifications": (
        "identification_id",
        "list_identifications",
        "get_identification",
        {"submit"},
    ),
}
#: The router modules of those kinds (no list/get signature of their own any more).
KIND_MODULES = (
    "plans",
    "simulations",
    "profiles",
    "sweeps",
    "cohorts",
    "fronts",
    "analyses",
    "poses",
    "robot_logs",
)

#: The routes' contract: SQLite only (tests/api/conftest.py).
pytestmark = pytest.mark.api_contract


@pytest.fixture(scope="module")
def app_routes() -> dict[tuple[str, str], APIRoute]:
    """Every route of the result kinds' routers, by method and path (prefix included)."""
    routers = [importlib.import_module(f"app.api.routes.{m}").router for m in KIND_MODULES]
    routers.append(robot_logs.identifications)
    return {
        (method, route.path): route
        for router in routers
        for route in router.routes
        if isinstance(route, APIRoute)
        for method in route.methods or ()
    }


@pytest.fixture(scope="module")
def openapi(shared_client: TestClient) -> dict[str, Any]:
    doc: dict[str, Any] = shared_client.get("/openapi.json").json()
    return doc


def _params(operation: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {p["name"]: p for p in operation.get("parameters", [])}


@pytest.mark.parametrize("prefix", sorted(KINDS))
def test_every_result_kind_has_the_factory_routes(
    prefix: str, app_routes: dict[tuple[str, str], APIRoute], openapi: dict[str, Any]
) -> None:
    id_name, list_name, get_name, extra = KINDS[prefix]
    one = f"{prefix}/{{{id_name}:int}}"
    optional = {
        "submit": ("POST", prefix),
        "patch": ("PATCH", one),
        "delete": ("DELETE", one),
        "arrays": ("GET", f"{one}/arrays"),
        "traj": ("GET", f"{one}/trajectory"),
    }
    expected: dict[tuple[str, str], str | None] = {("GET", prefix): list_name}
    expected["GET", one] = get_name
    expected.update({optional[op]: None for op in extra})
    for key, name in expected.items():
        route = app_routes[key]
        assert route.endpoint.__module__ == _results.__name__, key  # made by the factory
        if name is not None:
            assert route.name == name
    for op, key in optional.items():  # the optional routes exist only where asked for
        assert (key in app_routes) == (op in extra), (op, key)

    listed = openapi["paths"][prefix]["get"]
    params = _params(listed)
    assert params["limit"]["schema"] == {
        "type": "integer",
        "maximum": 500,
        "minimum": 1,
        "default": 50,
        "title": "Limit",
    }
    assert params["offset"]["schema"]["maximum"] == 10**9
    assert params["offset"]["schema"]["minimum"] == 0
    assert "state" in params
    assert listed["summary"] == list_name.replace("_", " ").title()
    fetched = openapi["paths"][f"{prefix}/{{{id_name}}}"]["get"]
    (path_param,) = [p for p in fetched["parameters"] if p["in"] == "path"]
    assert path_param["name"] == id_name
    assert path_param["schema"]["minimum"] == 1 and path_param["schema"]["maximum"] == 2**31 - 1


def test_list_filters_keep_their_constraints(openapi: dict[str, Any]) -> None:
    def param(prefix: str, name: str) -> dict[str, Any]:
        return _params(openapi["paths"][prefix]["get"])[name]

    for prefix in ("/api/plans", "/api/simulations", "/api/profiles"):
        assert param(prefix, "robot")["schema"]["anyOf"][0]["maxLength"] == 100
    assert "pattern" in param("/api/identifications", "robot")["schema"]["anyOf"][0]
    assert param("/api/analyses", "recording_id")["description"] == "only this recording's analyses"
    assert param("/api/poses", "recording_id")["description"] == "only this recording's"
    for prefix in ("/api/sweeps", "/api/cohorts", "/api/fronts"):
        assert set(_params(openapi["paths"][prefix]["get"])) == {"limit", "offset", "state"}
    traj = _params(openapi["paths"]["/api/plans/{plan_id}/trajectory"]["get"])
    assert list(traj)[:4] == ["plan_id", "format", "rate", "method"]
    point = _params(openapi["paths"]["/api/fronts/{front_id}/points/{pid}/export"]["get"])
    assert set(traj) - set(point) == {"plan_id", "method"}  # the same export options


def test_no_result_router_defines_its_own_list_or_get() -> None:
    for module in KIND_MODULES:
        tree = ast.parse((ROUTES_DIR / f"{module}.py").read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef):
                names = {a.arg for a in node.args.args + node.args.kwonlyargs}
                assert "limit" not in names, f"{module}.{node.name} lists by itself"
                for deco in node.decorator_list:
                    if not (isinstance(deco, ast.Call) and isinstance(deco.func, ast.Attribute)):
                        continue
                    owner = ast.unparse(deco.func.value)
                    if module == "robot_logs" and owner == "router":
                        continue  # the logs themselves are not a job's result
                    if deco.args and isinstance(deco.args[0], ast.Constant):
                        path = str(deco.args[0].value)
                        assert path != "" and not path.endswith("_id:int}"), (
                            f"{module}.{node.name} makes a shared route"
                        )


def test_the_factory_names_a_new_kind_from_its_noun() -> None:
    router = APIRouter(prefix="/api/widgets")
    add_result_routes(router, ResultRoutes("widget", label=True, delete=True))
    app = FastAPI()
    app.include_router(router)
    paths = app.openapi()["paths"]
    assert set(paths) == {"/api/widgets", "/api/widgets/{widget_id}"}
    one = paths["/api/widgets/{widget_id}"]
    assert {m: op["summary"] for m, op in one.items()} == {
        "get": "Get Widget",
        "patch": "Relabel Widget",
        "delete": "Delete Widget",
    }
    assert one["delete"]["description"].startswith("Delete a widget (its job and result)")
    body = one["patch"]["requestBody"]["content"]["application/json"]["schema"]
    assert body["$ref"].endswith(f"/{LabelPatch.__name__}")
    assert "post" not in paths["/api/widgets"]  # no submit without a hook
    assert ResultRoutes("profiles", plural="profiles").name("list") == "list_profiles"


@pytest.mark.parametrize("prefix", sorted(KINDS))
def test_factory_routes_answer(shared_client: TestClient, prefix: str) -> None:
    page = shared_client.get(prefix, params={"limit": 3, "offset": 0})
    assert page.status_code == 200, page.text
    assert {"items", "total", "limit", "offset"} <= set(page.json())
    assert page.json()["limit"] == 3
    assert_problem(shared_client.get(prefix, params={"limit": 0}), 422)
    assert_problem(shared_client.get(prefix, params={"state": "sleeping"}), 422)
    missing = shared_client.get(f"{prefix}/987654")
    assert_problem(missing, 404)
    assert missing.json()["detail"].endswith("987654 does not exist")


def test_relabel_and_delete_of_a_missing_result_are_404(shared_client: TestClient) -> None:
    for prefix in ("/api/plans", "/api/simulations", "/api/fronts"):
        assert_problem(shared_client.patch(f"{prefix}/987654", json={"label": "x"}), 404)
    for prefix in ("/api/cohorts", "/api/fronts"):
        gone = shared_client.delete(f"{prefix}/987654")
        assert_problem(gone, 404)
        assert prefix.removeprefix("/api/").rstrip("s") in gone.json()["detail"]
    assert shared_client.delete("/api/plans/987654").status_code == 405  # plans keep theirs
