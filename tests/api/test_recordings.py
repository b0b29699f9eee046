"""Recordings API against real files; expected values come from parsing the files here."""

from __future__ import annotations

import csv
import hashlib
import io
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from tests.utils.api import TestClient, assert_problem, make_client
from tests.utils.data import shared_file

NORAXON = "noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv"
MEDIAPIPE = "mediapipe_bicep_curl_frames/test.csv"


def noraxon_reference(path: Path) -> tuple[float, np.ndarray]:
    """Rate [Hz] and EMG [V] of a Noraxon MR3 CSV, read with the csv module (not our reader)."""
    text = path.read_bytes().decode("utf-8-sig")
    rows = list(csv.reader(io.StringIO(text), delimiter=";"))
    header = dict(zip(rows[0], rows[1], strict=True))
    data = [r for r in rows[4:] if r]
    emg_uv = np.array([float(r[3].replace(",", ".")) for r in data])
    return float(header["frequency"]), emg_uv * 1e-6


def _upload(client: TestClient, *paths: Path, **form: str) -> object:
    files = [("files", (p.name, p.read_bytes(), "text/csv")) for p in paths]
    return client.post("/api/recordings", files=files, data=form)


def test_upload_detail_signals_and_raw_bytes(client: TestClient) -> None:
    path = shared_file(NORAXON)
    rate, emg = noraxon_reference(path)
    r = _upload(client, path, subject="s01", task="curl", load_kg="12", notes="supinated")
    assert r.status_code == 201, r.text  # type: ignore[attr-defined]
    rec = r.json()  # type: ignore[attr-defined]
    assert (rec["subject"], rec["task"], rec["load_kg"], rec["n_files"]) == ("s01", "curl", 12, 1)
    f = rec["files"][0]
    assert f["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert f["size"] == path.stat().st_size
    (ch,) = f["channels"]
    assert ch["n_samples"] == len(emg) and ch["rate"] == rate and ch["unit"] == "V"
    assert ch["duration"] == pytest.approx(len(emg) / rate)

    assert client.get(f"/api/recordings/{rec['id']}").json() == rec

    sig = client.get(f"/api/recordings/{rec['id']}/signals", params={"points": 400}).json()
    (s,) = sig["channels"][0]["series"]
    assert 2 <= len(s["t"]) <= 400
    assert np.all(np.diff(s["t"]) > 0)
    # Min/max preserving: the extremes of the whole signal survive the downsampling.
    assert max(s["y"]) == pytest.approx(emg.max(), rel=1e-12)
    assert min(s["y"]) == pytest.approx(emg.min(), rel=1e-12)

    # A window returns only samples inside it.
    win = client.get(
        f"/api/recordings/{rec['id']}/signals",
        params={"t0": 1.0, "t1": 2.0, "points": 10000, "channel": ch["id"]},
    ).json()
    (w,) = win["channels"][0]["series"]
    i0, i1 = int(np.ceil(1.0 * rate)), int(np.floor(2.0 * rate))
    np.testing.assert_allclose(w["y"], emg[i0 : i1 + 1], rtol=1e-12)

    raw = client.get(f"/api/recordings/{rec['id']}/files/{f['id']}")
    assert raw.status_code == 200 and raw.content == path.read_bytes()


def test_one_session_many_files_and_overrides(client: TestClient) -> None:
    nor, mp = shared_file(NORAXON), shared_file(MEDIAPIPE)
    r = _upload(client, nor, mp, frame_rate="30", image_size="640x480")
    assert r.status_code == 201, r.text  # type: ignore[attr-defined]
    rec = r.json()  # type: ignore[attr-defined]
    assert rec["file_names"] == [nor.name, mp.name]
    assert rec["options"] == {"frame_rate": 30.0, "image_size": [640, 480]}
    landmarks = rec["files"][1]["channels"]
    with mp.open() as fh:
        n_frames = sum(1 for _ in fh) - 1
    assert {c["dims"] for c in landmarks} == {3}
    assert all(c["n_samples"] == n_frames and c["rate"] == 30.0 for c in landmarks)
    one = landmarks[0]
    sig = client.get(
        f"/api/recordings/{rec['id']}/signals", params={"name": one["name"], "points": 50}
    ).json()
    assert [s["label"] for s in sig["channels"][0]["series"]] == ["x", "y", "z"]


def test_a_bad_file_rejects_the_whole_upload(client: TestClient, tmp_path: Path) -> None:
    good = shared_file(NORAXON)
    bad = tmp_path / "notes.csv"
    bad.write_text("this is not a recording\nat all\n")
    r = _upload(client, good, bad)
    body = assert_problem(r, 422, file="notes.csv")
    assert "notes.csv" in body["detail"]
    assert client.get("/api/recordings").json()["total"] == 0
    blobs = list((tmp_path / "data" / "blobs").rglob("*"))
    assert [b for b in blobs if b.is_file()] == []


def test_upload_limit_is_enforced(tmp_path: Path) -> None:
    path = shared_file(NORAXON)
    data = path.read_bytes()
    boundary = "bioplan-test-boundary"
    body = (
        (
            f'--{boundary}\r\nContent-Disposition: form-data; name="files"; filename="a.csv"\r\n'
            "Content-Type: text/csv\r\n\r\n"
        ).encode()
        + data
        + f"\r\n--{boundary}--\r\n".encode()
    )
    sent = []

    def chunks() -> Iterator[bytes]:
        for i in range(0, len(body), 16384):
            sent.append(i)
            yield body[i : i + 16384]

    with make_client(tmp_path, max_upload_mb=0.1) as c:
        # Content-Length declared: refused before the body is read.
        assert_problem(_upload(c, path), 413)
        # Chunked, no length: refused while streaming, once 0.1 MB has arrived.
        r = c.post(
            "/api/recordings",
            content=chunks(),
            headers={"Content-Type": f"multipart/form-data; boundary={boundary}"},
        )
        assert "BIOPLAN_MAX_UPLOAD_MB" in assert_problem(r, 413)["detail"]
        assert c.get("/api/recordings").json()["total"] == 0


def test_stored_by_hash_never_by_name(client: TestClient, tmp_path: Path) -> None:
    data = shared_file(NORAXON).read_bytes()
    r = client.post("/api/recordings", files=[("files", ("../../evil name.csv", data))])
    assert r.status_code == 201, r.text
    f = r.json()["files"][0]
    assert f["original_name"] == "evil name.csv"
    stored = [p for p in (tmp_path / "data").rglob("*") if p.is_file()]
    assert tmp_path / "data" / "blobs" / f["sha256"][:2] / f["sha256"] in stored
    assert not any("evil" in p.name for p in stored)
    assert not (tmp_path / "evil name.csv").exists()


def test_list_filters_paging_and_delete(client: TestClient, tmp_path: Path) -> None:
    data = shared_file(NORAXON).read_bytes()
    ids = []
    for i in range(5):
        r = client.post(
            "/api/recordings",
            files=[("files", (f"rec{i}.csv", data))],
            data={"subject": f"s{i % 2}", "task": "curl" if i < 4 else "walk"},
        )
        ids.append(r.json()["id"])
    page = client.get("/api/recordings", params={"limit": 2, "offset": 1}).json()
    assert page["total"] == 5 and [x["id"] for x in page["items"]] == ids[::-1][1:3]
    only = client.get("/api/recordings", params={"subject": "s1"}).json()
    assert only["total"] == 2 and {x["subject"] for x in only["items"]} == {"s1"}
    assert client.get("/api/recordings", params={"task": "walk"}).json()["total"] == 1
    assert client.get("/api/recordings", params={"q": "rec3"}).json()["total"] == 1
    assert client.get("/api/recordings", params={"format": "noraxon_csv"}).json()["total"] == 5

    for n, rid in enumerate(ids):
        assert client.delete(f"/api/recordings/{rid}").status_code == 204
        # The list is cached between writes: every delete shows at once.
        assert client.get("/api/recordings").json()["total"] == 4 - n
    assert_problem(client.get(f"/api/recordings/{ids[0]}"), 404)
    assert_problem(client.delete(f"/api/recordings/{ids[0]}"), 404)
    blobs = [p for p in (tmp_path / "data" / "blobs").rglob("*") if p.is_file()]
    assert blobs == []


def test_response_cache_never_serves_a_page_older_than_a_write() -> None:
    from app.services import ResponseCache

    cache = ResponseCache(maxsize=2)
    v = cache.version
    cache.put("a", v, b"1")
    assert cache.get("a") == b"1"
    stale = cache.version
    cache.invalidate()  # a write committed while "b" was being computed
    cache.put("b", stale, b"old")
    assert cache.get("a") is None and cache.get("b") is None
    cache.put("b", cache.version, b"new")
    cache.put("c", cache.version, b"c")
    cache.put("d", cache.version, b"d")  # evicts the least recently used ("b")
    assert (cache.get("b"), cache.get("c"), cache.get("d")) == (None, b"c", b"d")


def test_form_errors_name_the_field(client: TestClient) -> None:
    data = shared_file(NORAXON).read_bytes()
    files = [("files", ("a.csv", data))]
    r = client.post("/api/recordings", files=files, data={"muscle_map": "{not json"})
    assert_problem(r, 422, field="muscle_map")
    r = client.post("/api/recordings", files=files, data={"muscle_map": '{"A": "calf"}'})
    assert "calf" in assert_problem(r, 422, field="muscle_map")["detail"]
    r = client.post("/api/recordings", files=files, data={"load_kg": "-3"})
    assert_problem(r, 422, field="load_kg")
    ok = client.post("/api/recordings", files=files, data={"format": "noraxon_csv"})
    assert ok.status_code == 201 and ok.json()["options"] == {"format": "noraxon_csv"}
    assert client.delete(f"/api/recordings/{ok.json()['id']}").status_code == 204
    r = client.post("/api/recordings", files=files, data={"format": "c3d"})
    assert_problem(r, 422, file="a.csv")
    r = client.post("/api/recordings", files=[("files", ("empty.csv", b""))])
    assert_problem(r, 422, file="empty.csv")
    r = client.post("/api/recordings", data={"subject": "x"})
    assert_problem(r, 422, field="files")
    assert client.get("/api/recordings").json()["total"] == 0
