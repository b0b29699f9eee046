"""The README's and the docs' examples run as written, in order.

Every ```bash / ```python block in ``README.md`` and ``docs/*.md`` carries a marker on the line
before it (a new command cannot slip in untested)::

    <!-- readme-test: shell -->            run with bash, line by line, stopping at an error
    <!-- readme-test: python -->           run with this environment's Python
    <!-- readme-test: shell, server -->    the same, with ``bioplan serve`` answering at the
    <!-- readme-test: python, server -->   address the block names (127.0.0.1:8000 is replaced
                                           by the test server's, the only change made)
    <!-- readme-test: skip (why) -->       not run, for the reason given

The blocks run in one scratch folder laid out like a checkout: ``.venv`` is this environment,
``../shared/data`` the real recordings, and ``bioplan`` is on PATH (as after ``source
.venv/bin/activate``). ``bioplan samples`` copies the samples from ``../shared/data``
(``BIOPLAN_SAMPLES_FROM``) where a newcomer's downloads them. What they write stays in that folder.

This environment has the test extra too; the README promises the blocks run after ``make run``
alone, so every package they import (or look up by distribution name) must be one that
installing bioplan without extras brings (:func:`test_examples_need_nothing_from_the_test_extra`).
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, packages_distributions, requires
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from tests.utils.data import REPO_ROOT, SHARED_DATA
from tests.utils.server import Server

DOCS = [REPO_ROOT / "README.md", *sorted((REPO_ROOT / "docs").glob("*.md"))]
MARKER = re.compile(r"<!--\s*readme-test:\s*(?P<spec>[^>]*?)\s*-->\s*$")
FENCE = re.compile(r"^```(?P<lang>\w*)\s*$")
RUNNABLE = {"bash", "sh", "shell", "python", "py"}
#: Where the examples say the server is.
EXAMPLE_SERVER = "127.0.0.1:8000"


@dataclass(frozen=True)
class Block:
    """One fenced code block of a document and how it is run."""

    doc: Path
    line: int  # of the opening fence, 1-based
    lang: str
    code: str
    spec: str  # the marker's text, "" when there is none

    @property
    def id(self) -> str:
        return f"{self.doc.name}:{self.line}"

    @property
    def kind(self) -> str:
        return self.spec.split(",")[0].split("(")[0].strip()

    @property
    def needs_server(self) -> bool:
        return "server" in [p.strip() for p in self.spec.split(",")[1:]]


def blocks(doc: Path) -> list[Block]:
    """The fenced blocks of ``doc``, with the marker (if any) on the line before each."""
    lines = doc.read_text(encoding="utf-8").splitlines()
    out, i = [], 0
    while i < len(lines):
        fence = FENCE.match(lines[i])
        if fence is None:
            i += 1
            continue
        end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
        marker = MARKER.search(lines[i - 1]) if i else None
        spec = marker.group("spec") if marker else ""
        out.append(Block(doc, i + 1, fence.group("lang"), "\n".join(lines[i + 1 : end]), spec))
        i = end + 1
    return out


ALL = [b for doc in DOCS for b in blocks(doc)]
RUN = [b for b in ALL if b.kind in ("shell", "python")]


def test_every_command_block_says_how_it_is_tested() -> None:
    missing = [
        b.id for b in ALL if b.lang in RUNNABLE and b.kind not in ("shell", "python", "skip")
    ]
    assert not missing, f"blocks without a readme-test marker (run, or skip with why): {missing}"
    bad_skips = [b.id for b in ALL if b.kind == "skip" and "(" not in b.spec]
    assert not bad_skips, f"a skip needs its reason in parentheses: {bad_skips}"
    assert any(b.kind == "shell" for b in RUN) and any(b.kind == "python" for b in RUN)


def test_what_the_examples_write_is_ignored_by_git() -> None:
    """Run from a checkout, the examples write into out/ (and the server into data/): git
    ignores both, so nothing they write gets committed by accident."""
    for path in (
        "out/template.json",
        "out/figs/a.html",
        "out/report/index.html",
        "data/x.db",
        "samples/video_sports2d_demo/demo.mp4",
    ):
        done = subprocess.run(["git", "check-ignore", "-q", path], cwd=REPO_ROOT)
        assert done.returncode == 0, f"{path} is not ignored by git"


def _run_environment(root: str = "bioplan") -> set[str]:
    """The distributions installing ``root`` without extras brings (what ``make run`` makes),
    from the installed metadata: requirements followed transitively, markers evaluated here."""
    seen: set[tuple[str, str]] = set()
    todo = [(root, "")]
    while todo:
        name, extra = todo.pop()
        if (canonicalize_name(name), extra) in seen:
            continue
        seen.add((canonicalize_name(name), extra))
        try:
            texts = requires(name) or []
        except PackageNotFoundError:
            continue
        for text in texts:
            req = Requirement(text)
            if req.marker is None or req.marker.evaluate({"extra": extra}):
                todo += [(req.name, ""), *((req.name, e) for e in req.extras)]
    return {name for name, _ in seen}


def _used_distributions(block: Block) -> set[str]:
    """Distributions a block uses: its imports (Python blocks and ``python -c`` code) and the
    names it looks up with ``importlib.metadata.distribution``."""
    code = block.code
    snippets = [code] if block.kind == "python" else re.findall(r'python -c "([^"]*)"', code)
    modules: set[str] = set()
    for snippet in snippets:
        for node in ast.walk(ast.parse(snippet)):
            if isinstance(node, ast.Import):
                modules |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                modules.add(node.module.split(".")[0])
    owners = packages_distributions()
    used = {
        canonicalize_name(dist)
        for module in modules - set(sys.stdlib_module_names)
        for dist in owners.get(module, [module])
    }
    looked_up = re.findall(r"""\b(?:d|distribution)\(\s*['"]([^'"]+)['"]""", code)
    return used | {canonicalize_name(name) for name in looked_up}


def test_examples_need_nothing_from_the_test_extra() -> None:
    """`make run` installs bioplan without its test extra: an example that imports (or looks up)
    a package only the test extra brings would fail there, though it passes here."""
    run_env = _run_environment()
    assert "numpy" in run_env and "pytest" not in run_env
    missing = {b.id: sorted(_used_distributions(b) - run_env) for b in RUN}
    missing = {k: v for k, v in missing.items() if v}
    assert not missing, f"examples use packages `make run` does not install: {missing}"


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A scratch folder shaped like a checkout: .venv, and ../shared/data beside it."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real test data not found at {SHARED_DATA} (set BIOPLAN_SHARED_DATA)")
    root = tmp_path_factory.mktemp("readme")
    (root / "shared").mkdir()
    (root / "shared" / "data").symlink_to(SHARED_DATA, target_is_directory=True)
    work = root / "checkout"
    work.mkdir()
    (work / ".venv").symlink_to(Path(sys.prefix), target_is_directory=True)
    # What a checkout has beside its code that the examples use: the docs' example files and
    # the pose environment `make` creates (found as ./.venv-pose, as in a checkout).
    (work / "docs").symlink_to(REPO_ROOT / "docs", target_is_directory=True)
    pose_env = REPO_ROOT / ".venv-pose"
    if pose_env.is_dir():
        (work / ".venv-pose").symlink_to(pose_env, target_is_directory=True)
    return work


@pytest.fixture(scope="module")
def server(workdir: Path) -> Iterator[Server]:
    """A real server for the blocks that talk to one (started on first use)."""
    s = Server(workdir.parent / "server" / "data").start()
    yield s
    s.stop()


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("BIOPLAN_")}
    env["PATH"] = f"{Path(sys.prefix) / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["BIOPLAN_SHARED_DATA"] = str(SHARED_DATA)
    env["BIOPLAN_SAMPLES_FROM"] = str(SHARED_DATA)  # `bioplan samples` copies, checked
    return env


@pytest.mark.slow
@pytest.mark.parametrize("block", RUN, ids=[b.id for b in RUN])
def test_example_runs_as_written(
    block: Block, workdir: Path, request: pytest.FixtureRequest
) -> None:
    code = block.code
    if block.needs_server:
        server: Server = request.getfixturevalue("server")
        assert EXAMPLE_SERVER in code, f"{block.id}: a server block names {EXAMPLE_SERVER}"
        code = code.replace(EXAMPLE_SERVER, server.url.removeprefix("http://"))
    if block.kind == "shell":
        cmd = ["bash", "-euo", "pipefail", "-c", code]
    else:
        cmd = [sys.executable, "-c", code]
    done = subprocess.run(cmd, cwd=workdir, env=_env(), capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, (
        f"{block.id} failed (exit {done.returncode}):\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}"
    )
