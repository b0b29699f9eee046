"""Settings refuse unsafe binds; writes need the token when one is set; CORS closed by default."""

from __future__ import annotations

from pathlib import Path

import pytest
from pydantic import ValidationError

from app.config import Settings, is_loopback
from tests.utils.api import assert_problem, make_client


@pytest.mark.parametrize(
    ("host", "loopback"),
    [("127.0.0.1", True), ("127.8.9.10", True), ("::1", True), ("localhost", True),
     ("0.0.0.0", False), ("192.168.1.5", False), ("::", False), ("example.org", False)],
)  # fmt: skip
def test_loopback_detection(host: str, loopback: bool) -> None:
    assert is_loopback(host) is loopback


def test_non_loopback_bind_needs_a_token(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BIOPLAN_HOST", "0.0.0.0")
    monkeypatch.delenv("BIOPLAN_API_TOKEN", raising=False)
    with pytest.raises(ValidationError, match="BIOPLAN_API_TOKEN"):
        Settings()
    monkeypatch.setenv("BIOPLAN_API_TOKEN", "s3cret")
    s = Settings()
    assert s.host == "0.0.0.0" and s.token == "s3cret"
    assert "s3cret" not in repr(s)  # a secret, never printed


def test_a_viewer_on_every_interface_needs_a_token(monkeypatch: pytest.MonkeyPatch) -> None:
    """The viewer streams plans' poses: ``BIOPLAN_VIEWER_HOST=0.0.0.0`` alone was accepted."""
    monkeypatch.delenv("BIOPLAN_HOST", raising=False)
    monkeypatch.delenv("BIOPLAN_API_TOKEN", raising=False)
    monkeypatch.setenv("BIOPLAN_VIEWER_HOST", "0.0.0.0")
    with pytest.raises(ValidationError, match="BIOPLAN_VIEWER_HOST"):
        Settings()
    monkeypatch.setenv("BIOPLAN_API_TOKEN", "s3cret")
    assert Settings().viewer_host == "0.0.0.0"


def test_settings_defaults_and_parsing(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("BIOPLAN_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("BIOPLAN_CORS_ORIGINS", "http://a.example, http://b.example")
    monkeypatch.setenv("BIOPLAN_EXECUTOR", "dask://10.0.0.2:8786")
    s = Settings()
    assert s.host == "127.0.0.1" and s.max_upload_mb == 200 and s.max_workers >= 1
    assert s.db_url == f"sqlite:///{tmp_path.resolve() / 'bioplan.db'}"
    assert s.cors_origins == ["http://a.example", "http://b.example"]
    assert s.dask_address == "tcp://10.0.0.2:8786"
    monkeypatch.setenv("BIOPLAN_EXECUTOR", "threads")
    with pytest.raises(ValidationError, match="dask://HOST:PORT"):
        Settings()


def test_writes_need_the_token(tmp_path: Path) -> None:
    with make_client(tmp_path, api_token="s3cret") as c:
        body = {"recording_id": 1}
        r = c.post("/api/analyses", json=body)
        assert_problem(r, 401)
        assert r.headers["www-authenticate"] == "Bearer"
        assert_problem(
            c.post("/api/analyses", json=body, headers={"Authorization": "Bearer x"}), 401
        )
        assert_problem(c.delete("/api/recordings/1"), 401)
        assert_problem(c.post("/api/jobs/1/cancel"), 401)
        ok = c.post("/api/analyses", json=body, headers={"Authorization": "Bearer s3cret"})
        assert ok.status_code == 404  # past the token check: recording 1 does not exist
        assert c.get("/api/recordings").status_code == 200  # reads stay open
        assert c.get("/api/health").json()["status"] == "ok"


def test_cors_closed_by_default_open_when_configured(tmp_path: Path) -> None:
    pre = {"Origin": "http://evil.example", "Access-Control-Request-Method": "POST"}
    with make_client(tmp_path / "a") as c:
        r = c.options("/api/recordings", headers=pre)
        assert "access-control-allow-origin" not in r.headers
        r = c.get("/api/recordings", headers={"Origin": "http://evil.example"})
        assert "access-control-allow-origin" not in r.headers
    with make_client(tmp_path / "b", cors_origins=["http://lab.example"]) as c:
        ok = {**pre, "Origin": "http://lab.example"}
        r = c.options("/api/recordings", headers=ok)
        assert r.headers["access-control-allow-origin"] == "http://lab.example"
        r = c.options("/api/recordings", headers=pre)
        assert "access-control-allow-origin" not in r.headers


def test_a_foreign_host_name_is_refused_dns_rebinding(tmp_path: Path) -> None:
    """Issue 14 item 3: ``Host: attacker.example`` read raw uploaded files (DNS rebinding)."""
    with make_client(tmp_path / "a") as c:
        r = c.get("/api/recordings", headers={"Host": "attacker.example"})
        assert "BIOPLAN_ALLOWED_HOSTS" in assert_problem(r, 421)["detail"]
        assert c.get("/", headers={"Host": "attacker.example:8000"}).status_code == 421
        for name in ("127.0.0.1:8000", "localhost:8000", "[::1]:8000", "127.0.0.2"):
            assert c.get("/api/recordings", headers={"Host": name}).status_code == 200, name
    with make_client(tmp_path / "b", allowed_hosts="lab.example") as c:
        assert c.get("/api/recordings", headers={"Host": "lab.example"}).status_code == 200
        assert c.get("/api/recordings", headers={"Host": "evil.example"}).status_code == 421


def test_cross_site_writes_are_refused_with_or_without_a_token(tmp_path: Path) -> None:
    """Issue 14 item 3: a ``text/plain`` POST from any site cancelled a job (no preflight)."""
    evil = {"Origin": "http://evil.example", "Content-Type": "text/plain"}
    with make_client(tmp_path / "a") as c:
        assert_problem(c.post("/api/jobs/1/cancel", headers=evil), 403)
        fetch = {"Sec-Fetch-Site": "cross-site"}
        assert_problem(c.post("/api/jobs/1/cancel", headers=fetch), 403)
        other_port = {"Origin": "http://127.0.0.1:9999"}  # another site on this machine
        assert_problem(c.post("/api/jobs/1/cancel", headers=other_port), 403)
        assert_problem(c.delete("/api/recordings/1", headers={"Origin": "null"}), 403)
        same = {"Origin": "http://127.0.0.1", "Sec-Fetch-Site": "same-origin"}
        assert_problem(c.post("/api/jobs/1/cancel", headers=same), 404)  # past the perimeter
        assert_problem(c.post("/api/jobs/1/cancel"), 404)  # no Origin: not from a browser
        assert c.get("/api/recordings", headers=evil).status_code == 200  # reads: CORS decides
    with make_client(tmp_path / "b", api_token="s3cret") as c:
        auth = {"Authorization": "Bearer s3cret"}
        assert_problem(c.post("/api/jobs/1/cancel", headers={**evil, **auth}), 403)
    with make_client(tmp_path / "c", cors_origins="http://lab.example") as c:
        lab = {"Origin": "http://lab.example"}
        assert_problem(c.post("/api/jobs/1/cancel", headers=lab), 404)  # a configured origin


def test_the_token_is_checked_before_the_body_is_read(tmp_path: Path) -> None:
    """Issue 14 item 4: 150 MB were spooled before the 401; bad JSON got 422, not 401."""
    import asyncio

    from app.api.middleware import PerimeterMiddleware

    reached: list[str] = []

    async def app(scope: object, receive: object, send: object) -> None:
        reached.append("app")

    async def receive() -> dict[str, object]:
        raise AssertionError("the body was read before the token was checked")

    sent: list[dict[str, object]] = []

    async def send(message: dict[str, object]) -> None:
        sent.append(message)

    settings = Settings(data_dir=tmp_path, api_token="s3cret")
    middleware = PerimeterMiddleware(app, settings)  # type: ignore[arg-type]
    scope = {
        "type": "http",
        "method": "POST",
        "path": "/api/recordings",
        "headers": [(b"host", b"127.0.0.1:8000"), (b"content-length", b"157286400")],
    }
    asyncio.run(middleware(scope, receive, send))  # type: ignore[arg-type]
    assert reached == [] and sent[0]["status"] == 401
    with make_client(tmp_path / "c", api_token="s3cret") as c:
        r = c.post("/api/plans", content=b"{not json", headers={"Content-Type": "application/json"})
        assert_problem(r, 401)


def test_reads_can_require_the_token(tmp_path: Path) -> None:
    """Issue 14 item 6: with a token set, raw files, subjects and notes stayed readable."""
    with make_client(tmp_path / "a", api_token="s3cret", protect_reads=True) as c:
        assert "reads" in assert_problem(c.get("/api/recordings"), 401)["detail"]
        assert_problem(c.get("/api/recordings/1/files/1"), 401)
        assert c.get("/api/health").status_code == 200 and c.get("/api/meta").status_code == 200
        assert c.get("/").status_code == 200  # the page itself holds no data
        ok = c.get("/api/recordings", headers={"Authorization": "Bearer s3cret"})
        assert ok.status_code == 200
    with make_client(tmp_path / "b", api_token="s3cret") as c:
        assert c.get("/api/recordings").status_code == 200  # the default: reads open


def test_work_per_request_is_capped_by_configuration(tmp_path: Path) -> None:
    """Issue 14 item 8: ``particles 1000, iterations 10000, n_samples 100000`` asked for
    8.94 GiB, and ``workers: 64`` started 65 processes past ``BIOPLAN_MAX_WORKERS``."""
    with make_client(tmp_path, max_particles=50, max_iterations=150, max_samples=300) as c:
        plan = {"robot": "human_arm_2dof", "methods": ["quintic", "paper"]}
        for field, value, env in (
            ("particles", 51, "BIOPLAN_MAX_PARTICLES"),
            ("iterations", 151, "BIOPLAN_MAX_ITERATIONS"),
            ("n_samples", 301, "BIOPLAN_MAX_SAMPLES"),
        ):
            r = c.post("/api/plans", json={**plan, field: value})
            detail = assert_problem(r, 422, field=field)["detail"]
            assert detail == f"{field} {value} exceeds the limit {value - 1} ({env})"
        sweep = {"robot": "human_arm_2dof", "durations": [1.0], "payloads": [0.0], "workers": 3}
        r = c.post("/api/sweeps", json=sweep)  # the test service runs 2 workers
        assert "BIOPLAN_MAX_WORKERS" in assert_problem(r, 422, field="workers")["detail"]
        assert c.get("/api/jobs").json()["total"] == 0  # nothing queued
        ok = c.post("/api/plans", json={**plan, "particles": 50, "iterations": 2})
        assert ok.status_code == 202, ok.text


def test_a_file_name_with_control_characters_is_refused(tmp_path: Path) -> None:
    """Issue 14 item 14: a name with a NUL byte was stored and its download dropped the
    connection. The multipart body is written by hand: httpx would escape the byte."""
    boundary = "bioplanboundary"
    body = (
        f"--{boundary}\r\n"
        'Content-Disposition: form-data; name="files"; filename="a\x00b.csv"\r\n'
        "Content-Type: text/csv\r\n\r\n"
        "t,x\r\n0,1\r\n0.1,2\r\n0.2,3\r\n"
        f"\r\n--{boundary}--\r\n"
    ).encode()
    headers = {"Content-Type": f"multipart/form-data; boundary={boundary}"}
    with make_client(tmp_path) as c:
        r = c.post("/api/recordings", content=body, headers=headers)
        problem = assert_problem(r, 422, field="files")
        assert "control characters" in problem["detail"] and "\\x00" in problem["detail"]
        assert c.get("/api/recordings").json()["total"] == 0
        named = f'--{boundary}\r\nContent-Disposition: form-data; name="name"\r\n\r\nr1\r\n'
        robot = named.encode() + body.replace(b'name="files"', b'name="urdf"')
        r = c.post("/api/robots", content=robot, headers=headers)
        assert "control characters" in assert_problem(r, 422)["detail"]


def test_a_full_disk_is_507_and_health_reports_the_disk(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 14 item 10: uploads answered 500 on a full disk and health said "ok"."""
    import errno

    from app.db.blobs import BlobStore

    def full(self: BlobStore, data: bytes) -> str:
        raise OSError(errno.ENOSPC, "No space left on device")

    csv = b"t,EMG1\n" + b"".join(f"{i / 1000},{i % 7}\n".encode() for i in range(3000))
    with make_client(tmp_path / "a") as c:
        health = c.get("/api/health").json()
        assert health["status"] == "ok" and health["disk"]["ok"] and health["disk"]["free_mb"] > 0
        monkeypatch.setattr(BlobStore, "put", full)
        r = c.post("/api/recordings", files={"files": ("emg.csv", csv)}, data={"emg_rate": "1000"})
        assert "storage is full" in assert_problem(r, 507)["detail"]
        assert c.get("/api/recordings").json()["total"] == 0  # nothing half-stored
        monkeypatch.undo()

        def bug(self: BlobStore, data: bytes) -> str:
            raise FileNotFoundError("a bug, not a full disk")

        monkeypatch.setattr(BlobStore, "put", bug)
        r = c.post("/api/recordings", files={"files": ("emg.csv", csv)}, data={"emg_rate": "1000"})
        assert r.status_code == 500  # a bug stays a 500
    with make_client(tmp_path / "b", min_free_mb=1e15) as c:
        health = c.get("/api/health").json()
        assert health["status"] == "degraded" and health["disk"]["ok"] is False


def test_no_server_paths_or_library_locations_in_answers(tmp_path: Path) -> None:
    """Issue 14 item 6: errors showed server paths and versions. Bad files of every kind, bad
    robots and bad requests: no answer names the data directory, the installation or a
    temporary folder (a file is named as uploaded)."""
    bad_files = {
        "a.mat": b"MATLAB 5.0 MAT-file garbage" + b"\0" * 200,
        "b.c3d": b"\x02\x50" + b"\0" * 600,
        "c.h5": b"\x89HDF\r\n\x1a\n" + b"\0" * 100,
        "d.edf": b"0       " + b"x" * 300,
        "e.csv": b"a,b\n1,2\nx,y\n",
        "f.json": b"{not json",
        "h.mp4": b"\0\0\0\x18ftypmp42" + b"\0" * 100,
    }
    broken_urdf = b'<robot name="r"><link'
    mjcf = b'<mujoco><include file="nothere.xml"/></mujoco>'
    with make_client(tmp_path) as c:
        answers = [c.post("/api/recordings", files={"files": (n, b)}) for n, b in bad_files.items()]
        answers += [
            c.post("/api/robots", data={"name": "r1"}, files={"urdf": ("r.urdf", broken_urdf)}),
            c.post("/api/robots", data={"name": "r2"}, files={"mjcf": ("m.xml", mjcf)}),
            c.post("/api/plans", json={"robot": "nope"}),
            c.get("/api/recordings/1/files/1"),
            c.get("/api/plans/1/trajectory?format=csv"),
        ]
    server_places = (str(tmp_path), "site-packages", "/usr/lib", "/tmp/", ".venv", "Traceback")
    for r in answers:
        assert 400 <= r.status_code < 500, r.text
        leaks = [p for p in server_places if p in r.text]
        assert not leaks, (r.request.url, leaks, r.text)


def test_a_huge_json_field_is_refused_before_it_is_stored(tmp_path: Path) -> None:
    """Issue 14 item 11: five job templates with a 20 MiB ``source`` made ``GET /api/jobs``
    105 MB. A request that is not an upload is capped as a whole (BIOPLAN_MAX_JSON_KB), before
    anything is parsed or stored; uploads keep their own, larger limit."""
    template = {"source": "x" * (2 * 1024 * 1024), "peak_velocity_angle_deg": 62.0}
    with make_client(tmp_path) as c:
        r = c.post("/api/plans", json={"robot": "human_arm_2dof", "template": template})
        assert "BIOPLAN_MAX_JSON_KB" in assert_problem(r, 413)["detail"]
        assert c.get("/api/jobs").json()["total"] == 0
        csv = b"t,EMG1\n" + b"".join(f"{i / 1000},{i % 7}\n".encode() for i in range(120_000))
        assert len(csv) > 1024 * 1024  # far larger than the JSON limit, an upload all the same
        up = c.post("/api/recordings", files={"files": ("emg.csv", csv)}, data={"emg_rate": "1000"})
        assert up.status_code == 201, up.text
    with make_client(tmp_path / "small", max_json_kb=1) as c:
        r = c.post("/api/plans", json={"robot": "human_arm_2dof", "notes": "y" * 2000})
        assert "1024 bytes" in assert_problem(r, 413)["detail"]  # the configured limit


def _mat5_bomb(variables: int, inflated_mb: int) -> bytes:
    """A MAT v5 file of compressed variables that inflate to ``inflated_mb`` MB each: elements
    of zeros a reader skips (a few KB on disk; built in chunks, never held inflated here)."""
    import struct
    import zlib

    header = b"MATLAB 5.0 MAT-file, bomb".ljust(116, b" ") + b"\0" * 8 + b"\x00\x01IM"
    chunk = b"\0" * (1 << 20)
    out = [header]
    for _ in range(variables):
        z = zlib.compressobj()
        body = []
        for _ in range(inflated_mb):
            body += [z.compress(struct.pack("<II", 2, len(chunk))), z.compress(chunk)]  # miUINT8
        data = b"".join([*body, z.flush()])
        out.append(struct.pack("<II", 15, len(data)) + data)  # miCOMPRESSED
    return b"".join(out)


def test_decompression_bombs_are_refused_before_they_grow(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 14 item 7: a 5 KB MAT 7.3 took 4.8 GB and 53 s, a 5.6 MB MAT v5 6.6 GB and 155 s.
    The decoded size is capped per file, all datasets or variables together (each one alone
    under the old per-dataset limit): HDF5 by the declared shapes before anything is read, MAT
    v5 while inflating."""
    import h5py

    from app.recordings import _mat5
    from app.services import sandbox

    bomb = tmp_path / "bomb.mat"
    with h5py.File(bomb, "w") as f:
        for k in range(3):  # 3 x 240 MB declared, never written: a few KB on disk
            f.create_dataset(f"emg{k}", shape=(30_000_000,), dtype="f8", chunks=(1 << 16,),
                             compression="gzip")  # fmt: skip
    assert bomb.stat().st_size < 100_000
    monkeypatch.setattr(_mat5, "_MAX_INFLATED", 8 << 20)  # the same rule, a smaller test
    v5 = _mat5_bomb(variables=3, inflated_mb=5)  # each under 8 MB, 15 MB in all
    assert len(v5) < 100_000
    with make_client(tmp_path / "server") as c:
        # The readers' own caps, in this process (where the smaller cap above applies): the
        # sandbox around them is tested in test_parse_sandbox.py.
        monkeypatch.setattr(sandbox, "_active", None)
        r = c.post("/api/recordings", files={"files": ("bomb.mat", bomb.read_bytes())})
        problem = assert_problem(r, 422, file="bomb.mat")
        assert "512 MB in all" in problem["detail"] and "emg" in problem["detail"]
        r = c.post("/api/recordings", files={"files": ("v5.mat", v5)})
        assert "inflate beyond 8 MB in all" in assert_problem(r, 422, file="v5.mat")["detail"]
        assert c.get("/api/recordings").json()["total"] == 0
        assert c.get("/api/health").status_code == 200


def test_an_mjcf_replicate_bomb_is_refused_before_compiling(tmp_path: Path) -> None:
    """Issue 14 item 7: a 1.8 KB MJCF of nested ``<replicate>`` took 7.5 GB for 129 s."""
    nested = '<body><geom size=".01"/></body>'
    for _ in range(4):
        nested = f'<replicate count="12" offset="0 0 .01">{nested}</replicate>'
    model = f"<mujoco><worldbody>{nested}</worldbody></mujoco>".encode()
    assert len(model) < 1000
    with make_client(tmp_path) as c:
        r = c.post("/api/robots", data={"name": "bomb"}, files={"mjcf": ("bomb.xml", model)})
        problem = assert_problem(r, 422)
        assert "replicate" in problem["detail"] and "at most 1000" in problem["detail"]


@pytest.mark.parametrize("slots", [1, 2])
def test_uploads_are_parsed_a_bounded_number_at_a_time(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, slots: int
) -> None:
    """Issue 14 item 11: 64 concurrent 50 MB uploads pushed the list route to p99 17.9 s.
    Uploads queue for BIOPLAN_MAX_PARALLEL_PARSES parse slots; reads are not held up."""
    import threading
    import time

    from app.api.routes import recordings as route

    active, peak, lock = [0], [0], threading.Lock()
    real = route.store_recording

    def slow(**kwargs: object) -> object:
        with lock:
            active[0] += 1
            peak[0] = max(peak[0], active[0])
        time.sleep(0.5)  # a parse that takes a while
        with lock:
            active[0] -= 1
        return real(**kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(route, "store_recording", slow)
    csv = b"t,EMG1\n" + b"".join(f"{i / 1000},{i % 7}\n".encode() for i in range(3000))
    with make_client(tmp_path, max_parallel_parses=slots) as c:
        codes: list[int] = []

        def upload(k: int) -> None:
            files = {"files": (f"e{k}.csv", csv.replace(b",6\n", f",{k % 5}\n".encode(), 1))}
            codes.append(
                c.post("/api/recordings", files=files, data={"emg_rate": "1000"}).status_code
            )

        threads = [threading.Thread(target=upload, args=(k,)) for k in range(4)]
        for t in threads:
            t.start()
        time.sleep(0.2)
        listed = c.get("/api/recordings")  # a read while uploads wait: answered
        for t in threads:
            t.join(120)
        assert listed.status_code == 200
        assert codes == [201] * 4
    assert peak[0] == slots  # never more at once, and the slots are used
