"""Trade-offs under Compare (#/compare/fronts, front.js) in a real browser: a front drawn from the
form with progress, plotted as the API gives it (points, knee, references), a clicked point
playing in the viewer with its metrics, the CSV and a point's export; the form's rules (A != B,
no fixed duration on a duration axis), a refusal beside its field, and cancel."""

from __future__ import annotations

import csv
import io
import urllib.parse
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from tests.frontend.test_browser import wait_for
from tests.utils.browser import screenshot
from tests.utils.server import Server

#: A small front on the built-in 2-DOF arm that solves in seconds: 3 points (a knee between
#: the two ends), the coarsest mesh, a loose convergence tolerance.
ROBOT = "human_arm_2dof"
A, B = "tau_sq", "jerk"
#: Waits for jobs [s]: generous, the machine is shared; nothing is asserted about time.
JOB_TIMEOUT = 1200.0


@pytest.fixture
def fronts(live_server: Server) -> Server:
    """The live server, when it serves fronts (the page is developed beside the service)."""
    paths = live_server.get("/openapi.json").get("paths", {})
    if "/api/fronts" not in paths:
        pytest.skip(
            "this server has no fronts service (POST /api/fronts, app/api/routes/fronts.py)"
        )
    return live_server


def _open_form(page: Any, server: Server) -> None:
    page.goto(f"{server.url}/#/compare")
    page.click("#open-fronts")  # the way there from Compare
    page.wait_for_selector("#front-form")


def _fill_small_front(page: Any) -> None:
    page.select_option("#front-robot", ROBOT)
    page.select_option("#front-a", A)
    page.select_option("#front-b", B)
    page.fill("#front-points", "3")
    page.click("#front-form summary")
    page.fill("#front-intervals", "8")
    page.fill("#front-tolerance", "0.05")


def _plot(page: Any) -> list[dict[str, Any]]:
    return page.evaluate(  # type: ignore[no-any-return]
        "document.getElementById('front-plot').data.map(d => "
        "({name: d.name, x: d.x, y: d.y, customdata: d.customdata || null}))"
    )


def _click_plot_point(page: Any, index: int) -> None:
    """Click the front's `index`-th marker where it is drawn (Plotly picks the point under the
    mouse and fires plotly_click)."""
    marker = page.locator("#front-plot .scatterlayer .trace").first.locator("path.point")
    marker.nth(index).click(force=True)


def test_the_form_keeps_its_axes_apart_and_the_duration_off_a_duration_axis(
    live_server: Server, page: Any
) -> None:
    _open_form(page, live_server)
    page.select_option("#front-a", "abs_work")
    disabled = (
        "sel => [...document.querySelector(sel).options].filter(o => o.disabled).map(o => o.value)"
    )
    assert page.evaluate(disabled, "#front-b") == ["abs_work"]
    page.select_option("#front-b", "peak_power")
    assert page.evaluate(disabled, "#front-a") == ["peak_power"]
    assert not page.is_disabled("#front-duration") and page.is_disabled("#front-max-duration")
    page.select_option("#front-a", "duration")
    assert page.is_disabled("#front-duration") and not page.is_disabled("#front-max-duration")
    assert page.evaluate(disabled, "#front-b") == ["duration"]
    # Every axis the service takes, each with its unit; the front's peak torque is a ratio to
    # the limit, not Nm.
    values = page.eval_on_selector_all("#front-a option", "els => els.map(e => e.value)")
    schema = live_server.get("/openapi.json")["components"]["schemas"].get("FrontRequest")
    if schema is not None:
        assert values == schema["properties"]["objectives"]["items"]["enum"]
    texts = page.eval_on_selector_all("#front-a option", "els => els.map(e => e.textContent)")
    assert len(texts) == 8 and all("[" in t for t in texts)
    assert next(t for t in texts if t.startswith("peak_torque")).endswith("[τ/τ_max]")


