"""Issue 15 item 4: a running job could be neither followed nor cancelled after leaving the
Plan page, and the recent jobs table did not refresh. The job drawer is on every page, updated
live from ``GET /api/events/jobs``, and survives navigation and reload."""

from __future__ import annotations

from typing import Any

from tests.frontend.test_browser import wait_for
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
    wait_for(lambda: _state(page, job["id"]) == "succeeded", 180, "the job succeeding")
    page.click(f"{_item(job['id'])} a.job-open")
    page.wait_for_selector("#metrics-table", timeout=120_000)
    assert page.url.endswith(f"#/compare/plan/{job['id']}")
    page.click("#job-drawer-close")
    assert page.locator("#job-drawer[hidden]").count() == 1
