"""Browser tests: a real ``bioplan serve --demo`` and Debian's Chromium via Playwright.

The demo is seeded once per test run (a real ``serve --demo`` on a template folder, stopped once
it answers); each xdist worker's server starts on its own copy, where ``--demo`` finds the
recordings and seeds nothing (seeding plans and simulates the 6-DOF arm: about a minute each).

Chromium runs headless with WebGL through SwiftShader (``tests/utils/browser.py``). Screenshots
go to ``artifacts/screenshots/`` (git-ignored; CI keeps them). The tests skip, saying why, when
``/usr/bin/chromium`` is missing (``make test`` installs it).
"""

from __future__ import annotations

import fcntl
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.utils.browser import CHROMIUM, CHROMIUM_ARGS, new_context, offline_guard
from tests.utils.server import Server


def _pose_env() -> dict[str, str]:
    """The pose environment this test process finds (./.venv-pose from the repository), named
    for the server, which runs in another folder."""
    from app.errors import BioPlanError
    from app.recordings import find_pose_python

    try:
        return {"BIOPLAN_POSE_PYTHON": str(find_pose_python())}
    except BioPlanError:
        return {}


def _seeded_demo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The data folder of a seeded demo, made by the first worker of this run to ask (the
    others wait on a lock, then reuse it). Under xdist the run's base folder is the workers'
    common parent; without it, this process's own."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent
    template = base / "demo-seeded" / "data"
    with (base / "demo-seeded.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if not (template.parent / "complete").is_file():
            shutil.rmtree(template.parent, ignore_errors=True)
            seeding = Server(template, demo=True, **_pose_env())
            try:
                seeding.start(timeout=600)
            finally:
                seeding.stop()
            (template.parent / "complete").touch()
    return template


@pytest.fixture(scope="session")
def live_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    if not CHROMIUM.is_file():
        pytest.skip(f"Chromium not found at {CHROMIUM} (make test installs Debian's chromium)")
    data = tmp_path_factory.mktemp("live") / "data"
    shutil.copytree(_seeded_demo(tmp_path_factory), data, ignore=shutil.ignore_patterns("*.lock"))
    server = Server(data, demo=True, viewer=True, **_pose_env())
    try:
        server.start(timeout=600)
        yield server
    finally:
        server.stop()


@pytest.fixture(scope="session")
def chromium() -> Iterator[Any]:
    """Debian's Chromium through Playwright, once per test run: Playwright's sync API cannot
    be started twice in one process (a second start fails inside the first's event loop)."""
    if not CHROMIUM.is_file():
        pytest.skip(f"Chromium not found at {CHROMIUM} (make test installs Debian's chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        instance = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            yield instance
        finally:
            instance.close()


@pytest.fixture(scope="session")
def browser(live_server: Server, chromium: Any) -> Any:
    """The browser for pages of the live demo server."""
    return chromium


@pytest.fixture
def page(browser: Any) -> Iterator[Any]:
    context = new_context(browser, viewport={"width": 1280, "height": 800})
    outside = offline_guard(context)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        yield page
    finally:
        context.close()
    assert not errors, f"JavaScript errors on the page: {errors}"
    assert not outside, f"the page asked for resources off this machine: {outside}"
