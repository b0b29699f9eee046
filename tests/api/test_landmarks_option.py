"""The ``landmarks`` analysis option through HTTP (issue 29): a TRC with only Plug-in Gait
right-side names and one wrist marker is refused without it and analysed with the preset; an
unknown preset is a 422 that lists the presets."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.utils.api import TestClient, assert_problem, make_client, wait_job
from tests.utils.markers import curl_markers, write_trc


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with make_client(tmp_path_factory.mktemp("landmarks")) as c:
        yield c


def _analyse(client: TestClient, rid: int, **options: Any) -> dict[str, Any]:
    r = client.post("/api/analyses", json={"recording_id": rid, **options})
    assert r.status_code == 202, r.text
    job: dict[str, Any] = wait_job(client, r.json()["id"])
    return job


def test_landmarks_preset_through_the_api(api: TestClient, tmp_path: Path) -> None:
    rec, _ = curl_markers({"shoulder": "RSHO", "elbow": "RELB", "wrist": "RWRA"}, 12.0)
    trc = write_trc(tmp_path / "pig_right.trc", rec)
    r = api.post("/api/recordings", files=[("files", (trc.name, trc.read_bytes(), "text/plain"))])
    assert r.status_code == 201, r.text
    rid = r.json()["id"]
    refused = _analyse(api, rid)
    assert refused["state"] == "failed"
    assert "no arm landmarks" in str(refused["error"]) and "plugin_gait_right" in str(
        refused["error"]
    )
    done = _analyse(api, rid, landmarks="plugin_gait_right")
    assert done["state"] == "succeeded", done
    out = api.get(f"/api/analyses/{done['id']}").json()
    assert out["result"]["n_lifts"] == 6
    assert out["result"]["settings"]["pose"]["landmarks"] == "plugin_gait_right"
    body = assert_problem(
        api.post("/api/analyses", json={"recording_id": rid, "landmarks": "vicon"}), 422
    )
    assert "plugin_gait_right" in body["detail"]
