"""A recording's condition from its BIDS file names or sidecars at upload (issue 29): filled
unless the user gives one, with where it came from; the user's own replaces it."""

from __future__ import annotations

import json
from pathlib import Path

from tests.utils.api import TestClient
from tests.utils.data import SHARED_DATA

CUSTOM = SHARED_DATA / "edf_emg_bids_examples/emg_CustomBipolar"
STEM = "sub-01_task-holdWeight"


def _files(stem: str, emg_json: dict[str, object] | None = None) -> list[tuple[str, tuple]]:
    """The BIDS example's EDF and sidecars, uploaded under ``stem``."""
    out = []
    for suffix in ("_emg.edf", "_channels.tsv", "_emg.json"):
        data = (CUSTOM / f"{STEM}{suffix}").read_bytes()
        if suffix == "_emg.json" and emg_json is not None:
            data = json.dumps({**json.loads(data), **emg_json}).encode()
        out.append(("files", (f"{stem}{suffix}", data)))
    return out


def _upload(client: TestClient, files: list[tuple[str, tuple]], **form: str) -> dict:
    r = client.post("/api/recordings", files=files, data=form)
    assert r.status_code == 201, r.text
    body: dict = r.json()
    return body


def test_condition_from_bids_names_and_sidecar(client: TestClient, shared_data: Path) -> None:
    # the real example's name: its task entity is all that names a condition
    rec = _upload(client, _files(STEM))
    assert rec["condition"] == "holdWeight"
    assert rec["options"]["condition_from"] == (
        f"the task-holdWeight (BIDS task) entity of {STEM}_emg.edf"
    )
    # a planted acquisition entity wins over the task
    rec = _upload(client, _files("sub-02_task-curl_acq-supinated"))
    assert rec["condition"] == "supinated"
    assert "acq-supinated (BIDS acquisition)" in rec["options"]["condition_from"]
    # a Condition in the _emg.json sidecar wins over acq-
    rec = _upload(client, _files("sub-03_task-curl_acq-x", {"Condition": "heavy"}))
    assert rec["condition"] == "heavy"
    side = "sub-03_task-curl_acq-x_emg.json"
    assert rec["options"]["condition_from"] == f"the Condition field of {side}"
    # the user's condition is kept as given, and nothing says it came from the files
    mine = _upload(client, _files("sub-04_task-curl_cond-light"), condition="fatigued")
    assert mine["condition"] == "fatigued" and "condition_from" not in mine["options"]
    # a condition set later is the user's: the file names' note goes
    r = client.patch(f"/api/recordings/{rec['id']}", json={"condition": "light", "analyse": False})
    assert r.status_code == 200, r.text
    assert r.json()["condition"] == "light" and "condition_from" not in r.json()["options"]
    # the list of recordings finds it by the condition the name gave
    found = client.get("/api/recordings", params={"q": "supinated"}).json()
    assert [x["condition"] for x in found["items"]] == ["supinated"]


def test_no_condition_without_an_entity(client: TestClient, shared_data: Path) -> None:
    data = (SHARED_DATA / "biosppy_emg_examples/emg_1.txt").read_bytes()
    rec = _upload(client, [("files", ("S01 curls.txt", data))], rate="1000")
    assert rec["condition"] is None and "condition_from" not in rec["options"]
