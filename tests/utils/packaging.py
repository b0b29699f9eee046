"""Building the wheel the way an installer would, from exactly the files it is given."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from collections.abc import Iterable
from pathlib import Path

import pytest

from tests.utils.data import REPO_ROOT


def tracked_files() -> list[str]:
    """The repository's files as a fresh clone has them (tracked, plus new ones not ignored)."""
    if shutil.which("git") is None or not (REPO_ROOT / ".git").exists():
        pytest.skip("not a git checkout: the files a clone would have are unknown")
    out = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
        cwd=REPO_ROOT,
        capture_output=True,
        check=True,
    ).stdout.decode()
    return sorted(f for f in out.split("\0") if f and (REPO_ROOT / f).is_file())


def copy_tree(files: Iterable[str], target: Path) -> Path:
    """Copy repository files (relative paths) into ``target``."""
    for name in files:
        dest = target / name
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO_ROOT / name, dest)
    return target


def build_wheel(source: Path, out: Path) -> Path:
    """Build a wheel of ``source`` with setuptools (PEP 517 backend, no network)."""
    out.mkdir(parents=True, exist_ok=True)
    code = "import sys, setuptools.build_meta as b; print(b.build_wheel(sys.argv[1]))"
    done = subprocess.run(
        [sys.executable, "-c", code, str(out)],
        cwd=source,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "SetuptoolsDeprecationWarning" not in done.stderr, done.stderr
    return out / done.stdout.strip().splitlines()[-1]


def wheel_files(wheel: Path) -> set[str]:
    """The files a wheel installs (its metadata folder left out: it names the build)."""
    with zipfile.ZipFile(wheel) as z:
        return {n for n in z.namelist() if ".dist-info/" not in n}
