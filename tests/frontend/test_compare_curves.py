"""The Compare page draws the per-joint power and cumulative energy the API serves (it computes
neither), and prints the floors' formulas ``/api/meta`` sends (real browser)."""

from __future__ import annotations

from typing import Any

import numpy as np

from tests.frontend.test_browser import demo_ids
from tests.utils.server import Server


def test_power_and_energy_plots_are_the_served_curves(live_server: Server, page: Any) -> None:
    sim = demo_ids(live_server)["simulation"]
    page.goto(f"{live_server.url}/#/compare/simulation/{sim}")
    page.wait_for_selector("#plot-energy .main-svg", timeout=180_000)
    view = live_server.get(f"/api/viewer/comparisons/simulation/{sim}?points=400")
    joint = view["elbow_joint"]
    solid, ghost = view["methods"]["standard"], view["methods"]["optimized"]
    labels = {m["name"]: m["label"] for m in live_server.get("/api/meta")["methods"]}
    for plot, field in (("plot-power", "joint_power"), ("plot-energy", "joint_energy")):
        traces = page.evaluate(
            f"document.getElementById('{plot}').data.map(d => ({{name: d.name, y: d.y}}))"
        )
        drawn = {t["name"]: np.asarray(t["y"], dtype=float) for t in traces}
        for label, method in (("standard", solid), ("optimized", ghost)):
            served = np.asarray(view["curves"][label][field], dtype=float)[:, joint]
            np.testing.assert_allclose(drawn[labels[method]], served, rtol=1e-12, atol=1e-12)


def test_the_floor_formulas_are_the_served_ones(live_server: Server, page: Any) -> None:
    meta = live_server.get("/api/meta")
    plan = demo_ids(live_server)["plan"]
    page.goto(f"{live_server.url}/#/compare/plan/{plan}")
    page.wait_for_selector("#metrics-table")
    cell = page.inner_text('#metrics-table tr[data-metric="abs_work"] td[data-floor]')
    assert meta["floor_formulas"]["abs_work"] in cell
    assert meta["floor_note"] in page.inner_text("#metrics-card")
