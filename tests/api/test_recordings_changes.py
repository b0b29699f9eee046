"""After upload: the rate check and its one-request rerun, muscle mapping and excluded channels
changed with ``PATCH`` and the analysis rerun without uploading again; BIDS sidecars."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.analysis import _synthetic as syn
from tests.api.test_analyses_options import analysis, finished, upload
from tests.utils.api import TestClient, assert_problem, make_client
from tests.utils.data import shared_file

NT01 = "noraxon_curls_biceps_brachioradialis/NT-01.mat"
BIDS = "edf_emg_bids_examples/emg_CustomBipolar/sub-01_task-holdWeight"


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with make_client(tmp_path_factory.mktemp("changes")) as c:
        yield c


@pytest.fixture(scope="module")
def emg(tmp_path_factory: pytest.TempPathFactory) -> Path:
    t, _ = syn.elbow_curls(3, 60.0)
    cycle = syn.RISE_S + syn.HOLD_S + syn.LOWER_S + syn.REST_S
    bursts = [syn.REST_S + k * cycle for k in range(3)]
    path = tmp_path_factory.mktemp("changes_files") / "emg.csv"
    return syn.write_emg_csv(path, bursts, seconds=float(t[-1]) + 0.5)


def patch(client: TestClient, rid: int, **body: Any) -> dict[str, Any]:
    r = client.patch(f"/api/recordings/{rid}", json=body)
    assert r.status_code == 200, r.text
    out: dict[str, Any] = r.json()
    return out


def test_rate_check_at_upload_and_the_one_request_rerun(api: TestClient) -> None:
    path = shared_file(NT01)
    rec = upload(api, path)
    check = rec["rate_check"]
    # NT-01 stores 20 kHz; its EMG's spectral median (474 Hz there) says 2 kHz.
    assert check["stored_rate_hz"] == 20000.0 and check["suggested_rate_hz"] == 2000.0
    assert check["file"] == "NT-01.mat" and check["reason"]
    assert api.get(f"/api/recordings/{rec['id']}").json()["rate_check"] == check
    assert any("implausible" in w for w in rec["warnings"])

    before = analysis(api, rec["id"])
    assert before["result"]["files"][0]["rate_check"] is not None
    rerun = check["rerun"]
    assert rerun["method"] == "PATCH" and rerun["url"] == f"/api/recordings/{rec['id']}"
    r = api.request(rerun["method"], rerun["url"], json=rerun["json"])
    assert r.status_code == 200, r.text
    fixed = r.json()
    assert fixed["options"]["emg_rate"] == 2000.0 and fixed["rate_check"] is None
    after = finished(api, fixed["analysis_job"]["id"])
    assert after["result"]["settings"]["emg_rate_hz"] == 2000.0
    assert after["result"]["files"][0]["rate_check"] is None
    # 10x the rate: the same samples last a tenth of the time.
    span0 = before["result"]["files"][0]["emg"]
    span1 = after["result"]["files"][0]["emg"]
    site = next(iter(span0))
    assert span1[site]["rate_hz"] == pytest.approx(span0[site]["rate_hz"] * 0.1)
    # The old analysis is kept beside the new one.
    listed = api.get("/api/analyses", params={"recording_id": rec["id"]}).json()
    assert [a["id"] for a in listed["items"]] == [after["id"], before["id"]]


def test_patch_mapping_and_exclusion_rerun_without_upload(api: TestClient, emg: Path) -> None:
    rec = upload(api, emg, subject="s1")
    rid = rec["id"]
    flat = {c["name"]: c["flat"] for c in rec["files"][0]["channels"]}
    assert flat == {"biceps": False, "deltoid": False, "spare": True}
    first = analysis(api, rid)
    assert set(first["result"]["files"][0]["emg"]) == {"biceps", "deltoid"}

    mapped = patch(api, rid, muscle_map={"deltoid": "triceps"})
    sites = {c["name"]: c["site"] for c in mapped["files"][0]["channels"]}
    assert sites["deltoid"] == "triceps" and mapped["updated_at"] is not None
    out = finished(api, mapped["analysis_job"]["id"])
    assert set(out["result"]["files"][0]["emg"]) == {"biceps", "triceps"}
    assert out["result"]["settings"]["muscle_map"] == {"deltoid": "triceps"}

    excluded = patch(api, rid, exclude_channels=["deltoid"], session="together", subject="s2")
    assert excluded["subject"] == "s2" and excluded["session"] == "together"
    marks = {c["name"]: c["excluded"] for c in excluded["files"][0]["channels"]}
    assert marks == {"biceps": False, "deltoid": True, "spare": False}
    out = finished(api, excluded["analysis_job"]["id"])
    assert set(out["result"]["files"][0]["emg"]) == {"biceps"}
    assert out["result"]["settings"]["exclude_channels"] == ["deltoid"]
    assert out["result"]["settings"]["session"] == "together"

    # Without a rerun; then clearing the exclusion brings the channel back.
    quiet = patch(api, rid, exclude_channels=None, analyse=False)
    assert quiet["analysis_job"] is None and "exclude_channels" not in quiet["options"]
    listed = api.get("/api/analyses", params={"recording_id": rid}).json()
    assert listed["total"] == 3  # every earlier analysis is kept

    # Bad changes are 4xx, and change nothing.
    assert_problem(
        api.patch(f"/api/recordings/{rid}", json={"exclude_channels": ["nope"]}),
        422,
        field="exclude_channels",
    )
    assert_problem(
        api.patch(f"/api/recordings/{rid}", json={"muscle_map": {"nope": "biceps"}}),
        422,
        field="muscle_map",
    )
    assert_problem(api.patch(f"/api/recordings/{rid}", json={"muscle_map": {"x": "toe"}}), 422)
    assert_problem(api.patch("/api/recordings/99999", json={"subject": "x"}), 404)
    again = api.get(f"/api/recordings/{rid}").json()
    assert again["options"] == quiet["options"] and again["subject"] == "s2"


def test_bids_sidecars_go_with_their_edf(api: TestClient) -> None:
    names = [f"{BIDS}_emg.edf", f"{BIDS}_channels.tsv", f"{BIDS}_emg.json"]
    paths = [shared_file(n) for n in names]
    rec = upload(api, *paths)
    roles = {f["original_name"]: (f["role"], f["parent_id"]) for f in rec["files"]}
    edf = next(f for f in rec["files"] if f["role"] == "recording")
    assert roles == {
        paths[0].name: ("recording", None),
        paths[1].name: ("sidecar", edf["id"]),
        paths[2].name: ("sidecar", edf["id"]),
    }
    # The target muscle comes from channels.tsv (the EDF alone names none), the device from
    # the JSON sidecar.
    (ch,) = edf["channels"]
    assert ch["name"] == "EMG1" and ch["site"] == "forearm"
    assert edf["metadata"]["device"] == "Custom Raspberry Pi"
    assert all(not f["channels"] for f in rec["files"] if f["role"] == "sidecar")
    bare = upload(api, paths[0])
    assert bare["files"][0]["channels"][0]["site"] is None

    # A sidecar without its EDF is refused, naming both.
    sent = [("files", (paths[1].name, paths[1].read_bytes(), "text/plain"))]
    body = assert_problem(api.post("/api/recordings", files=sent), 422)
    assert paths[1].name in body["detail"] and "_emg.edf" in body["detail"]