def test_a_refused_front_is_named_beside_its_field(fronts: Server, page: Any) -> None:
    _open_form(page, fronts)
    page.fill("#front-points", "1")  # the API takes 2 or more (the two ends)
    page.click("#submit-front")
    error = page.wait_for_selector('.field-error[data-field="points"]')
    assert error.inner_text().startswith("Points")
    assert page.get_attribute("#front-points", "aria-invalid") == "true"
    assert page.locator("#front-progress").count() == 0


def test_draw_a_front_click_a_point_and_export(fronts: Server, page: Any) -> None:
    _open_form(page, fronts)
    _fill_small_front(page)
    page.click("#submit-front")
    page.wait_for_selector("#front-progress")
    page.wait_for_selector("#front-plot .main-svg", timeout=JOB_TIMEOUT * 1000)
    front_id = int(page.evaluate("location.hash").rsplit("/", 1)[1])
    # Left while it loaded, the Compare page filled its own box, not this page.
    assert page.locator("#metrics-table, #curves-card, #viewer-card").count() == 0
    out = fronts.get(f"/api/fronts/{front_id}")
    r = out["result"]
    assert out["job"]["params"]["objectives"] == [A, B] and r["robot"] == ROBOT
    points = r["points"]
    ids = [p["id"] for p in points]
    assert len(ids) >= 2

    # The plot is the API's front: A on x, B on y, in front order; the knee where it says.
    traces = _plot(page)
    front = traces[0]
    assert front["customdata"] == ids
    assert front["x"] == [p[A] for p in points] and front["y"] == [p[B] for p in points]
    knee = [t for t in traces if t["name"] == "knee"]
    assert [k["customdata"] for k in knee] == ([[r["knee"]]] if r["knee"] else [])
    # Every reference drawn where it has values, and named with its error where it failed.
    labels = {m["name"]: m["label"] for m in fronts.get("/api/meta")["methods"]}
    notes = page.inner_text("#front-ref-notes")
    for name, ref in r["references"].items():
        drawn = [t for t in traces if t["name"] == labels[name]]
        if "error" in ref:
            assert not drawn and ref["error"] in notes
        else:
            assert drawn[0]["x"] == [ref[A]] and drawn[0]["y"] == [ref[B]]

    # The knee (or the first point) is shown first; clicking another plays it in the viewer.
    first = r["knee"] or ids[0]
    page.wait_for_selector(f'#front-point-metrics[data-point="{first}"]')
    before = page.get_attribute("#front-viewer-frame", "src")
    index = next(i for i, pid in enumerate(ids) if pid != first)
    pid = ids[index]
    _click_plot_point(page, index)
    page.wait_for_selector(f'#front-point-metrics[data-point="{pid}"]')
    view = fronts.get(f"/api/fronts/{front_id}/points/{pid}/view")
    assert view["viewer"]["enabled"], "the live server runs the viewer"
    src = wait_for(
        lambda: (s := page.get_attribute("#front-viewer-frame", "src")) != before and s,
        what="the viewer to change",
    )
    shown, given = urllib.parse.urlsplit(src), urllib.parse.urlsplit(view["viewer"]["url"])
    assert pid in src and (shown.port, shown.path, shown.query) == (
        given.port,
        given.path,
        given.query,
    )
    # The viewer plays that point beside the quintic (viser connects once in view).
    page.locator("#front-viewer-frame").scroll_into_view_if_needed()

    def playing() -> Any:
        for s in fronts.get("/api/viewer/sessions"):
            if s["kind"] == "front" and s["id"] == front_id and pid in (s["solid"], s["ghost"]):
                return s
        return None

    session = wait_for(playing, 300, f"a viewer tab playing {pid}")
    assert {session["solid"], session["ghost"]} == {pid, "quintic"}
    # Its metrics are the API's point's, every axis.
    point = view["point"]
    assert point == points[index]
    for axis in ("tau_sq", "abs_work", "pos_work", "electrical_energy", "peak_power", "jerk"):
        value = page.get_attribute(f'#front-point-table tr[data-metric="{axis}"]', "data-value")
        assert float(value or "nan") == pytest.approx(point[axis], rel=1e-12), axis
    joints = page.eval_on_selector_all(
        "#front-point-torques td[data-joint]", "els => els.map(e => e.dataset.joint)"
    )
    assert joints == list(point["peak_torques"])
    screenshot(page, "front-page")

    # The front as CSV: one row per point in front order, A and B first.
    href = page.get_attribute("#front-csv", "href")
    with urllib.request.urlopen(f"{fronts.url}{href}", timeout=120) as response:
        assert response.headers["Content-Type"].startswith("text/csv")
        rows = list(csv.reader(io.StringIO(response.read().decode())))
    assert rows[0][:3] == ["id", A, B] and [row[0] for row in rows[1:]] == ids

    # The point's trajectory saved from the page is the API's export of it.
    link = page.locator('#front-point-exports a[data-format="csv"]')
    with page.expect_download() as saved:
        link.click()
    data = Path(saved.value.path()).read_bytes()
    with urllib.request.urlopen(f"{fronts.url}{link.get_attribute('href')}", timeout=120) as res:
        assert data == res.read()
    assert f"/points/{pid}/" in (link.get_attribute("href") or "")

    # The job drawer links the finished front to this page.
    if page.locator("#job-drawer[hidden]").count():
        page.click("#jobs-button")
    opener = page.locator(f'#job-list li[data-job-id="{front_id}"] a.job-open')
    opener.wait_for(timeout=120_000)
    assert opener.get_attribute("href") == f"#/compare/fronts/{front_id}"
    assert "Pareto front" in page.inner_text(f'#job-list li[data-job-id="{front_id}"]')


