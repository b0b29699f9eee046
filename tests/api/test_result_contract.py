"""The typed result contract: every result kind is served as its pydantic model (named in the
OpenAPI document), real results of small jobs validate against them unchanged, the Compare
page's per-joint power and energy come from the API and equal NumPy's trapezoid on the stored
torques and velocities, and ``/api/meta`` carries the floors' formulas and the front's axes."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest
from pydantic import BaseModel

from app.api import result_models as rm
from tests.utils.api import TestClient, wait_job

#: The routes' contract: SQLite only (tests/api/conftest.py).
pytestmark = pytest.mark.api_contract

#: One small real job per kind (as the kinds' own API tests submit them).
JOBS: dict[str, tuple[str, dict[str, Any], type[BaseModel]]] = {
    "plan": (
        "plans",
        {"robot": "human_arm_2dof", "duration": 1.0, "particles": 8, "iterations": 5,
         "methods": ["quintic", "paper"], "seed": 1},
        rm.PlanOut,
    ),
    "simulation": (
        "simulations",
        {"robot": "human_arm_2dof", "duration": 1.0, "seed": 2, "particles": 8, "iterations": 5,
         "payload": 6.0, "methods": ["quintic", "paper"]},
        rm.SimulationOut,
    ),
    "profiles": (
        "profiles",
        {"robot": "human_arm_2dof", "duration": 1.2, "mtc_intervals": 16,
         "methods": ["quintic", "paper"], "particles": 8, "iterations": 5},
        rm.ProfilesOut,
    ),
    "sweep": (
        "sweeps",
        {"robot": "human_arm_2dof", "durations": [1.0, 1.5], "payloads": [4.0],
         "objectives": ["abs_work"], "seed": 2, "particles": 6, "iterations": 4},
        rm.SweepOut,
    ),
    "front": (
        "fronts",
        {"robot": "human_arm_2dof", "payload_mass": 5.0, "objectives": ["tau_sq", "jerk"],
         "points": 3, "intervals": 20, "tolerance": 0.01},
        rm.FrontOut,
    ),
}  # fmt: skip


@pytest.fixture(scope="module")
def served(shared_client: TestClient) -> dict[str, dict[str, Any]]:
    """Each kind's result as ``GET`` serves it (all submitted first: the runner has 2 workers)."""
    ids = {}
    for kind, (path, body, _) in JOBS.items():
        r = shared_client.post(f"/api/{path}", json=body)
        assert r.status_code == 202, r.text
        ids[kind] = r.json()["id"]
    out = {}
    for kind, job_id in ids.items():
        job = wait_job(shared_client, job_id, timeout=900)
        assert job["state"] == "succeeded", job
        r = shared_client.get(job["result_url"])
        assert r.status_code == 200, r.text
        out[kind] = r.json()
    return out


@pytest.fixture(scope="module")
def openapi(shared_client: TestClient) -> dict[str, Any]:
    doc: dict[str, Any] = shared_client.get("/openapi.json").json()
    return doc


def _schema_ref(openapi: dict[str, Any], path: str) -> str:
    schema = openapi["paths"][path]["get"]["responses"]["200"]["content"]["application/json"]
    ref: str = schema["schema"]["$ref"]
    return ref.rsplit("/", 1)[-1]


@pytest.mark.parametrize("kind", sorted(JOBS))
def test_a_real_result_validates_as_its_model_unchanged(
    served: dict[str, dict[str, Any]], kind: str
) -> None:
    model = JOBS[kind][2]
    answer = served[kind]
    typed = model.model_validate(answer)  # a ValidationError names the field that differs
    assert typed.result is not None  # type: ignore[attr-defined]
    # Nothing lost and nothing invented: the model gives back what the server stored.
    again = json.loads(typed.model_dump_json(exclude_unset=True))
    assert again == answer


@pytest.mark.parametrize("kind", sorted(JOBS))
def test_the_openapi_document_names_each_kinds_model(openapi: dict[str, Any], kind: str) -> None:
    path, _, model = JOBS[kind]
    noun = "profiles" if kind == "profiles" else kind
    assert _schema_ref(openapi, f"/api/{path}/{{{noun}_id}}") == model.__name__
    page = _schema_ref(openapi, f"/api/{path}")
    items = openapi["components"]["schemas"][page]["properties"]["items"]["items"]["$ref"]
    assert items.rsplit("/", 1)[-1] == model.__name__
    # The result block is typed: its fields are listed, not an open dict.
    result = openapi["components"]["schemas"][model.__name__]["properties"]["result"]
    refs = [s.get("$ref", "") for s in result["anyOf"]]
    assert any(r.endswith("Result") for r in refs), result


