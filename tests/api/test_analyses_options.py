"""Every upload and analysis option through HTTP: each changes the result and is echoed.

Inputs are the synthetic curls of ``tests/analysis/_synthetic`` written as the files users
upload (known rest/top angles, a 16:9 frame, EMG bursts at known times), so each expected change
is known in advance: a doubled frame rate halves every time, the true image size undoes a known
aspect distortion, an offset shifts every lift by itself, and so on (the same checks as the
CLI's, ``tests/test_cli_analyze.py``, so the API and the CLI agree).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.analysis import _synthetic as syn
from tests.utils.api import TestClient, assert_problem, make_client, wait_job

RATE = 60.0
IMAGE = f"{syn.IMAGE[0]}x{syn.IMAGE[1]}"


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with make_client(tmp_path_factory.mktemp("options")) as c:
        yield c


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("options_files")
    t, y = syn.elbow_curls(3, RATE)
    cycle = syn.RISE_S + syn.HOLD_S + syn.LOWER_S + syn.REST_S
    bursts = [syn.REST_S + k * cycle for k in range(3)]
    return {
        "pose": syn.write_mediapipe_csv(d / "pose.csv", y),
        "both_arms": syn.write_mediapipe_csv(d / "both.csv", y, left_elbow_deg=0.5 * y + 10),
        "emg": syn.write_emg_csv(d / "emg.csv", bursts, seconds=float(t[-1]) + 0.5),
    }


def upload(client: TestClient, *paths: Path, **form: str) -> dict[str, Any]:
    sent = [("files", (p.name, p.read_bytes(), "text/csv")) for p in paths]
    r = client.post("/api/recordings", files=sent, data=form)
    assert r.status_code == 201, r.text
    out: dict[str, Any] = r.json()
    return out


def analysis(client: TestClient, rid: int, **options: Any) -> dict[str, Any]:
    """The finished analysis (``GET /api/analyses/{id}``) of recording ``rid``."""
    r = client.post("/api/analyses", json={"recording_id": rid, **options})
    assert r.status_code == 202, r.text
    return finished(client, r.json()["id"])


def finished(client: TestClient, job_id: int) -> dict[str, Any]:
    job = wait_job(client, job_id)
    assert job["state"] == "succeeded", job
    out: dict[str, Any] = client.get(f"/api/analyses/{job_id}").json()
    return out


def lifts(out: dict[str, Any], k: int = 0) -> list[dict[str, Any]]:
    found: list[dict[str, Any]] = out["result"]["files"][k]["lifts"]
    return found


def pose_upload(client: TestClient, path: Path, **form: str) -> int:
    rid: int = upload(client, path, frame_rate=str(RATE), image_size=IMAGE, **form)["id"]
    return rid


@pytest.fixture(scope="module")
def pose_default(api: TestClient, files: dict[str, Path]) -> tuple[int, dict[str, Any]]:
    """The pose file uploaded at :data:`RATE` with its true image size, and its analysis with
    every option at its default: the reference most option tests compare against, analysed
    once (further analyses of this recording, with options, leave it as it is)."""
    rid = pose_upload(api, files["pose"])
    return rid, analysis(api, rid)


@pytest.fixture(scope="module")
def emg_default(api: TestClient, files: dict[str, Path]) -> dict[str, Any]:
    """The EMG file uploaded with no options and analysed with none (only ever that one
    analysis of this recording: a test lists its analyses)."""
    return analysis(api, upload(api, files["emg"])["id"])


# ------------------------------------------------------------------------ upload (reader)


def test_frame_rate_sets_the_pose_clock(
    api: TestClient, files: dict[str, Path], pose_default: tuple[int, dict[str, Any]]
) -> None:
    slow = pose_default[1]  # uploaded with frame_rate=60
    fast = analysis(api, upload(api, files["pose"], frame_rate="120", image_size=IMAGE)["id"])
    assert slow["result"]["settings"]["frame_rate_hz"] == 60.0
    assert fast["result"]["settings"]["frame_rate_hz"] == 120.0
    assert lifts(fast)[1]["top_s"] == pytest.approx(lifts(slow)[1]["top_s"] / 2, abs=0.02)


def test_image_size_undoes_the_aspect_distortion(
    api: TestClient, files: dict[str, Path], pose_default: tuple[int, dict[str, Any]]
) -> None:
    true = pose_default[1]  # uploaded with the true image size
    raw = analysis(api, upload(api, files["pose"], frame_rate=str(RATE))["id"])
    assert true["result"]["settings"]["image_size_px"] == list(syn.IMAGE)
    assert raw["result"]["settings"]["image_size_px"] is None
    lo, hi = true["result"]["files"][0]["pose"]["elbow_range_deg"]
    assert (lo, hi) == pytest.approx((syn.REST_DEG, syn.TOP_DEG), abs=1.0)
    assert raw["result"]["files"][0]["pose"]["elbow_range_deg"][1] - syn.TOP_DEG > 5.0
    assert any("video size unknown" in w for w in raw["summary"]["warnings"])
    assert not any("video size unknown" in w for w in true["summary"]["warnings"])


def test_emg_rate_at_upload_and_per_analysis(
    api: TestClient, files: dict[str, Path], emg_default: dict[str, Any]
) -> None:
    stored = emg_default  # the rate the file states
    at_upload = analysis(api, upload(api, files["emg"], emg_rate="2000")["id"])
    rid = upload(api, files["emg"])["id"]
    per_request = analysis(api, rid, emg_rate=2000.0)
    t0 = [lift["top_s"] for lift in lifts(stored)]
    for out in (at_upload, per_request):
        assert out["result"]["settings"]["emg_rate_hz"] == 2000.0
        assert out["result"]["files"][0]["emg"]["biceps"]["rate_hz"] == pytest.approx(2000.0)
        np.testing.assert_allclose([x["top_s"] for x in lifts(out)], np.divide(t0, 2), atol=0.05)


def test_muscle_map_at_upload_and_per_analysis(
    api: TestClient, files: dict[str, Path], emg_default: dict[str, Any]
) -> None:
    default = emg_default  # no map
    rec = upload(api, files["emg"], muscle_map='{"deltoid": "triceps"}')
    sites = {c["name"]: c["site"] for c in rec["files"][0]["channels"]}
    assert sites["deltoid"] == "triceps"
    at_upload = analysis(api, rec["id"])
    per_request = analysis(api, upload(api, files["emg"])["id"], muscle_map={"deltoid": "triceps"})
    assert set(default["result"]["files"][0]["emg"]) == {"biceps", "deltoid"}
    for out in (at_upload, per_request):
        assert set(out["result"]["files"][0]["emg"]) == {"biceps", "triceps"}
        assert out["result"]["settings"]["muscle_map"] == {"deltoid": "triceps"}


def test_format_and_rate_pick_the_reader(api: TestClient, files: dict[str, Path]) -> None:
    rec = upload(api, files["pose"], frame_rate=str(RATE), image_size=IMAGE, format="mediapipe_csv")
    assert rec["options"]["format"] == "mediapipe_csv"
    assert [c["dims"] for c in rec["files"][0]["channels"]] == [3, 3, 3]  # landmarks
    out = analysis(api, rec["id"])
    assert out["result"]["settings"]["format"] == "mediapipe_csv"
    # The generic CSV reader on the same bytes: one scalar channel per column, which needs a
    # rate (the file has no time column) -- ``rate`` gives it.
    sent = [("files", ("pose.csv", files["pose"].read_bytes(), "text/csv"))]
    r = api.post("/api/recordings", files=sent, data={"format": "csv"})
    assert_problem(r, 422, file="pose.csv")
    assert "sampling rate" in r.json()["detail"]
    r = api.post("/api/recordings", files=sent, data={"format": "csv", "rate": "50"})
    assert r.status_code == 201, r.text
    generic = r.json()["files"][0]
    assert generic["format"] == "csv" and {c["dims"] for c in generic["channels"]} == {1}
    assert {c["rate"] for c in generic["channels"]} == {50.0}


def test_unsupported_format_names_the_supported_ones(api: TestClient) -> None:
    sent = [("files", ("notes.xyz", b"\x00\x01 just some bytes \x02" * 20, "text/plain"))]
    body = assert_problem(api.post("/api/recordings", files=sent), 422)
    assert "notes.xyz" in body["detail"]
    for named in ("C3D", "EDF", "MediaPipe", "video (mp4, mov, avi)"):
        assert named in body["detail"], body["detail"]


# -------------------------------------------------------------------------- analysis options


def test_side_picks_the_arm(api: TestClient, files: dict[str, Path]) -> None:
    rid = pose_upload(api, files["both_arms"])
    auto = analysis(api, rid)
    left = analysis(api, rid, side="left")
    assert auto["result"]["files"][0]["pose"]["side"] == "right"  # the better visible arm
    assert left["result"]["files"][0]["pose"]["side"] == "left"
    assert left["result"]["settings"]["side"] == "left"
    assert left["result"]["files"][0]["pose"]["elbow_range_deg"][1] == pytest.approx(
        0.5 * syn.TOP_DEG + 10, abs=1.0
    )


def test_session_mode_at_upload_and_per_analysis(api: TestClient, files: dict[str, Path]) -> None:
    form = {"frame_rate": str(RATE), "image_size": IMAGE}
    apart_rec = upload(api, files["pose"], files["emg"], **form)
    joint_rec = upload(api, files["pose"], files["emg"], session="together", **form)
    assert apart_rec["session"] == "separate" and joint_rec["session"] == "together"
    apart, joint = analysis(api, apart_rec["id"]), analysis(api, joint_rec["id"])
    # The overlays are per file too, so the page draws one panel per trial.
    over = api.get(f"/api/viewer/recordings/{apart_rec['id']}/analysis", params={"points": 50})
    assert over.status_code == 200, over.text
    assert [f["file"] for f in over.json()["files"]] == ["pose.csv", "emg.csv"]
    forced = analysis(api, apart_rec["id"], together=True)
    assert apart["result"]["settings"]["session"] == apart["summary"]["session"] == "separate"
    assert joint["result"]["settings"]["session"] == forced["summary"]["session"] == "together"
    # Separate trials: each file its own lifts on its own clock, pooled in one template.
    assert len(apart["result"]["files"]) == 2 and len(joint["result"]["files"]) == 1
    assert [f["lifts"] for f in apart["summary"]["files"]] == [3, 3]
    assert joint["template"]["emg_lifts"] == 3 and joint["template"]["n_lifts"] == 3
    assert joint["template"]["activation_order"][0] == "deltoid"


def test_offset_shifts_the_pose_onto_the_emg_clock(api: TestClient, files: dict[str, Path]) -> None:
    rid = upload(api, files["pose"], files["emg"], session="together", frame_rate=str(RATE),
                 image_size=IMAGE)["id"]  # fmt: skip
    zero = analysis(api, rid, offset=0)
    later = analysis(api, rid, offset=0.75)
    assert zero["result"]["settings"]["offset_s"] == 0
    assert later["result"]["settings"]["offset_s"] == 0.75
    for a, b in zip(lifts(zero), lifts(later), strict=True):
        assert b["start_s"] - a["start_s"] == pytest.approx(0.75, abs=1e-6)


def test_phase_bounds_move_the_phases(
    api: TestClient, pose_default: tuple[int, dict[str, Any]]
) -> None:
    rid, default = pose_default
    moved = analysis(api, rid, phase_bounds_deg=[60, 110])
    assert moved["result"]["settings"]["phase_bounds_deg"] == [60.0, 110.0]
    assert moved["template"]["phase_bounds_deg"] == [60.0, 110.0]

    def a_end(out: dict[str, Any]) -> float:
        return float(next(p["end_s"] for p in lifts(out)[0]["phases"] if p["name"] == "A"))

    assert a_end(moved) > a_end(default) + 0.05


@pytest.mark.parametrize(
    ("option", "value", "key"),
    [("body_mass", 95.0, "body_mass_kg"), ("body_height", 1.95, "body_height_m"),
     ("load_mass", 20.0, "load_mass_kg")],
)  # fmt: skip
def test_body_and_load_change_the_energetics(
    api: TestClient, pose_default: tuple[int, dict[str, Any]], option: str, value: float, key: str
) -> None:
    rid, default = pose_default
    changed = analysis(api, rid, **{option: value})
    assert changed["result"]["settings"][key] == value
    work = [lifts(d)[0]["energetics"]["metrics"]["pos_work"] for d in (default, changed)]
    assert work[1] > work[0] * 1.01  # heavier segments or load: more positive work


def test_load_defaults_to_the_recordings(api: TestClient, files: dict[str, Path]) -> None:
    rid = pose_upload(api, files["pose"], load_kg="20")
    assert analysis(api, rid)["result"]["settings"]["load_mass_kg"] == 20.0


def test_exclude_channels_per_analysis(api: TestClient, files: dict[str, Path]) -> None:
    rid = upload(api, files["emg"])["id"]
    dropped = analysis(api, rid, exclude_channels=["deltoid"])
    assert set(dropped["result"]["files"][0]["emg"]) == {"biceps"}
    assert dropped["result"]["settings"]["exclude_channels"] == ["deltoid"]
    r = api.post("/api/analyses", json={"recording_id": rid, "exclude_channels": ["nope"]})
    assert_problem(r, 422, field="exclude_channels")


# ------------------------------------------------------------------- templates and warnings


def test_templates_say_where_they_came_from(
    api: TestClient, emg_default: dict[str, Any], pose_default: tuple[int, dict[str, Any]]
) -> None:
    emg_only, posed = emg_default, pose_default[1]
    s = emg_only["summary"]
    assert s["is_paper_default"] and s["template_lifts"] == 0
    assert s["template_source"].startswith("paper default: no kinematics")
    assert any("paper's defaults" in w for w in s["warnings"])
    assert s["n_lifts"] == 3  # EMG lifts found, none with kinematics
    # Flat channels are left out with a note, and the note reaches the API.
    assert any("'spare'" in w for w in s["warnings"])
    p = posed["summary"]
    assert not p["is_paper_default"] and p["template_lifts"] == 3
    assert p["template_source"] == posed["template"]["source"]
    listed = api.get("/api/analyses", params={"recording_id": emg_only["recording_id"]}).json()
    assert listed["items"][0]["summary"]["is_paper_default"] is True
