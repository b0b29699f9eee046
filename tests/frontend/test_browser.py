"""The dashboard in a real browser: upload, plots, errors, planning, comparing, the 3-D viewer."""

from __future__ import annotations

import io
import json
import time
import urllib.error
import urllib.request
import uuid
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from tests.utils.browser import new_context, screenshot
from tests.utils.data import shared_file
from tests.utils.server import Server

C3D = "pyomeca_upperlimb_c3d_emg/markers_analogs.c3d"
NORAXON_CSV = "noraxon_curls_biceps_brachioradialis/2023-04-20-15-06_BR_posredni.csv"


def wait_for(predicate: Any, timeout: float = 120.0, what: str = "condition") -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def wait_for_jobs(
    server: Server, predicate: Any, what: str, quiet: float = 180.0, cap: float = 900.0
) -> Any:
    """Wait for something a job brings, however long the jobs queued before it take.

    A session's live server runs at most two jobs at once, and other tests on the same worker
    may have queued long ones (a video's pose, a sweep) before this test's job. So the deadline
    is ``quiet`` seconds after the server last had a job queued or running, never more than
    ``cap`` in all; a timeout names the jobs still active.
    """
    start = last_active = time.monotonic()
    while time.monotonic() - start < cap:
        value = predicate()
        if value:
            return value
        if server.active_jobs():
            last_active = time.monotonic()
        elif time.monotonic() - last_active > quiet:
            break
        time.sleep(0.5)
    active = [(j["id"], j["kind"], j["state"], j["progress"]) for j in server.active_jobs()]
    raise AssertionError(
        f"timed out after {time.monotonic() - start:.0f} s waiting for {what} "
        f"(the server's jobs were last active {time.monotonic() - last_active:.0f} s ago; "
        f"active now: {active})"
    )


def signal_names(page: Any, plot: str) -> list[str]:
    """Names of a plot's signal traces (leaving out the phase, lift-top and onset overlays)."""
    names: list[str] = page.evaluate(f"document.getElementById('{plot}').data.map(d => d.name)")
    overlay = ("phase ", "lift tops")
    return [n for n in names if not n.startswith(overlay) and not n.endswith(" onsets")]


def post_files(server: Server, files: list[tuple[str, bytes]]) -> tuple[int, dict[str, Any]]:
    """Upload through the API directly (the reference for what the page must show)."""
    boundary = uuid.uuid4().hex
    body = io.BytesIO()
    for name, data in files:
        body.write(f"--{boundary}\r\n".encode())
        body.write(
            f'Content-Disposition: form-data; name="files"; filename="{name}"\r\n'
            "Content-Type: application/octet-stream\r\n\r\n".encode()
        )
        body.write(data + b"\r\n")
    body.write(f"--{boundary}--\r\n".encode())
    request = urllib.request.Request(
        f"{server.url}/api/recordings",
        data=body.getvalue(),
        headers={"Content-Type": f"multipart/form-data; boundary={boundary}"},
    )
    try:
        with urllib.request.urlopen(request, timeout=120) as response:
            return response.status, json.load(response)
    except urllib.error.HTTPError as exc:
        with exc:
            return exc.code, json.load(exc)


def demo_ids(server: Server) -> dict[str, int]:
    jobs = server.get("/api/jobs?limit=200")["items"]
    first = {}
    for j in sorted(jobs, key=lambda j: j["id"]):
        if j["state"] == "succeeded":
            first.setdefault(j["kind"], j["id"])
    return first


