"""Browser tests: a real ``bioplan serve --demo`` and Debian's Chromium via Playwright.

Chromium runs headless with WebGL through SwiftShader (``tests/utils/browser.py``). Screenshots
go to ``artifacts/screenshots/`` (git-ignored; CI keeps them). The tests skip, saying why, when
``/usr/bin/chromium`` is missing (``make test`` installs it).
"""

from __future__ import annotations

from collections.abc import Iterator
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


@pytest.fixture(scope="session")
def live_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    if not CHROMIUM.is_file():
        pytest.skip(f"Chromium not found at {CHROMIUM} (make test installs Debian's chromium)")
    server = Server(tmp_path_factory.mktemp("live") / "data", demo=True, viewer=True, **_pose_env())
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
