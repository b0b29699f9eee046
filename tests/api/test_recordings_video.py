"""Videos through HTTP: checked at upload (4xx, nothing stored), turned into pose by a job with
progress that can be cancelled (nothing half-stored), skeleton frames served, then analysed.

Needs the pose environment (``make test`` creates it; ``BIOPLAN_POSE_PYTHON``) and the shared
Sports2D demo video; skips with the reason otherwise.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from app.errors import BioPlanError
from tests.utils.api import TestClient, assert_problem, make_client, wait_job
from tests.utils.data import shared_file

DEMO = "video_sports2d_demo/demo.mp4"


@pytest.fixture(scope="module")
def video() -> Path:
    from app.recordings import find_pose_python

    try:
        find_pose_python()
    except BioPlanError:
        pytest.skip(
            "no pose environment (make test creates it; or set BIOPLAN_POSE_PYTHON /"
            " run 'bioplan pose-env')"
        )
    return shared_file(DEMO)


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("video")


@pytest.fixture(scope="module")
def api(folder: Path, video: Path) -> Iterator[TestClient]:
    with make_client(folder) as c:
        yield c


def _workers(scratch: Path) -> list[int]:
    """Pids of the processes whose command line names a video copy in ``scratch``."""
    pids = []
    for entry in Path("/proc").iterdir():
        try:
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if entry.name.isdigit() and str(scratch) in cmd:
            pids.append(int(entry.name))
    return pids


def _send(client: TestClient, name: str, data: bytes, **form: str) -> Any:
    return client.post("/api/recordings", files=[("files", (name, data, "video/mp4"))], data=form)


def _count(client: TestClient) -> int:
    total: int = client.get("/api/recordings").json()["total"]
    return total


def test_bad_videos_are_refused_at_upload_and_nothing_is_stored(
    api: TestClient, video: Path, tmp_path: Path
) -> None:
    before = _count(api)
    body = assert_problem(
        _send(api, "broken.mp4", b"\x00\x00\x00\x18ftypmp42" + b"\x01" * 500), 422
    )
    assert "broken.mp4" in body["detail"]
    body = assert_problem(_send(api, "notes.mov", b"hello, not a video at all" * 10), 422)
    assert "notes.mov" in body["detail"]
    assert _count(api) == before
    # A video longer than the server's limit (the demo lasts about 7.7 s).
    with make_client(tmp_path, max_video_seconds=2.0) as short:
        body = assert_problem(_send(short, "demo.mp4", video.read_bytes()), 422, file="demo.mp4")
        assert "limit of 2 s" in body["detail"] and "BIOPLAN_MAX_VIDEO_SECONDS" in body["detail"]
        assert _count(short) == 0


def _follow(client: TestClient, job_id: int, timeout: float = 300.0) -> list[dict[str, Any]]:
    """Every distinct job state seen while polling, until the job ends."""
    seen: list[dict[str, Any]] = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job: dict[str, Any] = client.get(f"/api/jobs/{job_id}").json()
        if not seen or job != seen[-1]:
            seen.append(job)
        if job["state"] in ("succeeded", "failed", "cancelled"):
            return seen
        time.sleep(0.2)
    raise AssertionError(f"pose job {job_id} did not end within {timeout} s: {seen[-1]}")


@pytest.mark.slow
def test_video_to_pose_to_analysis_end_to_end(api: TestClient, video: Path) -> None:
    rec = _send(api, video.name, video.read_bytes(), subject="walker").json()
    rid = rec["id"]
    (vid,) = rec["files"]
    assert vid["role"] == "video" and vid["format"] == "video" and not vid["channels"]
    assert vid["video"]["width"] == 1768 and vid["video"]["height"] == 994
    (job,) = rec["pose_jobs"]
    assert job["kind"] == "pose" and job["result_url"] == f"/api/poses/{job['id']}"
    # Analysing before the landmarks exist: 409 naming the pose job to wait for.
    body = assert_problem(api.post("/api/analyses", json={"recording_id": rid}), 409)
    assert body["job"]["id"] == job["id"]

    seen = _follow(api, job["id"])
    assert seen[-1]["state"] == "succeeded", seen[-1]
    frames = [j for j in seen if j.get("stage") == "pose" and j.get("of")]
    assert frames, seen
    assert {j["of"] for j in frames} == {vid["video"]["frames"]}
    done = [j["done"] for j in frames]
    assert done == sorted(done) and done[-1] <= vid["video"]["frames"]

    pose = api.get(job["result_url"]).json()
    result = pose["result"]
    assert result["frames"] == vid["video"]["frames"] and result["frames_with_pose"] > 100
    assert result["image_size"] == [1768, 994] and result["fps"] == pytest.approx(30, abs=0.5)

    detail = api.get(f"/api/recordings/{rid}").json()
    marks = next(f for f in detail["files"] if f["role"] == "recording")
    assert marks["parent_id"] == vid["id"] and marks["format"] == "mediapipe_json"
    assert marks["id"] == result["landmarks_file_id"]
    assert {c["dims"] for c in marks["channels"]} == {3}
    assert detail["files"][0]["pose"]["job"]["state"] == "succeeded"
    assert detail["n_files"] == 1  # the user uploaded one file

    listed = api.get(detail["frames_url"]).json()["frames"]
    assert 1 <= len(listed) <= 4 and all(f["video"] == "demo.mp4" for f in listed)
    jpeg = api.get(listed[0]["url"])
    assert jpeg.status_code == 200 and jpeg.headers["content-type"] == "image/jpeg"
    assert jpeg.content[:2] == b"\xff\xd8"
    assert (
        api.get(listed[0]["url"], headers={"if-none-match": jpeg.headers["etag"]}).status_code
        == 304
    )
    assert_problem(api.get(f"/api/recordings/{rid}/frames/{len(listed)}.jpg"), 404)
    # Whom each frame shows (two people are in the video): what the pose quality module
    # decides from the stored landmarks, frame by frame.
    from app.recordings.video import _frame_quality

    quality = _frame_quality(api.get(f"/api/recordings/{rid}/files/{marks['id']}").content)
    assert quality is not None and quality.n_persons >= 1
    for f in listed:
        assert f["person"] == int(quality.person[f["frame"]])
        assert f["quality"] == pytest.approx(float(quality.score[f["frame"]]), abs=1e-12)
        assert f["note"].startswith("the tracked person" if f["person"] == 0 else "not the")

    # The landmarks are analysed as soon as they are stored, like an uploaded MediaPipe file.
    deadline = time.monotonic() + 60
    while not (items := api.get("/api/analyses", params={"recording_id": rid}).json()["items"]):
        assert time.monotonic() < deadline, "no analysis after the pose job"
        time.sleep(0.2)
    out = wait_job(api, items[0]["id"])
    assert out["state"] == "succeeded", out
    analysed = api.get(f"/api/analyses/{out['id']}").json()
    assert analysed["result"]["files"][0]["format"] == "mediapipe_json"
    assert analysed["summary"]["session"] == "separate"

    # Deleting the recording takes its video, landmarks and frames along.
    assert api.delete(f"/api/recordings/{rid}").status_code == 204
    assert_problem(api.get(f"/api/recordings/{rid}/frames"), 404)
    assert api.get(job["result_url"]).json()["recording_id"] is None


def test_a_cancelled_pose_job_leaves_nothing_half_stored(
    api: TestClient, video: Path, folder: Path
) -> None:
    scratch = folder / "data" / "scratch"
    rec = _send(api, video.name, video.read_bytes()).json()
    rid, (job,) = rec["id"], rec["pose_jobs"]
    # Wait until the worker is decoding frames, then cancel.
    deadline = time.monotonic() + 120
    while not (api.get(f"/api/jobs/{job['id']}").json()["stage"] == "pose" and _workers(scratch)):
        assert time.monotonic() < deadline, api.get(f"/api/jobs/{job['id']}").json()
        time.sleep(0.1)
    r = api.post(f"/api/jobs/{job['id']}/cancel")
    assert r.status_code in (200, 202), r.text
    ended = wait_job(api, job["id"])
    assert ended["state"] == "cancelled", ended
    # The worker is stopped and the video's temporary copy removed.
    deadline = time.monotonic() + 30
    while _workers(scratch) or list(scratch.glob("pose-*")):
        assert time.monotonic() < deadline, (_workers(scratch), list(scratch.iterdir()))
        time.sleep(0.2)
    detail = api.get(f"/api/recordings/{rid}").json()
    assert [f["role"] for f in detail["files"]] == ["video"]  # no landmarks file
    assert detail["frames_url"] is None
    assert api.get(f"/api/recordings/{rid}/frames").json()["frames"] == []
    assert api.get(f"/api/poses/{job['id']}").json()["result"] is None
    assert api.get("/api/analyses", params={"recording_id": rid}).json()["total"] == 0
    body = assert_problem(api.post("/api/analyses", json={"recording_id": rid}), 409)
    assert f"/api/recordings/{rid}/pose" in body["detail"]
    # It can be started again (one request), and refused while it runs.
    again = api.post(f"/api/recordings/{rid}/pose")
    assert again.status_code == 202, again.text
    (job2,) = again.json()["pose_jobs"]
    assert_problem(api.post(f"/api/recordings/{rid}/pose"), 409)
    api.post(f"/api/jobs/{job2['id']}/cancel")
    assert wait_job(api, job2["id"])["state"] == "cancelled"


def test_a_video_without_a_person_fails_its_job_and_stores_nothing(
    api: TestClient, tmp_path: Path
) -> None:
    import numpy as np

    from tests.recordings.test_video import _write_video

    blank = _write_video(tmp_path / "empty.mp4", [np.full((120, 160, 3), 90)] * 12)
    rec = _send(api, "empty.mp4", blank.read_bytes()).json()
    (job,) = rec["pose_jobs"]
    ended = wait_job(api, job["id"])
    assert ended["state"] == "failed" and "no person detected" in ended["error"], ended
    detail = api.get(f"/api/recordings/{rec['id']}").json()
    assert [f["role"] for f in detail["files"]] == ["video"] and detail["frames_url"] is None
    assert detail["files"][0]["pose"]["job"]["state"] == "failed"
    assert api.get("/api/analyses", params={"recording_id": rec["id"]}).json()["total"] == 0


def test_deleting_a_recording_cancels_its_pose_job(api: TestClient, video: Path) -> None:
    rec = _send(api, video.name, video.read_bytes()).json()
    (job,) = rec["pose_jobs"]
    assert api.delete(f"/api/recordings/{rec['id']}").status_code == 204
    ended = wait_job(api, job["id"])
    assert ended["state"] == "cancelled", ended
    assert_problem(api.get(f"/api/recordings/{rec['id']}"), 404)
