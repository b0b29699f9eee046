"""Debian's Chromium under Playwright: launch options, an offline guard, screenshots."""

from __future__ import annotations

import os
import urllib.parse
from pathlib import Path
from typing import Any

from tests.utils.data import REPO_ROOT

CHROMIUM = Path(os.environ.get("BIOPLAN_CHROMIUM", "/usr/bin/chromium"))
SCREENSHOTS = REPO_ROOT / "artifacts" / "screenshots"
#: Headless Chromium with WebGL through SwiftShader (no GPU), nothing fetched from outside.
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--use-gl=angle",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


def offline_guard(context: Any) -> list[str]:
    """Abort and record every request that leaves loopback (the dashboard works offline)."""
    outside: list[str] = []

    def handle(route: Any) -> None:
        host = urllib.parse.urlsplit(route.request.url).hostname or ""
        if route.request.url.startswith(("data:", "blob:")) or host in ("127.0.0.1", "localhost"):
            route.continue_()
        else:
            outside.append(route.request.url)
            route.abort()

    context.route("**/*", handle)
    return outside


def screenshot(page: Any, name: str, *, full_page: bool = True, timeout: float = 120_000) -> Path:
    """Save a screenshot to ``artifacts/screenshots/`` (generous timeout: software WebGL)."""
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    path = SCREENSHOTS / f"{name}.png"
    page.screenshot(path=str(path), full_page=full_page, timeout=timeout)
    return path


#: Playwright's default wait for any one step [ms]: generous, software WebGL on a busy machine.
STEP_TIMEOUT_MS = 120_000


def new_context(browser: Any, **options: Any) -> Any:
    """A browser context whose every wait (selectors, navigation, screenshots) is generous."""
    context = browser.new_context(**options)
    context.set_default_timeout(STEP_TIMEOUT_MS)
    context.set_default_navigation_timeout(STEP_TIMEOUT_MS)
    return context
