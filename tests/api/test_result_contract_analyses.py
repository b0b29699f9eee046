"""The typed result contract of the analysis, cohort and identification kinds (issue 24 item 5):
real results, run here as jobs on real recordings (``../shared/data``) and on robot logs made
by MuJoCo's inverse dynamics, validate against ``app.api.result_models`` unchanged, and every
key they hold is a declared field, at the top level and in every typed block below it, so the
models cannot drift from what the library emits (a new key fails here until it is documented,
and a declared field the library stops writing fails too)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import BaseModel

from app.api import result_models as rm
from app.jsonsafe import json_safe
from app.services.demo import synthetic_curls_csv
from tests.utils.api import TestClient, wait_job
from tests.utils.data import shared_file
from tests.utils.robot_logs import arm_urdf, excitation, mujoco_torques, write_generic_csv

#: The routes' contract: SQLite only (tests/api/conftest.py).
pytestmark = pytest.mark.api_contract

C3D = "pyomeca_upperlimb_c3d_emg/markers_analogs.c3d"  # markers + 13 EMG channels: 3 lifts
LANDMARKS = "mediapipe_bicep_curl_frames/test.csv"  # MediaPipe landmarks with per-frame quality
NORAXON = "noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv"  # EMG only


def _walk(value: Any, path: str = "result") -> Iterator[tuple[str, BaseModel]]:
    """Every model in a validated result, with its path (``result.files[0].lifts[2]``)."""
    if isinstance(value, BaseModel):
        yield path, value
        for name in type(value).model_fields:
            yield from _walk(getattr(value, name), f"{path}.{name}")
    elif isinstance(value, dict):
        for key, item in value.items():
            yield from _walk(item, f"{path}[{key}]")
    elif isinstance(value, list | tuple):
        for i, item in enumerate(value):
            yield from _walk(item, f"{path}[{i}]")


def undocumented(result: BaseModel) -> list[str]:
    """Keys a result holds that no model declares, anywhere a model is declared."""
    return [f"{path}.{key}" for path, m in _walk(result) for key in m.model_extra or {}]


def unwritten(result: BaseModel) -> list[str]:
    """Declared fields the result does not hold (a freshly computed result holds them all)."""
    return [
        f"{path}.{name}"
        for path, m in _walk(result)
        for name in type(m).model_fields
        if name not in m.model_fields_set
    ]


# ------------------------------------------------------------------------- the real jobs


@pytest.fixture(scope="module")
def arm_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    """A nominal 3-joint arm and a log of the *true* arm (heavier, with a 1 kg payload):
    torques from MuJoCo's inverse dynamics plus viscous friction and noise."""
    from app.planning.robots import load_robot

    folder = tmp_path_factory.mktemp("contract-arm")
    true = folder / "true.urdf"
    true.write_text(arm_urdf(3, masses=[4.0, 4.2, 3.0], payload=1.0))
    robot = load_robot(str(true))
    t, q, qd, qdd = excitation(8.0, 200.0, 3, seed=4)
    noise = np.random.default_rng(2).normal(0.0, 0.05, q.shape)
    tau = mujoco_torques(robot, q, qd, qdd) + 0.8 * qd + noise
    log = write_generic_csv(folder / "log.csv", t, robot.joint_names, q, tau)
    return {"urdf": arm_urdf(3).encode(), "log": Path(log).read_bytes()}


def _upload(client: TestClient, name: str, data: bytes, **form: str) -> int:
    r = client.post("/api/recordings", files=[("files", (name, data))], data=form)
    assert r.status_code == 201, r.text
    rid: int = r.json()["id"]
    return rid


def _submit(client: TestClient, path: str, body: dict[str, Any]) -> int:
    r = client.post(path, json=body)
    assert r.status_code == 202, r.text
    job_id: int = r.json()["id"]
    return job_id