def test_cancel_a_front_while_it_runs(fronts: Server, page: Any) -> None:
    _open_form(page, fronts)
    page.select_option("#front-robot", "curtain_wall_6dof")
    page.fill("#front-points", "25")  # long enough to be cancelled while it runs
    page.click("#submit-front")
    page.wait_for_selector("#front-cancel")
    job_id = int(page.inner_text("#front-status strong").split("#")[1])
    page.click("#front-cancel")
    page.wait_for_selector("#front-status .banner.warn", timeout=JOB_TIMEOUT * 1000)
    assert page.inner_text("#front-status .banner.warn") == "Cancelled."
    assert fronts.get(f"/api/jobs/{job_id}")["state"] == "cancelled"
    assert page.locator("#front-plot").count() == 0


def test_a_previous_front_reopens_and_a_point_without_the_viewer_says_so(
    fronts: Server, page: Any
) -> None:
    body = {"robot": ROBOT, "objectives": [A, B], "points": 3, "intervals": 8, "tolerance": 0.05}
    job = fronts.post("/api/fronts", json=body).json()
    done = wait_for(
        lambda: (
            (j := fronts.get(f"/api/jobs/{job['id']}"))["state"] in ("succeeded", "failed") and j
        ),
        JOB_TIMEOUT,
        "the front",
    )
    assert done["state"] == "succeeded", done["error"]

    def no_viewer(route: Any) -> None:  # as a server without the viewer answers
        answer = route.fetch().json()
        route.fulfill(json={**answer, "viewer": {"enabled": False}})

    page.route("**/api/fronts/*/points/*/view", no_viewer)
    _open_form(page, fronts)
    # Listed among the previous fronts, and reopened from there.
    page.select_option("#front-select", str(job["id"]))
    wait_for(lambda: page.url.endswith(f"#/compare/fronts/{job['id']}"), 60, "the front's address")
    result = fronts.get(f"/api/fronts/{job['id']}")["result"]
    first = result["knee"] or result["points"][0]["id"]
    page.wait_for_selector(f'#front-point-metrics[data-point="{first}"]')
    assert "not running" in page.inner_text("#front-viewer")
    assert page.locator("#front-viewer-frame").count() == 0
    # The points' table chooses a point as the plot does.
    last = result["points"][-1]["id"]
    page.click("#front-card details summary")
    page.click(f'#front-points-table tr[data-point="{last}"]')
    page.wait_for_selector(f'#front-point-metrics[data-point="{last}"]')
    assert page.get_attribute("#front-result", "data-selected") == last
