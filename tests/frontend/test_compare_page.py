"""The Compare page with every planned method: values and floors against the API, the below-floor
flag, the human beside the robots, the viewer's pair, and trajectory exports (real browser)."""

from __future__ import annotations

import csv
import io
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from tests.frontend.test_browser import demo_ids, wait_for
from tests.utils.browser import screenshot
from tests.utils.server import Server

SCALARS = ("tau_sq", "abs_work", "pos_work", "electrical_energy", "peak_power")


def _cell(page: Any, metric: str, method: str) -> str | None:
    return page.get_attribute(
        f'#metrics-table tr[data-metric="{metric}"] td[data-method="{method}"]', "data-value"
    )  # type: ignore[no-any-return]


def test_every_method_with_its_floor_and_share(live_server: Server, page: Any) -> None:
    sim = demo_ids(live_server)["simulation"]
    result = live_server.get(f"/api/simulations/{sim}")["result"]
    planned = list(result["methods"])
    assert len(planned) == 5
    page.goto(f"{live_server.url}/#/compare/simulation/{sim}")
    page.wait_for_selector("#metrics-table")
    heads = page.eval_on_selector_all(
        "#metrics-table thead th[data-method]", "els => els.map(e => e.dataset.method)"
    )
    assert heads == planned
    for metric in SCALARS:
        for method in planned:
            expected = result["methods"][method][metric]
            shown = _cell(page, metric, method)
            if expected is None:
                assert shown == ""
            else:
                assert float(shown or "nan") == pytest.approx(expected, rel=1e-9), (metric, method)
        floor = page.get_attribute(
            f'#metrics-table tr[data-metric="{metric}"] td[data-floor]', "data-floor"
        )
        expected_floor = result["floors"].get(metric)
        if expected_floor is None:
            assert floor == ""
        else:
            assert float(floor or "nan") == pytest.approx(expected_floor, rel=1e-9)
    for method in planned:
        share = result["share_of_achievable_pct"][method]
        shown = _cell(page, "share", method)
        assert (shown == "") if share is None else float(shown or "nan") == pytest.approx(share)
    assert page.locator("#metrics-table .below-floor").count() == 0  # a correct result
    assert page.locator("#torque-table tbody tr").count() == len(planned)
    page.wait_for_selector("#plot-qd .main-svg")
    assert page.evaluate("document.getElementById('plot-qd').data.length") == len(planned)
    # The robots' elbow velocity beside the recorded human's (the demo plans with the demo
    # recording's template, whose lift is replayed).
    page.wait_for_selector("#plot-human .main-svg")
    traces = page.evaluate("document.getElementById('plot-human').data.map(d => d.name)")
    assert len(traces) >= len(planned)
    note = page.inner_text("#human-note")
    assert ("recorded human" in traces and "lift" in note) or "No recorded human" in note
    screenshot(page, "compare-methods")


def test_a_value_below_its_floor_is_flagged(live_server: Server, page: Any) -> None:
    """The page must not show an impossible number as a saving: a result whose paper's method
    does less work than |ΔPE| (as once the electrical energy below ΔPE on the human arm) is
    flagged in its cell and above the table."""
    plan = demo_ids(live_server)["plan"]

    def lower(route: Any) -> None:
        body = route.fetch().json()
        floor = body["result"]["floors"]["abs_work"]
        body["result"]["methods"]["paper"]["abs_work"] = 0.99 * floor
        route.fulfill(json=body)

    page.route(f"**/api/viewer/comparisons/plan/{plan}?*", lower)
    page.goto(f"{live_server.url}/#/compare/plan/{plan}")
    page.wait_for_selector("#metrics-table")
    flagged = page.locator('#metrics-table tr[data-metric="abs_work"] td.below-floor')
    assert flagged.count() == 1 and flagged.get_attribute("data-method") == "paper"
    assert "below floor" in flagged.inner_text()
    assert "below its physical floor" in page.inner_text("#metrics-card")
    assert page.locator("#metrics-table .below-floor").count() == 1


