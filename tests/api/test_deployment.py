"""The compose file and Dockerfile, kept correct by reading them (no Docker engine here)."""

from __future__ import annotations

import re

import yaml

from app.config import Settings
from tests.conftest import REPO_ROOT

COMPOSE = REPO_ROOT / "docker" / "compose.yaml"
DOCKERFILE = REPO_ROOT / "Dockerfile"


def test_compose_has_app_scheduler_two_workers_and_postgres() -> None:
    spec = yaml.safe_load(COMPOSE.read_text())
    services = spec["services"]
    assert set(services) == {"app", "scheduler", "worker-1", "worker-2", "db"}
    assert services["db"]["image"].startswith("postgres:")
    images = {name: s.get("image") for name, s in services.items() if name != "db"}
    assert set(images.values()) == {"bioplan:latest"}  # one image for the app and Dask
    sched = services["scheduler"]["command"]
    port = sched[sched.index("--port") + 1]
    for w in ("worker-1", "worker-2"):
        cmd = services[w]["command"]
        assert cmd[:3] == ["dask", "worker", f"tcp://scheduler:{port}"]
        assert cmd[cmd.index("--nthreads") + 1] == "1"
    env = services["app"]["environment"]
    assert env["BIOPLAN_EXECUTOR"] == f"dask://scheduler:{port}"
    assert env["BIOPLAN_DATABASE_URL"].startswith("postgresql+psycopg://bioplan:")
    assert env["BIOPLAN_DATABASE_URL"].endswith(
        "@db:5432/" + services["db"]["environment"]["POSTGRES_DB"]
    )
    # Every BIOPLAN_* variable is a real setting, and the values validate together.
    fields = {f"BIOPLAN_{name.upper()}" for name in Settings.model_fields}
    assert set(env) <= fields
    concrete = {k: re.sub(r"\$\{[^}]*\}", "x", str(v)) for k, v in env.items()}
    s = Settings(**{k.removeprefix("BIOPLAN_").lower(): v for k, v in concrete.items()})
    assert s.host == "0.0.0.0" and s.token  # non-loopback only with a token
    assert services["app"]["ports"] == ["127.0.0.1:8000:8000"]
    assert services["app"]["command"] == ["bioplan", "serve"]


def test_dockerfile_installs_the_code_with_its_migrations() -> None:
    text = DOCKERFILE.read_text()
    for needed in ("COPY migrations", "COPY alembic.ini", "COPY app", "psycopg", "USER bioplan"):
        assert needed in text, needed
    assert 'CMD ["bioplan", "serve"]' in text
    assert "EXPOSE 8000" in text
