"""A newcomer's first hour (issue 24): the set-up, the lock files, one-line errors, the pose
environment being optional for `make run`, `bioplan samples`, offline API docs, Docker."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from app.cli import samples as samples_cli
from app.cli._common import EXIT_BAD_INPUT
from tests.utils.data import REPO_ROOT, SHARED_DATA

LOCK = REPO_ROOT / "requirements" / "lock.txt"
POSE_LOCK = REPO_ROOT / "requirements" / "pose.txt"
PERMISSIVE = {"BSD-3-Clause", "MIT", "Apache-2.0", "CC0-1.0"}


def _cli(*args: str, **kw: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        **kw,  # type: ignore[call-overload]
    )


def _pins(path: Path) -> dict[str, list[str]]:
    """{name: [version, ...]} of a compiled requirements file (one per marker branch)."""
    pins: dict[str, list[str]] = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        m = re.match(r"^([A-Za-z0-9_.\-]+)==([^\s;]+)", line)
        if m:
            pins.setdefault(canonicalize_name(m.group(1)), []).append(m.group(2))
    return pins


# ---- reproducible installs -------------------------------------------------------------------


def test_the_lock_pins_every_dependency_within_pyproject() -> None:
    """requirements/lock.txt is current: every requirement of pyproject.toml (all extras) is
    pinned there, at a version the requirement allows (`make lock` after changing them)."""
    project = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]
    wanted = [*project["dependencies"]]
    for extra in project["optional-dependencies"].values():
        wanted += extra
    pins = _pins(LOCK)
    for text in wanted:
        req = Requirement(text)
        name = canonicalize_name(req.name)
        assert name in pins, f"{name} is not in {LOCK.name}: run `make lock`"
        assert any(req.specifier.contains(v, prereleases=True) for v in pins[name]), (
            f"{LOCK.name} pins {name}=={pins[name]}, outside {req.specifier}: run `make lock`"
        )


def test_the_pose_lock_pins_mediapipe_and_numpy_below_2() -> None:
    from app.recordings.video import MEDIAPIPE, POSE_REQUIREMENTS

    pins = _pins(POSE_LOCK)
    assert pins["mediapipe"] == [MEDIAPIPE.split("==")[1]]
    assert all(int(v.split(".")[0]) < 2 for v in pins["numpy"])
    for text in POSE_REQUIREMENTS:
        assert canonicalize_name(Requirement(text).name) in pins, text


def test_every_install_uses_the_lock_and_uv_stays_in_the_project() -> None:
    install = (REPO_ROOT / "scripts" / "install.sh").read_text()
    assert install.count('-c "$lock"') == 2  # uv and the pip fallback
    uv = (REPO_ROOT / "scripts" / "uv.sh").read_text()
    assert "--user" not in install + uv and ".tools/uv" in uv
    makefile = (REPO_ROOT / "Makefile").read_text()
    assert "$(STAMP): pyproject.toml $(LOCK)" in makefile
    assert "UV_CONSTRAINT=" in makefile and "scripts/uv.sh" in makefile
    assert re.search(r"^lock:\n\t@scripts/lock\.sh$", makefile, re.M)
    dockerfile = (REPO_ROOT / "Dockerfile").read_text()
    assert "pip install -c /tmp/requirements/lock.txt" in dockerfile


# ---- one-line errors -------------------------------------------------------------------------


def test_ruckig_refusals_are_one_line_errors() -> None:
    """ruckig answers -101 for a duration beyond its numerical limits, which its Python enum
    lacks ("-101 is not a valid Result"): it is a JerkLimitedError, not a crash."""
    from app.errors import BioPlanError
    from app.planning import load_robot
    from app.planning.jerk_limited import jerk_limited
    from app.planning.planner import PlanTask

    robot = load_robot("curtain_wall_6dof")
    task = PlanTask.default(robot)
    with pytest.raises(BioPlanError, match=r"in 10000 s \(a duration beyond") as info:
        jerk_limited(robot, task.start, task.goal, 1e4)
    assert "\n" not in str(info.value)


def test_an_out_file_that_cannot_be_written_is_one_line(tmp_path: Path) -> None:
    target = tmp_path / "no-such-folder" / "plan.json"
    done = _cli("plan", "--robot", "human_arm_2dof", "--method", "quintic", "--out", str(target))
    assert done.returncode == EXIT_BAD_INPUT
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and f"--out {target}: cannot write it" in lines[0], done.stderr


# ---- the pose environment is optional for `make run` ---------------------------------------


@pytest.fixture
def python_313(tmp_path: Path) -> Path:
    """A stand-in for a CPython 3.13 (MediaPipe 0.10.21 has no wheel for it)."""
    fake = tmp_path / "python3.13"
    fake.write_text('#!/bin/sh\necho "cpython 3 13"\n')
    fake.chmod(0o755)
    return fake


def test_pose_env_on_a_python_without_mediapipe_is_one_line(
    python_313: Path, tmp_path: Path
) -> None:
    done = _cli("pose-env", str(tmp_path / "env"), "--python", str(python_313))
    assert done.returncode == EXIT_BAD_INPUT
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert "CPython 3.9-3.12" in lines[0] and "3.13" in lines[0] and "--python" in lines[0]
    assert not (tmp_path / "env").exists()


def test_make_run_goes_on_without_the_pose_environment(python_313: Path, tmp_path: Path) -> None:
    """The step `make run` takes before serving reports the failure and exits 0."""
    if shutil.which("make") is None or not (REPO_ROOT / ".venv" / ".installed").is_file():
        pytest.skip("needs make and the checkout's .venv (made by `make`)")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("MAKE", "MFLAGS"))}
    done = subprocess.run(
        [
            "make",
            "--no-print-directory",
            "-o",
            ".venv/.installed",
            "pose-env-or-warn",
            f"PYTHON={python_313}",
            f"POSE_ENV={tmp_path / 'env'}",
        ],
        cwd=REPO_ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "CPython 3.9-3.12" in done.stderr
    assert "continuing without the pose environment" in done.stdout
    assert not (tmp_path / "env" / ".installed").exists()


# ---- bioplan samples -------------------------------------------------------------------------


def test_samples_are_permissive_pinned_and_public() -> None:
    paths = [s.path for s in samples_cli.SAMPLES]
    assert len(paths) == len(set(paths))
    for sample in samples_cli.SAMPLES:
        assert sample.license in PERMISSIVE, sample.path
        assert re.fullmatch(r"[0-9a-f]{64}", sample.sha256) and sample.size > 0
        assert sample.url.startswith("https://raw.githubusercontent.com/")
    assert not any(p.startswith("c3d_bts_gait_emg/") for p in paths)  # GPL-3.0


def test_samples_from_a_folder_are_copied_and_checked(tmp_path: Path) -> None:
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real test data not found at {SHARED_DATA} (set BIOPLAN_SHARED_DATA)")
    dest = tmp_path / "samples"
    done = _cli("samples", "--from", str(SHARED_DATA), "--dest", str(dest))
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == str(dest)
    for sample in samples_cli.SAMPLES:
        assert (dest / sample.path).stat().st_size == sample.size
    again = _cli("samples", "--from", str(SHARED_DATA), "--dest", str(dest), "--json")
    assert '"cached"' in again.stdout and '"copied"' not in again.stdout


def test_a_sample_that_does_not_match_its_checksum_is_refused(tmp_path: Path) -> None:
    sample = samples_cli.SAMPLES[0]
    source = tmp_path / "source"
    (source / sample.path).parent.mkdir(parents=True)
    (source / sample.path).write_bytes(b"not the file")
    dest = tmp_path / "dest"
    done = _cli("samples", "--from", str(source), "--dest", str(dest))
    assert done.returncode == EXIT_BAD_INPUT
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "does not match its pinned checksum" in lines[0], done.stderr
    assert not [p for p in dest.rglob("*") if p.is_file()]  # nothing half-written kept


def test_samples_without_network_or_folder_is_one_line(tmp_path: Path) -> None:
    """Downloading from an address that cannot answer: a one-line error naming --from."""
    env = {k: v for k, v in os.environ.items() if k != samples_cli.SAMPLES_FROM_ENV}
    env.update(https_proxy="http://127.0.0.1:9", HTTPS_PROXY="http://127.0.0.1:9")
    done = _cli("samples", "--dest", str(tmp_path / "d"), env=env)
    assert done.returncode == EXIT_BAD_INPUT
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "--from DIR" in lines[0], done.stderr


# ---- /docs and /redoc offline ----------------------------------------------------------------


def test_api_docs_load_nothing_from_outside_the_server(tmp_path: Path) -> None:
    from tests.utils.api import make_client

    with make_client(tmp_path) as client:
        for page in ("/docs", "/redoc"):
            r = client.get(page)
            assert r.status_code == 200
            urls = re.findall(r"""(?:src|href|url)\s*[=:]\s*['"]([^'"]+)['"]""", r.text)
            assert urls, page
            outside = [u for u in urls if re.match(r"(?i)(https?:)?//", u)]
            assert not outside, f"{page} loads from outside the server: {outside}"
            for url in urls:
                assert client.get(url).status_code == 200, url
            assert not re.search(r"https?://(?!127\.0\.0\.1)", r.text), page
        assert '"validatorUrl": null' in client.get("/docs").text  # no badge from swagger.io


# ---- Docker ----------------------------------------------------------------------------------


def test_the_image_exposes_the_viewer_and_has_the_video_environment() -> None:
    dockerfile = (REPO_ROOT / "Dockerfile").read_text()
    assert re.search(r"^EXPOSE 8000 8080$", dockerfile, re.M)
    assert "bioplan pose-env /opt/pose-env" in dockerfile
    assert "PIP_CONSTRAINT=/tmp/requirements/pose.txt" in dockerfile
    assert "ENV BIOPLAN_POSE_PYTHON=/opt/pose-env/bin/python" in dockerfile


# ---- benchmarks/RESULTS.md -------------------------------------------------------------------


def test_results_quote_no_test_count() -> None:
    """A count of tests goes stale with the next test added; the results do not quote one."""
    text = (REPO_ROOT / "benchmarks" / "RESULTS.md").read_text(encoding="utf-8")
    assert not re.search(r"\d+\s+passed", text)