def test_upload_a_real_file_and_see_its_plots(live_server: Server, page: Any) -> None:
    path = shared_file(C3D)
    page.goto(f"{live_server.url}/#/recordings")
    page.wait_for_selector("#recordings-table")
    screenshot(page, "recordings")
    page.set_input_files("#file-input", str(path))
    page.fill("#subject", "pyomeca S1")
    page.fill("#task", "box handling")
    page.click("#upload-button")
    link = page.wait_for_selector("#upload-error a")
    assert page.locator("#upload-progress").get_attribute("aria-valuenow") == "100"
    assert "Stored as recording #" in page.inner_text("#upload-error")
    rec_id = int(link.get_attribute("href").rsplit("/", 1)[1])
    detail = live_server.get(f"/api/recordings/{rec_id}")
    assert detail["subject"] == "pyomeca S1" and detail["file_names"] == [path.name]
    # The new recording is in the list, found by the search box.
    page.fill("#search", "pyomeca S1")
    page.wait_for_selector(f'#recordings-body tr[data-id="{rec_id}"]')

    link.click()
    page.wait_for_selector("#emg-plot .main-svg")
    # One raw trace per EMG channel mapped to a site (deltoid, biceps, triceps sites).
    mapped = [c for f in detail["files"] for c in f["channels"] if c["kind"] == "emg" and c["site"]]
    assert len(mapped) >= 3
    wait_for(
        lambda: len(signal_names(page, "emg-plot")) >= 2 * len(mapped),
        what="raw EMG and envelopes",
    )
    assert {f"{c['name']} raw" for c in mapped} <= set(signal_names(page, "emg-plot"))
    # Angles and velocities from the markers, lifts with phases in the table.
    page.wait_for_selector("#angle-plot .main-svg")
    assert signal_names(page, "angle-plot") == [
        "elbow flexion",
        "shoulder flexion",
        "elbow velocity",
        "shoulder velocity",
    ]
    page.wait_for_selector("#lifts-table tbody tr")
    analysis = live_server.get(f"/api/viewer/recordings/{rec_id}/analysis?points=50")
    assert page.locator("#lifts-table tbody tr").count() == len(analysis["lifts"]) > 0
    # Every A phase of the analysis is shaded on the angle plot (angles and velocities).
    shaded = page.evaluate(
        "document.getElementById('angle-plot').data.filter(d => d.name === 'phase A')"
        ".map(d => d.x.filter(v => v !== null).length / 5)"
    )
    phases_a = sum(p["name"] == "A" for lift in analysis["lifts"] for p in lift["phases"])
    assert shaded == [phases_a, phases_a] and phases_a > 0
    screenshot(page, "recording-detail")


def test_detail_page_runs_a_missing_analysis(live_server: Server, page: Any) -> None:
    """A recording stored by REST without an analysis: its page starts the job, follows it and
    then draws the overlays the job stored."""
    from app.services import synthetic_curls_csv

    status, rec = post_files(live_server, [("three_curls.csv", synthetic_curls_csv(lifts=3))])
    assert status == 201, rec
    assert live_server.get(f"/api/analyses?recording_id={rec['id']}")["total"] == 0
    page.goto(f"{live_server.url}/#/recordings/{rec['id']}")
    page.wait_for_selector("#analysis-status .progress")
    page.wait_for_selector("#lifts-table tbody tr")
    jobs = live_server.get(f"/api/analyses?recording_id={rec['id']}")["items"]
    assert len(jobs) == 1 and jobs[0]["job"]["state"] == "succeeded"
    assert page.locator("#lifts-table tbody tr").count() == 3
    names = page.evaluate("document.getElementById('angle-plot').data.map(d => d.name)")
    assert "elbow flexion" in names


def test_zoom_loads_the_window(live_server: Server, page: Any) -> None:
    rec = live_server.get("/api/recordings?subject=demo%20subject")["items"][0]["id"]
    page.goto(f"{live_server.url}/#/recordings/{rec}")
    page.wait_for_selector("#angle-plot .main-svg")
    first_raw = "document.getElementById('emg-plot').data.find(d => d.name.endsWith(' raw'))"
    full = page.evaluate(f"{first_raw}.x.length")
    page.evaluate(
        "Plotly.relayout(document.getElementById('emg-plot'), "
        "{'xaxis.range[0]': 6.0, 'xaxis.range[1]': 6.5})"
    )

    def zoomed() -> bool:
        xs = page.evaluate(f"{first_raw}.x")
        return bool(xs) and min(xs) >= 6.0 and max(xs) <= 6.5

    wait_for(zoomed, what="the zoomed window to load")
    # 0.5 s at 1 kHz: every sample of the window, more detail than the whole-file view had.
    xs = np.asarray(page.evaluate(f"{first_raw}.x"))
    assert len(xs) == 501 and np.allclose(np.diff(xs), 0.001)
    assert full <= 1600


