"""The Compare card states the plan's collision and workspace check (issue 27, item 1)."""

from __future__ import annotations

from typing import Any

from tests.frontend.test_browser import demo_ids
from tests.utils.server import Server


def test_the_card_shows_the_safety_check(live_server: Server, page: Any) -> None:
    plan = demo_ids(live_server)["plan"]
    result = live_server.get(f"/api/viewer/comparisons/plan/{plan}?points=10")["result"]
    safety = result["safety"]
    # The demo plans a built-in robot: checked with its collision primitives, clear.
    assert safety["checked"] is True and safety["ok"] is True and safety["findings"] == []
    page.goto(f"{live_server.url}/#/compare/plan/{plan}")
    page.wait_for_selector("#plan-safety")
    shown = page.inner_text("#plan-safety")
    clearance_mm = float(f"{1000 * safety['min_clearance']:.3g}")
    assert shown == f"ok, min clearance {clearance_mm:g} mm", shown
