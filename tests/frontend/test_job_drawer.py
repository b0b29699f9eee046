"""Issue 15 item 4: a running job could be neither followed nor cancelled after leaving the
Plan page, and the recent jobs table did not refresh. The job drawer is on every page, updated
live from ``GET /api/events/jobs``, and survives navigation and reload."""

from __future__ import annotations

from typing import Any

from tests.frontend.test_browser import wait_for, wait_for_jobs
from tests.utils.browser import screenshot
from tests.utils.server import Server

TINY = {"robot": "human_arm_2dof", "particles": 8, "iterations": 5, "methods": ["quintic", "paper"]}
LONG = {**TINY, "robot": "curtain_wall_6dof", "particles": 400, "iterations": 2000}


def _item(job_id: int) -> str:
    return f'#job-list li[data-job-id="{job_id}"]'


def _state(page: Any, job_id: int) -> str | None:
    return (
        page.get_attribute(_item(job_id), "data-state")
        if page.locator(_item(job_id)).count()
        else None
    )


def _progress(page: Any, job_id: int) -> int:
    bar = page.locator(f"{_item(job_id)} .progress")
    return int(bar.get_attribute("aria-valuenow") or 0) if bar.count() else -1


def test_a_job_is_followed_and_cancelled_from_any_page(live_server: Server, page: Any) -> None:
    page.goto(f"{live_server.url}/#/plan")
    page.wait_for_selector("#methods-fieldset")
    page.click("#jobs-button")
    page.wait_for_selector("#job-drawer:not([hidden])")

    # Submitted elsewhere (another tab, the CLI): it appears, then runs, with no reload.
    job = live_server.post("/api/plans", json=LONG).json()
    wait_for(lambda: _state(page, job["id"]) == "running", 120, "the job running in the drawer")
    assert page.inner_text("#jobs-count").strip() not in {"", "0"}
    assert "curtain_wall_6dof" in page.inner_text(_item(job["id"]))

    # Another page: the drawer is still there and still live (its progress moves).
    page.click('.tabs a[data-page="recordings"]')
    page.wait_for_selector("#upload-form")
    before = _progress(page, job["id"])
    wait_for(lambda: _progress(page, job["id"]) > before, 120, "the progress moving")

    # A reload: open again, with the job, which is cancelled from here.
    page.reload()
    page.wait_for_selector("#job-drawer:not([hidden])")
    wait_for(lambda: _state(page, job["id"]) == "running", 60, "the job after a reload")
    screenshot(page, "job-drawer")
    page.click(f"{_item(job['id'])} .job-cancel")
    wait_for(lambda: _state(page, job["id"]) == "cancelled", 60, "the cancelled state")
    assert live_server.get(f"/api/jobs/{job['id']}")["state"] == "cancelled"
    assert page.locator(f"{_item(job['id'])} .job-cancel").count() == 0


def test_a_finished_job_links_to_its_result(live_server: Server, page: Any) -> None:
    page.goto(f"{live_server.url}/#/recordings")
    page.wait_for_selector("#upload-form")
    if page.locator("#job-drawer[hidden]").count():
        page.click("#jobs-button")
    job = live_server.post("/api/plans", json=TINY).json()
    wait_for_jobs(live_server, lambda: _state(page, job["id"]) == "succeeded", "the job succeeding")
    # Its log (issue 24 item 6): what the planner said, as the API serves it.
    page.click(f"{_item(job['id'])} .job-log-toggle")
    log = page.wait_for_selector(f"{_item(job['id'])} pre.job-log:has-text('PSO of 8 particles')")
    assert log.inner_text().splitlines() == live_server.get(f"/api/jobs/{job['id']}/log")["lines"]
    page.click(f"{_item(job['id'])} .job-log-toggle")
    assert page.locator(f"{_item(job['id'])} pre.job-log").count() == 0
    page.click(f"{_item(job['id'])} a.job-open")
    page.wait_for_selector("#metrics-table", timeout=120_000)
    assert page.url.endswith(f"#/compare/plan/{job['id']}")
    page.click("#job-drawer-close")
    assert page.locator("#job-drawer[hidden]").count() == 1


# ---- issue 29 item 2: a researcher's findings in a real browser -----------------------------