def test_bad_files_show_the_servers_messages(
    live_server: Server, page: Any, tmp_path: Path
) -> None:
    """Issue 15: several bad files in one upload named only the first. Every unreadable file
    gets its own message next to it; the readable one is not stored either."""
    good = shared_file(NORAXON_CSV)
    bad = tmp_path / "truncated.c3d"
    bad.write_bytes(shared_file(C3D).read_bytes()[:3000])
    worse = tmp_path / "noise.csv"
    worse.write_bytes(b"\x00\x01\x02 not a table\n" * 20)
    upload = [(p.name, p.read_bytes()) for p in (good, bad, worse)]
    status, problem = post_files(live_server, upload)
    assert status == 422 and problem["file"] == bad.name
    details = {f["file"]: f["detail"] for f in problem["files"]}
    assert set(details) == {bad.name, worse.name}
    before = live_server.get("/api/recordings")["total"]

    page.goto(f"{live_server.url}/#/recordings")
    page.set_input_files("#file-input", [str(good), str(bad), str(worse)])
    page.click("#upload-button")
    for name in (bad.name, worse.name):
        error = page.wait_for_selector(f'li[data-name="{name}"] .file-error')
        assert error.inner_text() == details[name]  # the server's own words, next to the file
    assert "not stored" in page.inner_text(f'li[data-name="{good.name}"]')
    assert "2 files could not be read" in page.inner_text("#upload-error")
    assert live_server.get("/api/recordings")["total"] == before
    screenshot(page, "recordings-bad-file")


def test_delete_from_the_list(live_server: Server, page: Any) -> None:
    data = shared_file(NORAXON_CSV).read_bytes()
    status, rec = post_files(live_server, [("to_delete.csv", data)])
    assert status == 201
    page.on("dialog", lambda dialog: dialog.accept())
    page.goto(f"{live_server.url}/#/recordings")
    row = page.wait_for_selector(f'#recordings-body tr[data-id="{rec["id"]}"]')
    assert "to_delete.csv" in row.inner_text()
    page.click(f'button[aria-label="Delete recording {rec["id"]}"]')
    page.wait_for_selector(f'#recordings-body tr[data-id="{rec["id"]}"]', state="detached")
    gone = httpx.get(f"{live_server.url}/api/recordings/{rec['id']}", timeout=60)
    assert gone.status_code == 404


def test_plan_progress_reaches_done(live_server: Server, page: Any) -> None:
    page.goto(f"{live_server.url}/#/plan")
    page.wait_for_selector("#plan-form")
    page.select_option("#kind", "plan")
    page.fill("#particles", "16")
    page.fill("#iterations", "40")
    page.fill("#seed", "3")
    page.click("#submit-plan")
    page.wait_for_selector("#job-progress")
    page.wait_for_function("document.querySelector('#job-state').innerText === 'succeeded'")
    assert page.get_attribute("#job-progress", "aria-valuenow") == "100"
    page.wait_for_selector("#open-compare")
    href = page.get_attribute("#open-compare", "href")
    plan_id = int(href.rsplit("/", 1)[1])
    result = live_server.get(f"/api/plans/{plan_id}")["result"]
    assert result["optimizer"]["seed"] == 3
    # The convergence curve ends with the optimiser's full history.
    ys = page.evaluate("document.getElementById('convergence-plot').data[0].y")
    assert ys == pytest.approx(result["optimizer"]["history"])
    screenshot(page, "plan")


