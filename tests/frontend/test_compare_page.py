"""The Compare page with every planned method: values and floors against the API, the below-floor
flag, the human beside the robots, the viewer's pair, and trajectory exports (real browser)."""

from __future__ import annotations

import csv
import io
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from tests.frontend.test_browser import demo_ids, wait_for, wait_for_jobs
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
    rows = [r for r in csv.reader(io.StringIO(saved.read_text())) if not r[0].startswith("#")]
    header = ",".join(rows[0])  # after the export's "#" record lines
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


# Issue 29: findings of a researcher using the Compare page -----------------------------------

STANDARD = ["quintic", "paper", "human_optimal", "bound", "jerk_limited"]


@pytest.fixture(scope="module")
def slow_lift(live_server: Server) -> int:
    """A long slow lift (60 s) planned with every standard method and the paper's default
    template: its work sits on the |ΔPE| floor to round-off."""
    body = {"robot": "human_arm_2dof", "duration": 60.0, "objective": "abs_work",
            "methods": STANDARD, "particles": 8, "iterations": 5, "label": "slow lift"}  # fmt: skip
    job = live_server.post("/api/plans", json=body).json()
    state = wait_for(
        lambda: (
            (s := live_server.get(f"/api/jobs/{job['id']}")["state"]) in ("succeeded", "failed")
            and s
        ),
        900,
        "the 60-s plan",
    )
    assert state == "succeeded", live_server.get(f"/api/jobs/{job['id']}")
    return int(job["id"])


def test_the_card_says_where_the_template_came_from(live_server: Server, page: Any) -> None:
    """Items 1 and 2: the card says plainly whose lifts made the template (or that it is the
    paper's default), and what its angle is beside the per-lift peaks the recording shows."""
    plan = demo_ids(live_server)["plan"]
    data = live_server.get(f"/api/viewer/comparisons/plan/{plan}?points=10")
    info = data["template"]
    job = live_server.get(f"/api/jobs/{plan}")
    analysis_id = job["params"]["template_analysis_id"]
    template = live_server.get(f"/api/analyses/{analysis_id}/template")
    # The same analysis: the plan's angle is the lifts' mean peak fraction on the robot's stroke,
    # the recording's number the mean of the per-lift peak angles; both are stated.
    assert info["paper_default"] is False and info["n_lifts"] == template["n_lifts"]
    assert info["per_lift_mean_deg"] == pytest.approx(template["peak_velocity_angle_deg"])
    assert info["range_fraction"] == pytest.approx(template["peak_velocity_range_fraction"])
    assert info["angle_deg"] == pytest.approx(data["result"]["target_peak_velocity_angle_deg"])
    page.goto(f"{live_server.url}/#/compare/plan/{plan}")
    page.wait_for_selector("#metrics-table")
    source = page.inner_text("#template-source")
    assert f"from {template['n_lifts']} lifts of recording #" in source, source
    assert "paper" not in source
    angle = page.inner_text("#template-angle")
    assert f"template angle {info['angle_deg']:.1f}°" in angle, angle
    assert f"per-lift peaks {template['peak_velocity_angle_deg']:.1f}°" in angle, angle
    assert "mean ± SD of each lift's own peak angle" in angle
    # The recording's page says what its number is, and where a plan puts the peak.
    analysis = live_server.get(f"/api/analyses/{analysis_id}")
    page.goto(f"{live_server.url}/#/recordings/{analysis['recording_id']}")
    wait_for_jobs(
        live_server, lambda: "template from" in page.inner_text("#template-facts"), "the template"
    )
    facts = page.inner_text("#template-facts")
    assert "mean ± SD of each lift's own peak angle" in facts, facts
    assert f"{round(100 * template['peak_velocity_range_fraction'])} % of the elbow stroke" in facts


def test_a_metric_on_its_floor_to_round_off_is_not_below_it(
    live_server: Server, page: Any, slow_lift: int
) -> None:
    """Item 3: a 60-s plan showed "below floor!" where value and floor both printed alike."""
    result = live_server.get(f"/api/plans/{slow_lift}")["result"]
    floor = result["floors"]["abs_work"]
    values = {m: v["abs_work"] for m, v in result["methods"].items()}
    assert any(v < floor for v in values.values())  # under the floor by round-off only
    page.goto(f"{live_server.url}/#/compare/plan/{slow_lift}")
    page.wait_for_selector("#metrics-table", timeout=120_000)
    assert page.locator("#metrics-table .below-floor").count() == 0
    assert "below its physical floor" not in page.inner_text("#metrics-card")
    at = page.locator('#metrics-table tr[data-metric="abs_work"] td[data-floor-state="at"]')
    assert at.count() >= 1 and "at the floor" in at.first.inner_text()
    # Item 1: no template was given: the card says it is the paper's default, not the person's.
    source = page.inner_text("#template-source")
    assert "paper's default" in source and "not from the person's lifts" in source, source


def test_the_report_holds_every_method(live_server: Server, slow_lift: int) -> None:
    """Item 4: the exported report shows every planned method as the Compare page does."""
    import html
    import re

    url = f"{live_server.url}/api/viewer/comparisons/plan/{slow_lift}/export?format=report"
    with urllib.request.urlopen(url, timeout=300) as response:
        page = response.read().decode()
    table = re.search(r'<table id="metrics">.*?</table>', page, flags=re.S)
    assert table, "no metrics table"
    heads = [html.unescape(h) for h in re.findall(r"<th>(.*?)</th>", table.group(0))]
    for label in ("standard quintic", "paper's method", "human-like optimum", "physical bound",
                  "industrial jerk-limited"):  # fmt: skip
        assert label in heads, heads
    text = html.unescape(page.split("<script", 1)[0])
    assert "{'" not in text and "': " not in text
    assert "no floor" in text and "share of the achievable saving" in text
    assert "paper's default" in text and "no recorded human" in text


@pytest.mark.parametrize("kind", ["plan", "simulation"])
def test_no_horizontal_overflow_at_400_px(live_server: Server, browser: Any, kind: str) -> None:
    """Item 7: at 400 px the tables scroll inside their cards; the page itself never scrolls
    sideways."""
    from tests.utils.browser import new_context

    context = new_context(browser, viewport={"width": 400, "height": 800})
    try:
        page = context.new_page()
        result_id = demo_ids(live_server)[kind]
        page.goto(f"{live_server.url}/#/compare/{kind}/{result_id}")
        page.wait_for_selector("#export-card", timeout=180_000)
        page.wait_for_selector("#plot-human .main-svg", timeout=180_000)
        widths = page.evaluate(
            "[document.documentElement.scrollWidth, document.documentElement.clientWidth,"
            " document.body.scrollWidth]"
        )
        assert widths[0] <= widths[1] and widths[2] <= widths[1], widths
        for table in ("#metrics-table", "#torque-table"):
            wrap = page.evaluate(
                f"(() => {{ const r = document.querySelector('{table}').parentElement"
                ".getBoundingClientRect(); return [r.left, r.right]; })()"
            )
            assert wrap[0] >= 0 and wrap[1] <= widths[1], (table, wrap)
        screenshot(page, f"compare-400px-{kind}")
    finally:
        context.close()