SWEEP = {
    "robot": "human_arm_2dof",
    "payloads": [0.0],
    "objectives": ["abs_work"],
    "methods": ["quintic", "paper"],
    "particles": 6,
    "iterations": 4,
}


def _finished(server: Server, job_id: int) -> None:
    wait_for(
        lambda: server.get(f"/api/jobs/{job_id}")["state"] == "succeeded", 300, f"job {job_id}"
    )


def test_a_sweeps_heat_maps_open_from_the_drawer(live_server: Server, page: Any) -> None:
    """The drawer's "Heat maps →" opened the newest comparison (another robot's, without heat
    maps), and only a robot's newest sweep could be viewed: each sweep now has its URL."""
    older = live_server.post("/api/sweeps", json={**SWEEP, "durations": [1.0]}).json()
    newer = live_server.post("/api/sweeps", json={**SWEEP, "durations": [1.5]}).json()
    _finished(live_server, older["id"])
    _finished(live_server, newer["id"])
    plan = live_server.post("/api/plans", json={**TINY, "robot": "curtain_wall_6dof"}).json()
    _finished(live_server, plan["id"])  # the newest comparison is another robot's
    page.goto(f"{live_server.url}/#/recordings")
    page.wait_for_selector("#upload-form")
    if page.locator("#job-drawer[hidden]").count():
        page.click("#jobs-button")
    wait_for(lambda: _state(page, older["id"]) == "succeeded", 60, "the sweep in the drawer")
    page.click(f"{_item(older['id'])} a.job-open")
    page.wait_for_selector("#sweep-card", timeout=120_000)
    assert f"Sweep #{older['id']}:" in page.inner_text("#sweep-card")  # not the newer one
    assert page.url.endswith(f"#/compare?sweep={older['id']}")
    z = "document.getElementById('sweep-plot')?.data?.[0]?.z"
    wait_for(lambda: page.evaluate(z), 60, "the heat map")
    table = live_server.get(f"/api/sweeps/{older['id']}")["result"]["tables"]["abs_work"]
    assert page.evaluate(z) == table["abs_work"]["change_pct"]  # that sweep's cells
    assert page.evaluate("document.getElementById('sweep-plot').data[0].y") == ["1 s"]


def test_the_drawer_shows_labels_and_closes_with_escape(live_server: Server, page: Any) -> None:
    page.goto(f"{live_server.url}/#/recordings")
    page.wait_for_selector("#upload-form")
    if page.locator("#job-drawer[hidden]").count():
        page.click("#jobs-button")
    job = live_server.post("/api/plans", json={**TINY, "label": "heavy and slow"}).json()
    wait_for(lambda: _state(page, job["id"]) is not None, 60, "the job in the drawer")
    assert "heavy and slow" in page.inner_text(_item(job["id"]))
    page.keyboard.press("Escape")
    page.wait_for_selector("#job-drawer[hidden]", state="attached", timeout=10_000)
    assert page.get_attribute("#jobs-button", "aria-expanded") == "false"


def test_a_running_plan_is_followed_from_the_drawer(live_server: Server, page: Any) -> None:
    """A running plan in the drawer links to its progress and convergence on the Plan page."""
    page.goto(f"{live_server.url}/#/recordings")
    page.wait_for_selector("#upload-form")
    if page.locator("#job-drawer[hidden]").count():
        page.click("#jobs-button")
    job = live_server.post("/api/plans", json=LONG).json()
    wait_for(lambda: _state(page, job["id"]) == "running", 120, "the job running")
    page.click(f"{_item(job['id'])} a.job-follow")
    wait_for(lambda: f"#{job['id']}" in page.inner_text("#job-card"), 60, "its progress panel")
    assert page.locator("#convergence-plot").count() == 1
    # Cancelled from there (its PSO may also stop early, when the swarm stops improving).
    page.keyboard.press("Escape")  # the drawer covers the panel's Cancel on a narrow window
    page.wait_for_selector("#job-drawer[hidden]", state="attached", timeout=10_000)
    if live_server.get(f"/api/jobs/{job['id']}")["state"] == "running":
        page.click("#cancel-job", timeout=30_000)
    wait_for(lambda: page.is_hidden("#cancel-job"), 60, "the job's end shown")