def test_plan_can_be_cancelled(live_server: Server, page: Any) -> None:
    page.goto(f"{live_server.url}/#/plan")
    page.select_option("#kind", "plan")
    page.fill("#particles", "400")
    page.fill("#iterations", "2000")  # the most BIOPLAN_MAX_ITERATIONS allows
    page.click("#submit-plan")
    page.wait_for_function(
        "document.querySelector('#job-state') && "
        "document.querySelector('#job-state').innerText === 'running'",
    )
    # The convergence curve grows from the job's structured progress (stage "pso", iteration
    # `done`, `best` cost), not from its message text.
    page.wait_for_function(
        "(() => { const d = document.getElementById('convergence-plot').data;"
        " return d && d.length && d[0].x.length >= 2; })()"
    )
    curve = page.evaluate("document.getElementById('convergence-plot').data[0]")
    assert curve["name"] == "pso"
    assert curve["x"] == sorted(set(curve["x"])) and all(isinstance(x, int) for x in curve["x"])
    assert curve["y"] == sorted(curve["y"], reverse=True)  # the best cost never rises
    page.click("#cancel-job")
    page.wait_for_function("document.querySelector('#job-state').innerText === 'cancelled'")
    # The state tag follows the job's last event; the banner follows once the stream has closed,
    # a moment later on a busy machine, so wait for it rather than read it at once.
    page.wait_for_function("document.querySelector('#job-result').innerText.includes('Cancelled')")
    assert page.is_hidden("#cancel-job")


def test_compare_shows_the_sweep_heat_map(live_server: Server, page: Any) -> None:
    body = {
        "robot": "curtain_wall_6dof",
        "durations": [1.0, 1.5],
        "payloads": [0.0, 4.0],
        "objectives": ["abs_work"],
        "particles": 6,
        "iterations": 5,
        # The heat map beside the comparison is under test, not the sweep's methods or its
        # convergence check: the paper's method alone, one seed per cell.
        "methods": ["quintic", "paper"],
        "no_check": True,
    }
    request = urllib.request.Request(
        f"{live_server.url}/api/sweeps",
        data=json.dumps(body).encode(),
        headers={"Content-Type": "application/json"},
    )
    with urllib.request.urlopen(request, timeout=120) as response:
        job = json.load(response)
    wait_for(
        lambda: live_server.get(f"/api/jobs/{job['id']}")["state"] == "succeeded",
        120,
        "the sweep",
    )
    table = live_server.get(f"/api/sweeps/{job['id']}")["result"]["tables"]["abs_work"]
    # Sweeps show beside comparisons of the same robot only (the demo's: curtain_wall_6dof).
    page.goto(f"{live_server.url}/#/compare/simulation/{demo_ids(live_server)['simulation']}")
    page.wait_for_selector("#sweep-plot .main-svg")
    z = page.evaluate("document.getElementById('sweep-plot').data[0].z")
    assert z == table["abs_work"]["change_pct"]
    screenshot(page, "compare-sweep")


def _frame_pixels(page: Any) -> np.ndarray:
    from PIL import Image

    png = page.locator("#viewer-frame").screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)


def test_viewer_connects_renders_and_each_tab_has_its_own_scene(
    live_server: Server, browser: Any
) -> None:
    ids = demo_ids(live_server)
    context = new_context(browser, viewport={"width": 1280, "height": 800})
    try:
        tab1 = context.new_page()
        tab1.goto(f"{live_server.url}/#/compare/simulation/{ids['simulation']}")
        tab1.wait_for_selector("#viewer-frame")
        tab1.locator("#viewer-frame").scroll_into_view_if_needed()

        def session(kind: str, rid: int) -> Any:
            for s in live_server.get("/api/viewer/sessions"):
                if s["kind"] == kind and s["id"] == rid and s["frames"] > 20:
                    return s
            return None

        wait_for(lambda: session("simulation", ids["simulation"]), 60, "the viewer session")
        frame = tab1.frame_locator("#viewer-frame")
        frame.locator("canvas").first.wait_for()
        time.sleep(1.5)  # a few frames drawn
        pixels = _frame_pixels(tab1)
        screenshot(tab1, "viewer", full_page=False)
        r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
        drawn = (np.abs(pixels - pixels[5, 5]).sum(axis=2) > 30).mean()
        blue = ((b > r + 60) & (b > g + 25)).sum()  # the standard robot and its trace
        amber = ((r > 170) & (g > 90) & (g < 200) & (b < 120)).sum()  # the optimised ghost
        assert drawn > 0.05, f"the viewer looks blank ({100 * drawn:.1f}% drawn)"
        assert blue > 300 and amber > 100, (blue, amber)

        # A second tab shows another comparison at the same time.
        tab2 = context.new_page()
        tab2.goto(f"{live_server.url}/#/compare/plan/{ids['plan']}")
        tab2.wait_for_selector("#viewer-frame")
        tab2.locator("#viewer-frame").scroll_into_view_if_needed()
        wait_for(lambda: session("plan", ids["plan"]), 60, "the second tab's session")
        assert session("simulation", ids["simulation"]) is not None
    finally:
        context.close()


