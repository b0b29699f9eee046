"""Installed from a wheel, away from the source checkout, ``bioplan serve`` serves its pages and
migrates its database from the package alone."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
import zipfile
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from app import __version__
from tests.utils.packaging import build_wheel, copy_tree, tracked_files, wheel_files
from tests.utils.server import free_port


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The wheel of a fresh clone's files (built without warnings)."""
    tmp = tmp_path_factory.mktemp("wheel")
    return build_wheel(copy_tree(tracked_files(), tmp / "src"), tmp / "dist")


@pytest.fixture(scope="module")
def installed(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A new virtual environment with the wheel installed (its dependencies are borrowed from
    this environment's site-packages through a ``.pth`` line, so nothing is downloaded; the
    ``.pth`` files there, this checkout's editable install among them, are not run)."""
    env = tmp_path_factory.mktemp("env") / "venv"
    base = getattr(sys, "_base_executable", sys.executable)
    subprocess.run([base, "-m", "venv", str(env)], check=True, timeout=300)
    python = env / "bin" / "python"
    pip = [str(python), "-m", "pip", "install", "--no-deps", "--no-index", "--quiet", str(wheel)]
    subprocess.run(pip, check=True, timeout=300)
    purelib = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True, text=True, check=True,
    ).stdout.strip()  # fmt: skip
    (Path(purelib) / "borrowed_dependencies.pth").write_text(
        sysconfig.get_paths()["purelib"] + "\n"
    )
    return env


def test_the_wheel_holds_the_pages_the_migrations_and_the_licence(wheel: Path) -> None:
    files = wheel_files(wheel)
    tracked = tracked_files()
    for name in tracked:
        if name.startswith(("app/frontend/", "app/db/migrations/")):
            assert name in files, name
    assert "app/frontend/index.html" in files and "app/db/migrations/env.py" in files
    assert "app/py.typed" in files  # PEP 561: the library's annotations reach its users
    with zipfile.ZipFile(wheel) as z:
        meta = next(n for n in z.namelist() if n.endswith(".dist-info/METADATA"))
        text = z.read(meta).decode()
        assert any(n.endswith(".dist-info/licenses/LICENSE") for n in z.namelist())
    assert "License-Expression: MIT" in text
    assert f"Version: {__version__}" in text
    assert "ezc3d" not in [  # a test dependency only: the app never imports it
        line.split()[1].split(">")[0]
        for line in text.splitlines()
        if line.startswith("Requires-Dist:") and "extra ==" not in line
    ]


def _head() -> str:
    from alembic.script import ScriptDirectory

    from app.db.session import alembic_config

    head = ScriptDirectory.from_config(alembic_config("sqlite://")).get_current_head()
    assert head is not None
    return head


@pytest.fixture
def served(installed: Path, tmp_path: Path) -> Iterator[dict[str, str]]:
    """``bioplan serve --json`` of the installed package, run from an unrelated folder."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BIOPLAN_", "PYTHON"))}
    env.update(BIOPLAN_VIEWER="0", BIOPLAN_LOG_LEVEL="warning", PATH="/usr/bin:/bin")
    proc = subprocess.Popen(
        [str(installed / "bin" / "bioplan"), "serve", "--json", "--port", str(free_port())],
        cwd=elsewhere,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line, proc.stderr.read() if proc.stderr else "no output"
        yield json.loads(line)
    finally:
        proc.terminate()
        proc.communicate(timeout=60)


def test_an_installed_wheel_serves_from_any_folder(installed: Path, served: dict[str, str]) -> None:
    where = subprocess.run(
        [str(installed / "bin" / "python"), "-c", "import app; print(app.__file__)"],
        cwd="/",
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    assert where.startswith(str(installed)), where  # the wheel's copy, not this checkout
    url = served["url"]
    index = httpx.get(url, timeout=30)
    assert index.status_code == 200
    assert '<script type="module" src="/js/app.js">' in index.text
    assert httpx.get(url + "js/app.js", timeout=30).status_code == 200
    version = httpx.get(url + "api/version", timeout=30).json()
    assert version["version"] == __version__
    assert version["database_revision"] == _head()  # migrated by the package's own scripts
    out = subprocess.run(
        [str(installed / "bin" / "bioplan"), "--version"], capture_output=True, text=True
    )
    assert out.stdout.strip() == f"bioplan {__version__}"