def test_the_viewer_shows_the_chosen_pair(live_server: Server, page: Any) -> None:
    plan = demo_ids(live_server)["plan"]
    page.goto(f"{live_server.url}/#/compare/plan/{plan}")
    page.wait_for_selector("#viewer-frame")
    page.select_option("#method-b", "bound")
    wait_for(lambda: page.url.endswith("?methods=quintic,bound"), 60, "the pair in the address")
    page.select_option("#method-a", "human_optimal")
    wait_for(lambda: page.url.endswith("?methods=human_optimal,bound"), 60, "the new pair")
    page.wait_for_selector("#viewer-frame")
    page.locator("#viewer-frame").scroll_into_view_if_needed()  # viser connects once in view
    src = page.get_attribute("#viewer-frame", "src") or ""
    assert "methods%3Dhuman_optimal%2Cbound" in src
    legend = page.inner_text("#methods-legend")
    assert (
        "human-like optimum (in the viewer)" in legend
        and "physical bound (in the viewer)" in legend
    )

    def shown() -> Any:
        for s in live_server.get("/api/viewer/sessions"):
            if s["kind"] == "plan" and s["id"] == plan and s["solid"] == "human_optimal":
                return s
        return None

    try:
        session = wait_for(shown, 120, "a viewer tab showing the chosen pair")
    except AssertionError as exc:
        raise AssertionError(
            f"{exc}; sessions: {live_server.get('/api/viewer/sessions')}"
        ) from None
    assert session["ghost"] == "bound"
    page.select_option("#method-a", "bound")  # the same method twice is refused on the page
    assert "two different" in page.inner_text("#pair-note")


def test_export_any_method_at_any_rate(live_server: Server, page: Any, tmp_path: Path) -> None:
    plan = demo_ids(live_server)["plan"]
    result = live_server.get(f"/api/plans/{plan}")["result"]
    page.goto(f"{live_server.url}/#/compare/plan/{plan}")
    page.wait_for_selector("#export-download")
    page.select_option("#export-format", "csv")
    page.select_option("#export-method", "bound")
    page.fill("#export-rate", "50")
    with page.expect_download(timeout=120_000) as info:
        page.click("#export-download")
    saved = tmp_path / "bound.csv"
    info.value.save_as(saved)
    url = f"{live_server.url}/api/plans/{plan}/trajectory?format=csv&method=bound&rate=50"
    with urllib.request.urlopen(url, timeout=120) as response:
        assert saved.read_bytes() == response.read()  # what the API gives for those options
    rows = list(csv.reader(io.StringIO(saved.read_text())))
    header = ",".join(rows[0])
    assert all(name in header for name in result["joint_names"])
    assert len(rows) - 1 == pytest.approx(50 * result["duration"] + 1, abs=1)  # the rate
    wait_for(lambda: "Saved" in page.inner_text("#export-status"), 30, "the saved note")
    # A refused option shows the server's message, and the button is usable again.
    page.fill("#export-rate", "1000000")
    page.click("#export-download")
    wait_for(lambda: "rate" in page.inner_text("#export-status"), 60, "the server's message")
    assert page.locator("#export-download").is_enabled()
    with page.expect_download(timeout=120_000) as report:
        page.click("#export-report")
    assert b"<html" in Path(report.value.path()).read_bytes()[:2000].lower()


def test_a_labelled_plan_is_named_in_the_picker_and_renamed(live_server: Server, page: Any) -> None:
    """Issue 15 item 6: eight entries were all titled alike. A label given on the Plan page
    names the comparison in the picker; renamed on the Compare page, it stays renamed."""
    page.goto(f"{live_server.url}/#/plan")
    page.wait_for_selector("#methods-fieldset")
    page.select_option("#robot", "human_arm_2dof")
    page.select_option("#kind", "plan")
    page.fill("#plan-label", "light and quick")
    page.fill("#particles", "8")
    page.fill("#iterations", "5")
    page.click("#submit-plan")
    page.wait_for_selector("#open-compare, #job-result .banner", timeout=180_000)
    assert page.locator("#open-compare").count(), page.inner_text("#job-result")
    plan_id = int((page.get_attribute("#open-compare", "href") or "").rsplit("/", 1)[-1])
    assert live_server.get(f"/api/plans/{plan_id}")["label"] == "light and quick"

    page.click("#open-compare")
    page.wait_for_selector("#metrics-table", timeout=120_000)
    chosen = "#comparison-select option:checked"
    assert "“light and quick”" in page.inner_text(chosen)
    assert page.input_value("#label-input") == "light and quick"
    page.fill("#label-input", "renamed on compare")
    page.click("#label-save")
    wait_for(lambda: "renamed" in page.inner_text("#label-status"), 30, "the rename")
    assert "“renamed on compare”" in page.inner_text(chosen)
    assert live_server.get(f"/api/plans/{plan_id}")["label"] == "renamed on compare"
    page.reload()
    page.wait_for_selector("#metrics-table", timeout=120_000)
    assert "“renamed on compare”" in page.inner_text(chosen)
