"""The compose file and Dockerfile, kept correct by reading them (no Docker engine here)."""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from app.config import Settings
from tests.utils.data import REPO_ROOT
from tests.utils.packaging import build_wheel, copy_tree, tracked_files, wheel_files

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
    # The API and the 3-D viewer, each on the host's loopback only; the viewer binds in the
    # container where it can be reached (the token covers it as the API).
    assert services["app"]["ports"] == ["127.0.0.1:8000:8000", "127.0.0.1:8080:8080"]
    assert s.viewer_host == "0.0.0.0" and s.viewer_port == 8080
    assert services["app"]["command"] == ["bioplan", "serve"]


def _stages() -> dict[str, list[str]]:
    """Dockerfile instructions per stage (continuation lines joined), by stage name."""
    text = re.sub(r"\\\n\s*", " ", DOCKERFILE.read_text())
    stages: dict[str, list[str]] = {}
    current = ""
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("FROM "):
            parts = line.split()
            current = parts[3] if len(parts) > 3 and parts[2].upper() == "AS" else "image"
            stages[current] = []
        stages[current].append(line)
    return stages


def _copy_sources(lines: list[str]) -> list[str]:
    sources = []
    for line in lines:
        if line.startswith("COPY ") and "--from=" not in line:
            sources += line.split()[1:-1]
    return sources


def test_the_image_installs_the_wheel_built_from_what_it_copies(tmp_path: Path) -> None:
    """The image's application files are the wheel's: its first stage builds the wheel from the
    files it copies, and that wheel equals the one built from the repository."""
    stages = _stages()
    assert set(stages) == {"wheel", "image"}
    build = stages["wheel"]
    assert any("pip wheel --no-deps --wheel-dir /wheels ." in line for line in build)
    sources = _copy_sources(build)
    tracked = tracked_files()
    copied = [
        f for f in tracked if any(f == s or f.startswith(s.rstrip("/") + "/") for s in sources)
    ]
    from_docker = build_wheel(copy_tree(copied, tmp_path / "docker"), tmp_path / "d")
    from_repo = build_wheel(copy_tree(tracked, tmp_path / "repo"), tmp_path / "r")
    assert wheel_files(from_docker) == wheel_files(from_repo)
    # The image takes nothing else from the build context but the dependency list and its pins.
    image = stages["image"]
    assert _copy_sources(image) == [
        "pyproject.toml",
        "requirements/lock.txt",
        "requirements/pose.txt",
    ]
    assert "COPY --from=wheel /wheels /wheels" in image
    assert any("pip install --no-deps /wheels/*.whl" in line for line in image)
    for needed in ("psycopg", "USER bioplan", "EXPOSE 8000 8080", 'CMD ["bioplan", "serve"]'):
        assert any(needed in line for line in image), needed
    ignored = (REPO_ROOT / ".dockerignore").read_text().split()
    for name in (".venv", "data", ".git"):
        assert name in ignored, name
