"""Issue 24 item 2: one record per job kind. Every kind has every part (name, URL segment, task
function, result table, payload builder, result store), the API's enums and routes follow the
kernel's list, and the records behave as the service's former per-kind branches did."""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any, get_args

import pytest

from app.api.schemas import JobKind
from app.config import Settings
from app.db.models import JOB_KINDS as DB_KINDS
from app.db.models import RESULT_MODELS
from app.jobs.tasks import TASKS, run_task
from app.kinds import JOB_KINDS, KIND_NAMES, KIND_PATHS, result_url
from app.main import create_app
from app.progress import no_progress
from app.services.jobs import KIND_PATHS as SERVICE_PATHS
from app.services.kinds import KINDS, KindContext


def test_every_kind_has_every_part() -> None:
    assert KIND_NAMES == tuple(JOB_KINDS) == tuple(KINDS) == DB_KINDS
    assert set(TASKS) == set(RESULT_MODELS) == set(KIND_NAMES)
    for name, kind in KINDS.items():
        assert kind.name == name == kind.info.name
        assert kind.path == KIND_PATHS[name] and kind.path
        assert kind.task is TASKS[name]
        assert kind.result_model is RESULT_MODELS[name]
        assert callable(kind.payload) and callable(kind.store)
        assert list(inspect.signature(kind.task).parameters) == ["payload", "progress"]
    assert SERVICE_PATHS is KIND_PATHS
    assert len(set(KIND_PATHS.values())) == len(KIND_PATHS)  # one URL segment per kind
    # the tables differ: a result is never stored where another kind's is read
    assert len({m.__tablename__ for m in RESULT_MODELS.values()}) == len(RESULT_MODELS)


def test_the_api_enum_is_the_kernels_list() -> None:
    assert get_args(JobKind) == KIND_NAMES


@pytest.fixture(scope="module")
def app_doc(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, dict[str, Any]]:
    app = create_app(Settings(data_dir=tmp_path_factory.mktemp("kinds")))
    return app, app.openapi()


def test_every_kinds_result_url_is_a_route(app_doc: tuple[Any, dict[str, Any]]) -> None:
    """The ``result_url`` of a job of each kind names a GET route of the API."""
    _, doc = app_doc
    gets = {
        path.rsplit("/", 1)[0]
        for path, ops in doc["paths"].items()
        if "get" in ops and path.endswith("_id}")
    }
    for name in KIND_NAMES:
        url = result_url(name, 7)
        assert url == f"/api/{KIND_PATHS[name]}/7"
        assert url.rsplit("/", 1)[0] in gets, (name, url)


def test_openapi_lists_the_kinds(app_doc: tuple[Any, dict[str, Any]]) -> None:
    _, doc = app_doc
    params = doc["paths"]["/api/jobs"]["get"]["parameters"]
    kind = next(p for p in params if p["name"] == "kind")["schema"]
    enums = [s["enum"] for s in kind.get("anyOf", [kind]) if "enum" in s]
    assert enums == [list(KIND_NAMES)]
    job = doc["components"]["schemas"]["Job"]["properties"]["kind"]
    assert job["enum"] == list(KIND_NAMES)


def test_an_unknown_kind_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"unknown job kind 'nope' \(expected one of \["):
        run_task("nope", {}, no_progress)


class _Robots:
    """A catalogue that gives every robot the spec of a built-in one."""

    def spec(self, session: Any, name: str) -> dict[str, Any]:
        return {"name": name, "from": "catalog"}


def _context(tmp_path: Path) -> KindContext:
    return KindContext(blobs=None, robots=_Robots(), max_video_seconds=5.0)  # type: ignore[arg-type]


@pytest.mark.parametrize("name", [k for k, v in JOB_KINDS.items() if v.robot])
def test_a_robot_kinds_payload_carries_the_robots_spec(name: str, tmp_path: Path) -> None:
    """Plans, simulations, sweeps, profiles and fronts: the request with the robot's spec;
    only the kinds that take a template look the analysis up."""
    params = {"robot": "my_arm", "duration": 1.0}
    payload = KINDS[name].payload(None, _context(tmp_path), params)  # type: ignore[arg-type]
    assert payload == {"robot": {"name": "my_arm", "from": "catalog"}, "duration": 1.0}
    assert params == {"robot": "my_arm", "duration": 1.0}  # the stored request is unchanged
    with_template = {**params, "template_analysis_id": None}
    payload = KINDS[name].payload(None, _context(tmp_path), with_template)  # type: ignore[arg-type]
    assert "template_analysis_id" not in payload and "template" not in payload
    if not JOB_KINDS[name].template:
        # a kind without a template never reads the analysis, whatever the request says
        payload = KINDS[name].payload(  # type: ignore[arg-type]
            None, _context(tmp_path), {**params, "template_analysis_id": 3}
        )
        assert "template" not in payload