def _submit_all(client: TestClient, arm: dict[str, bytes]) -> dict[str, int]:
    """Every job of the module, submitted before any is awaited (the runner has 2 workers)."""
    jobs = {}
    for key, relative, form in (
        ("analysis_c3d", C3D, {}),
        ("analysis_landmarks", LANDMARKS, {"frame_rate": "30"}),
    ):
        path = shared_file(relative)
        rid = _upload(client, path.name, path.read_bytes(), **form)
        jobs[key] = _submit(client, "/api/analyses", {"recording_id": rid})
    for cond, up, seed in (("slow", 1.6, 0), ("quick", 0.9, 10)):
        for i in range(3):
            data = synthetic_curls_csv(lifts=2, seed=seed + i, up=up)
            _upload(client, f"{cond}_{i}.csv", data, condition=cond)
    jobs["cohort"] = _submit(client, "/api/cohorts", {"group_by": "condition"})
    r = client.post("/api/robots", data={"name": "arm"}, files={"urdf": ("arm.urdf", arm["urdf"])})
    assert r.status_code == 201, r.text
    r = client.post(
        "/api/robot-logs", data={"robot": "arm"}, files={"file": ("log.csv", arm["log"])}
    )
    assert r.status_code == 201, r.text
    log_id = r.json()["id"]
    jobs["identify"] = _submit(client, "/api/identifications", {"log_ids": [log_id]})
    jobs["identify_payload"] = _submit(
        client,
        "/api/identifications",
        {"log_ids": [log_id], "version": "arm-payload", "identify_payload": True},
    )
    return jobs


@pytest.fixture(scope="module")
def served(shared_client: TestClient, arm_files: dict[str, bytes]) -> dict[str, dict[str, Any]]:
    """Each job's answer as ``GET`` of its result serves it."""
    out = {}
    for key, job_id in _submit_all(shared_client, arm_files).items():
        job = wait_job(shared_client, job_id, timeout=900)
        assert job["state"] == "succeeded", job
        r = shared_client.get(job["result_url"])
        assert r.status_code == 200, r.text
        out[key] = r.json()
    return out


MODELS: dict[str, type[BaseModel]] = {
    "analysis_c3d": rm.AnalysisResultOut,
    "analysis_landmarks": rm.AnalysisResultOut,
    "cohort": rm.CohortResultOut,
    "identify": rm.IdentificationResultOut,
    "identify_payload": rm.IdentificationResultOut,
}


# ------------------------------------------------------------------------------- the tests


@pytest.mark.parametrize("key", sorted(MODELS))
def test_a_served_result_validates_unchanged_with_every_key_declared(
    served: dict[str, dict[str, Any]], key: str
) -> None:
    answer = served[key]
    typed = MODELS[key].model_validate(answer)  # a ValidationError names the field
    result = typed.result  # type: ignore[attr-defined]
    assert result is not None
    assert undocumented(result) == []
    assert unwritten(result) == []
    if key.startswith("analysis"):
        assert undocumented(typed.template) == [] and unwritten(typed.template) == []  # type: ignore[attr-defined]
    # Nothing lost and nothing invented: the model gives back what the server stored.
    assert json.loads(typed.model_dump_json(exclude_unset=True)) == answer


def test_the_real_results_reach_every_typed_block(served: dict[str, dict[str, Any]]) -> None:
    """The jobs above are not trivial: the typed blocks below the top level are exercised
    (lifts with phases and energetics, pose quality, tests with p-values, a payload)."""
    c3d = rm.AnalysisResultOut.model_validate(served["analysis_c3d"]).result
    assert c3d is not None and c3d.n_lifts == 3 and c3d.template.n_lifts == 3
    lift = c3d.files[0].lifts[0]
    assert lift.phases and lift.energetics is not None and lift.energetics.phases
    assert {"biceps", "triceps", "deltoid"} <= set(c3d.files[0].emg)
    landmarks = rm.AnalysisResultOut.model_validate(served["analysis_landmarks"]).result
    assert landmarks is not None
    pose = landmarks.files[0].pose
    assert pose is not None and pose.quality is not None and pose.quality.frames == 604
    assert landmarks.files[0].lifts[0].quality is not None
    cohort = rm.CohortResultOut.model_validate(served["cohort"]).result
    assert cohort is not None and set(cohort.groups) == {"slow", "quick"}
    assert any(t.p is not None for t in cohort.tests) and len(cohort.recording_ids or []) == 6
    plain = rm.IdentificationResultOut.model_validate(served["identify"]).result
    loaded = rm.IdentificationResultOut.model_validate(served["identify_payload"]).result
    assert plain is not None and plain.payload is None and plain.version == "arm-identified"
    assert loaded is not None and loaded.payload is not None
    # MuJoCo made the log, Pinocchio fits it: the identified arm predicts the held-back part.
    assert all(f.r2 is not None and f.r2 > 0.95 for f in plain.held_back.values()), plain.held_back
    assert loaded.payload.body == "link3" and loaded.payload.mass > 0.0
    assert set(plain.friction) == set(plain.joints) == set(plain.fit)


