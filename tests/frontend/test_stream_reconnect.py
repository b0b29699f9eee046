"""Security finding 4, the page's side: event streams now end after ``BIOPLAN_STREAM_IDLE_S``
and are refused (429) beyond ``BIOPLAN_MAX_STREAMS_PER_CLIENT``. In a real Chromium: the job
drawer's ``EventSource`` reconnects after an idle end and stays live; a drawer whose stream was
refused polls, and takes the stream again once a place is free."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tests.frontend.test_browser import wait_for, wait_for_jobs
from tests.utils.browser import new_context
from tests.utils.server import Server

TINY = {"robot": "human_arm_2dof", "particles": 8, "iterations": 5, "methods": ["quintic", "paper"]}


def _open_drawer(
    chromium: Any, server: Server, *, fake_clock: bool = False
) -> tuple[Any, Any, list[str]]:
    """A page of the dashboard with its job drawer open; the stream requests it makes.
    ``fake_clock``: the page's timers run on Playwright's clock, moved on by the test."""
    context = new_context(chromium, viewport={"width": 1280, "height": 800})
    page = context.new_page()
    if fake_clock:
        page.clock.install()
    streams: list[str] = []
    page.on("request", lambda r: streams.append(r.url) if "/api/events/jobs" in r.url else None)
    page.goto(f"{server.url}/#/recordings")
    page.wait_for_selector("#upload-form")
    if page.locator("#job-drawer[hidden]").count():
        page.click("#jobs-button")
    page.wait_for_selector("#job-drawer:not([hidden])")
    return context, page, streams


def _state(page: Any, job_id: int) -> str | None:
    item = f'#job-list li[data-job-id="{job_id}"]'
    return page.get_attribute(item, "data-state") if page.locator(item).count() else None


def test_the_drawer_reconnects_after_an_idle_end(chromium: Any, tmp_path: Path) -> None:
    server = Server(tmp_path / "data", BIOPLAN_STREAM_IDLE_S="2")
    server.start()
    try:
        context, page, streams = _open_drawer(chromium, server)
        try:
            # (A call into the page lets Playwright deliver the request events meanwhile.)
            wait_for(
                lambda: page.evaluate("1") and len(streams) >= 3,
                120,
                "the stream ended and reopened twice",
            )
            job = server.post("/api/plans", json=TINY).json()
            wait_for_jobs(server, lambda: _state(page, job["id"]) == "succeeded", "the job, live")
            assert page.inner_text("#job-drawer-note").strip() == ""
        finally:
            context.close()
    finally:
        server.cleanup()


def test_a_refused_drawer_polls_then_takes_the_stream_again(chromium: Any, tmp_path: Path) -> None:
    server = Server(tmp_path / "data", BIOPLAN_MAX_STREAMS_PER_CLIENT="1")
    server.start()
    try:
        first, _, _ = _open_drawer(chromium, server)
        # The same client: refused. Its polls (every 5 s) and its retry of the stream (a minute
        # later) run on a fake clock the test moves on, instead of waiting a real minute.
        second, page, _ = _open_drawer(chromium, server, fake_clock=True)

        def after(ms: int, done: Any) -> Any:
            return lambda: page.clock.run_for(ms) or done()

        try:
            note = "#job-drawer-note"
            wait_for(lambda: "unavailable" in page.inner_text(note), 60, "the refusal said")
            job = server.post("/api/plans", json=TINY).json()
            polled = after(5_000, lambda: _state(page, job["id"]) == "succeeded")
            wait_for_jobs(server, polled, "the job, by polling")
            assert "unavailable" in page.inner_text(note)  # still polling, not streaming
            first.close()  # a place is free: the drawer takes the stream again
            wait_for(after(60_000, lambda: page.inner_text(note).strip() == ""), 180, "the stream")
        finally:
            second.close()
    finally:
        server.cleanup()
