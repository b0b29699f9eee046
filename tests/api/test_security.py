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
        assert ok.status_code == 422  # past the token check: recording 1 does not exist
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