def test_an_undocumented_or_missing_key_is_found(served: dict[str, dict[str, Any]]) -> None:
    """The checks above can fail: a key the models do not declare is reported with its path,
    and a result that lost a required field does not validate."""
    planted = json.loads(json.dumps(served["analysis_c3d"]))
    planted["result"]["new_block"] = 1
    planted["result"]["files"][0]["lifts"][1]["new_metric_j"] = 2.0
    typed = rm.AnalysisResultOut.model_validate(planted).result
    assert typed is not None
    assert undocumented(typed) == ["result.new_block", "result.files[0].lifts[1].new_metric_j"]
    broken = json.loads(json.dumps(served["identify"]))
    del broken["result"]["friction"]
    with pytest.raises(ValueError, match="friction"):
        rm.IdentificationResultOut.model_validate(broken)
    stripped = json.loads(json.dumps(served["cohort"]))
    del stripped["result"]["recording_ids"]  # optional (the CLI's JSON has none): unwritten
    lacking = rm.CohortResultOut.model_validate(stripped).result
    assert lacking is not None and unwritten(lacking) == ["result.recording_ids"]


@pytest.mark.parametrize(
    ("relative", "options"),
    [(C3D, {}), (LANDMARKS, {"frame_rate": 30.0}), (NORAXON, {})],
)
def test_the_librarys_analysis_json_is_documented(relative: str, options: dict[str, Any]) -> None:
    """``bioplan analyze --json`` (the library's ``to_dict``, without the service's echo) on
    real files of three kinds: every key declared; the service-only settings left unset."""
    from app.analysis import analyze_files

    data = json_safe(analyze_files([shared_file(relative)], **options).to_dict())
    typed = rm.AnalysisResult.model_validate(data)
    assert undocumented(typed) == []
    assert json.loads(typed.model_dump_json(exclude_unset=True)) == data
    service_only = {"result.settings.rate_hz", "result.settings.format", "result.settings.side"}
    assert set(unwritten(typed)) == service_only


def test_the_openapi_document_types_the_three_kinds(shared_client: TestClient) -> None:
    """/openapi.json lists the result blocks' fields, not open objects."""
    schemas = shared_client.get("/openapi.json").json()["components"]["schemas"]
    for out, field, name in (
        ("AnalysisResultOut", "result", "AnalysisResult"),
        ("AnalysisResultOut", "template", "HumanTemplateOut"),
        ("CohortResultOut", "result", "CohortResult"),
        ("IdentificationResultOut", "result", "IdentificationResult"),
    ):
        refs = [s.get("$ref", "") for s in schemas[out]["properties"][field]["anyOf"]]
        assert f"#/components/schemas/{name}" in refs, (out, field, refs)
        assert set(schemas[name]["properties"]) == set(getattr(rm, name).model_fields)
    lift = schemas["AnalysisLift"]["properties"]
    assert lift["peak_velocity_angle_deg"]["description"] == "flexion at the velocity peak"
    assert schemas["CohortGroup"]["properties"]["measures"]["additionalProperties"] == {
        "$ref": "#/components/schemas/CohortMeasureSummary"
    }