def test_scene_export_opens_offline(live_server: Server, browser: Any, tmp_path: Path) -> None:
    from PIL import Image

    plan = demo_ids(live_server)["plan"]
    url = f"{live_server.url}/api/viewer/comparisons/plan/{plan}/export?format=scene"
    with urllib.request.urlopen(url, timeout=120) as response:
        path = tmp_path / "scene.html"
        path.write_bytes(response.read())
    context = new_context(browser, viewport={"width": 900, "height": 600}, offline=True)
    try:
        page = context.new_page()
        page.goto(path.as_uri())
        page.locator("canvas").first.wait_for()
        time.sleep(2.0)
        pixels = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)
        drawn = (np.abs(pixels - pixels[300, 5]).sum(axis=2) > 30).mean()
        assert drawn > 0.05
    finally:
        context.close()


def _in_view(page: Any, selector: str) -> bool:
    """The element is shown and wholly inside the 400 px wide window."""
    box = page.locator(selector).first.bounding_box()
    return box is not None and box["x"] >= 0 and box["x"] + box["width"] <= 400


def _check_narrow(page: Any, route: str) -> None:
    """Issue 15: at 400 px the Open and Delete buttons and the metrics' change and floor
    columns were off-screen (inside a table scrolled sideways)."""
    if route == "recordings":
        page.wait_for_selector("#recordings-body tr[data-id]")
        row = "#recordings-body tr[data-id]"
        assert _in_view(page, f"{row} a.button") and _in_view(page, f"{row} button.danger")
    if route == "compare":
        page.wait_for_selector("#metrics-table")
        for metric in ("abs_work", "pos_work", "peak_power"):  # the metrics with a floor
            row = f'#metrics-table tr[data-metric="{metric}"]'
            assert _in_view(page, f"{row} .floor-inline"), f"{metric}: floor off-screen"
            assert "floor" in page.inner_text(f"{row} .floor-inline")
            assert _in_view(page, f'{row} td[data-method="paper"] .small')  # its change
        # A legend of many entries goes under the plot, not over its curves.
        page.wait_for_selector("#plot-human .legend")
        legend = page.locator("#plot-human .legend").bounding_box()
        plot = page.locator("#plot-human .nsewdrag").first.bounding_box()
        assert legend["y"] >= plot["y"] + plot["height"], (legend, plot)
        # Scrolled to the last method, the metric names stay in view.
        page.eval_on_selector("#metrics-table", "t => t.parentElement.scrollLeft = 10000")
        assert _in_view(page, '#metrics-table tr[data-metric="tau_sq"] td:first-child')
        assert _in_view(
            page, '#metrics-table tr[data-metric="tau_sq"] td[data-method="jerk_limited"]'
        )


@pytest.mark.parametrize("route", ["recordings", "plan", "compare"])
def test_usable_on_a_narrow_window(live_server: Server, browser: Any, route: str) -> None:
    # The demo's comparison by id: the latest one may be another test's, without the paper.
    path = (
        f"compare/simulation/{demo_ids(live_server)['simulation']}" if route == "compare" else route
    )
    context = new_context(browser, viewport={"width": 400, "height": 860})
    try:
        page = context.new_page()
        page.goto(f"{live_server.url}/#/{path}")
        page.wait_for_selector("main .card")
        page.wait_for_timeout(1500)
        width = page.evaluate("document.documentElement.scrollWidth")
        assert width <= 400, f"{route} is {width} px wide on a 400 px window"
        _check_narrow(page, route)
        screenshot(page, f"{route}-narrow")
    finally:
        context.close()