def test_the_other_kinds_and_the_comparison_are_typed(openapi: dict[str, Any]) -> None:
    for path, name in (
        ("/api/cohorts/{cohort_id}", "CohortResultOut"),
        ("/api/analyses/{analysis_id}", "AnalysisResultOut"),
        ("/api/poses/{pose_id}", "PoseResultOut"),
        ("/api/identifications/{identification_id}", "IdentificationResultOut"),
        ("/api/viewer/comparisons/{kind}/{result_id}", "ComparisonView"),
        ("/api/meta", "MetaOut"),
    ):
        assert _schema_ref(openapi, path) == name, path


def test_a_result_that_breaks_the_contract_is_refused(served: dict[str, dict[str, Any]]) -> None:
    """The models check: a plan whose method lost its peak torques does not validate."""
    broken = json.loads(json.dumps(served["plan"]))
    del broken["result"]["standard"]["peak_torque"]
    with pytest.raises(ValueError, match="peak_torque"):
        rm.PlanOut.model_validate(broken)


def _cumulative_trapezoid(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The running integral by ``np.trapezoid`` over every prefix (independent of the app)."""
    return np.array([np.trapezoid(y[: k + 1], t[: k + 1]) for k in range(len(t))])


@pytest.mark.parametrize("points", [40, 10_000])
def test_joint_power_and_energy_are_numpys_trapezoid_on_the_stored_arrays(
    shared_client: TestClient, served: dict[str, dict[str, Any]], points: int
) -> None:
    plan_id = served["plan"]["id"]
    view = shared_client.get(f"/api/viewer/comparisons/plan/{plan_id}?points={points}")
    assert view.status_code == 200, view.text
    data = rm.ComparisonView.model_validate(view.json())
    names = [f"{m}_{x}" for m in ("quintic", "paper") for x in ("tau", "qd")]
    stored = shared_client.get(
        f"/api/plans/{plan_id}/arrays", params={"points": 10_000, "name": ["t", *names]}
    ).json()["arrays"]
    t = np.asarray(stored["t"], dtype=float)
    shown_t = np.asarray(data.curves.t)
    idx = np.searchsorted(t, shown_t)
    assert np.allclose(t[idx], shown_t, rtol=0, atol=1e-12)
    if points < len(t):
        assert len(shown_t) <= points < len(t)  # decimated: integrated before, on every sample
    for label, method in (("standard", "quintic"), ("optimized", "paper")):
        curves = getattr(data.curves, label)
        tau = np.asarray(stored[f"{method}_tau"], dtype=float)
        qd = np.asarray(stored[f"{method}_qd"], dtype=float)
        power = np.abs(tau * qd)
        served_power = np.asarray(curves.joint_power, dtype=float)
        served_energy = np.asarray(curves.joint_energy, dtype=float)
        assert served_power.shape == served_energy.shape == (len(shown_t), tau.shape[1])
        for j in range(tau.shape[1]):
            energy = _cumulative_trapezoid(t, power[:, j])
            np.testing.assert_allclose(served_power[:, j], power[idx, j], rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(served_energy[:, j], energy[idx], rtol=1e-9, atol=1e-12)
        # Summed over the joints, the running energy is the trajectory's absolute work so far.
        total = np.asarray(curves.energy, dtype=float)
        np.testing.assert_allclose(served_energy.sum(axis=1), total, rtol=1e-9, atol=1e-9)


def test_meta_serves_the_front_axes_and_every_floor_formula(shared_client: TestClient) -> None:
    from app.names import FRONT_AXES, METRICS

    meta = rm.MetaOut.model_validate(shared_client.get("/api/meta").json())
    assert meta.front_axes == list(FRONT_AXES)
    # The page can word every axis: by the front's own text or by the shared metric's.
    assert set(meta.front_axis_text) <= set(FRONT_AXES)
    assert all(a in meta.front_axis_text or a in METRICS for a in FRONT_AXES)
    for metric in METRICS.values():  # every floor a metric names has its formula
        if metric.floor is not None:
            assert metric.floor in meta.floor_formulas, metric.name
    for legacy in meta.legacy_floor_keys.values():
        assert legacy in meta.floor_formulas
    assert set(meta.legacy_floor_keys) <= set(METRICS)


def test_meta_offers_every_human_constraint_the_planner_takes(shared_client: TestClient) -> None:
    """The plan page builds its constraint menu from ``/api/meta``: every constraint the
    planner accepts is offered (``shape`` was missing from a hard-coded menu), none other."""
    from app.planning.optimal import HUMAN_CONSTRAINTS as PLANNER_CONSTRAINTS

    meta = rm.MetaOut.model_validate(shared_client.get("/api/meta").json())
    offered = [c.name for c in meta.human_constraints]
    assert offered == list(PLANNER_CONSTRAINTS)
    assert all(c.description for c in meta.human_constraints)
