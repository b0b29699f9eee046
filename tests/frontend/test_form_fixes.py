"""Issue 29's remaining browser findings, in a real browser: the image-size note's one-click
fix, caps shown beside their fields and a cap error seen (not hidden under the sticky top bar),
every error of a request at once in the form's words, and a condition taken from BIDS file
names said to be so."""

from __future__ import annotations

import time
from typing import Any

import httpx

from tests.frontend.test_browser import wait_for
from tests.utils.browser import screenshot
from tests.utils.data import SHARED_DATA, shared_file
from tests.utils.server import Server

LANDMARKS = "mediapipe_bicep_curl_frames/test.csv"
TOPBAR_PX = 52  # .topbar's height (style.css)


def _upload(server: Server, files: list[tuple[str, bytes]], **form: str) -> dict[str, Any]:
    r = server.post("/api/recordings", files=[("files", f) for f in files], data=form)
    assert r.status_code == 201, r.text
    body: dict[str, Any] = r.json()
    return body


def _analyses(server: Server, rid: int) -> list[dict[str, Any]]:
    items: list[dict[str, Any]] = server.get(f"/api/analyses?recording_id={rid}&limit=50")["items"]
    return items


def _finished(server: Server, job_id: int, timeout: float = 240.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job: dict[str, Any] = server.get(f"/api/jobs/{job_id}")
        if job["state"] in ("succeeded", "failed", "cancelled"):
            return job
        time.sleep(0.3)
    raise AssertionError(f"job {job_id} did not end in {timeout} s")


def _below_topbar_and_visible(page: Any, selector: str) -> bool:
    box = page.evaluate(
        f"(() => {{ const r = document.querySelector({selector!r}).getBoundingClientRect();"
        " return [r.top, r.bottom, window.innerHeight]; })()"
    )
    top, bottom, height = box
    return bool(top >= TOPBAR_PX and bottom <= height)


def test_the_image_size_note_has_a_one_click_fix(live_server: Server, page: Any) -> None:
    """Normalised landmarks without the video's size: the note said "--image-size W H" (the
    CLI's words) and offered no fix. A button now sets the size and re-analyses, and the
    angles change with it (x is scaled by width / height)."""
    data = shared_file(LANDMARKS).read_bytes()
    rec = _upload(live_server, [("curl_landmarks.csv", data)], frame_rate="30")
    rid = rec["id"]
    page.goto(f"{live_server.url}/#/recordings/{rid}")
    page.wait_for_selector("#image-size-fix", timeout=240_000)
    note = page.inner_text("#analysis-warnings")
    assert "--image-size" not in note and "only its aspect ratio matters" in note, note
    (before,) = _analyses(live_server, rid)
    old_peak = live_server.get(f"/api/analyses/{before['id']}")["result"]["template"]
    page.click("#image-size-1280x720")
    wait_for(
        lambda: "Image size set to 1280 × 720 px" in page.inner_text("#app"), 60, "the fix applied"
    )
    stored = live_server.get(f"/api/recordings/{rid}")
    assert stored["options"]["image_size"] == [1280, 720]

    def newer() -> dict[str, Any] | None:
        items = _analyses(live_server, rid)
        return items[0] if len(items) > 1 else None

    job = _finished(live_server, wait_for(newer, 60, "the new analysis")["id"])
    assert job["state"] == "succeeded", job
    after = live_server.get(f"/api/analyses/{job['id']}")["result"]
    assert not any("video size unknown" in w for w in after["warnings"])
    assert after["template"] != old_peak  # the angles are those of a 16:9 frame now
    # The page draws the new analysis in place: no note, so no fix offered.
    wait_for(
        lambda: page.get_attribute("#lifts", "data-analysis") == str(job["id"]),
        120,
        "the new analysis drawn",
    )
    assert page.locator("#image-size-fix").count() == 0
    screenshot(page, "image-size-fixed")


def test_caps_are_shown_and_a_cap_error_is_seen_beside_its_field(
    live_server: Server, browser: Any
) -> None:
    from tests.utils.browser import new_context

    caps = live_server.get("/api/caps")["plan"]
    context = new_context(browser, viewport={"width": 1280, "height": 640})
    try:
        page = context.new_page()
        page.goto(f"{live_server.url}/#/plan")
        page.wait_for_selector("#plan-form label[for='particles'] .cap")
        # Each capped field shows the server's cap (BIOPLAN_MAX_PARTICLES: 400 by default,
        # where the page's own attribute said 1000).
        for field, el in (("particles", "particles"), ("iterations", "iterations")):
            cap = caps[field]["maximum"]
            assert page.get_attribute(f"#{el}", "max") == f"{cap:g}"
            assert f"max {cap:,.0f}" in page.inner_text(f"label[for='{el}']")
        assert "max 600" in page.inner_text("label[for='duration']")
        page.fill("#particles", str(int(caps["particles"]["maximum"]) + 100))
        page.evaluate("window.scrollTo(0, document.body.scrollHeight)")
        page.click("#submit-plan")
        page.wait_for_selector("#particles + .field-error", timeout=60_000)
        beside = page.inner_text("#particles + .field-error")
        assert beside.startswith("Particles:") and "400" in beside, beside
        assert page.get_attribute("#particles", "aria-invalid") == "true"
        # Seen: the message beside the field lies below the sticky top bar, in the window.
        assert _below_topbar_and_visible(page, "#particles + .field-error")
        screenshot(page, "plan-cap-error", full_page=False)
        # Corrected and sent again: the mark goes.
        page.fill("#particles", "20")
        page.fill("#iterations", "5")
        page.fill("#duration", "700")
        page.click("#submit-plan")
        page.wait_for_selector("#duration + .field-error", timeout=60_000)
        assert page.locator("#particles + .field-error").count() == 0
        assert _below_topbar_and_visible(page, "#duration + .field-error")
    finally:
        context.close()


def test_every_error_of_a_request_at_once_in_the_forms_words(
    live_server: Server, page: Any
) -> None:
    """Two fields the server refuses: both are said, each by the form's label, in one go."""
    page.goto(f"{live_server.url}/#/plan")
    page.wait_for_selector("#plan-form")
    page.fill("#duration", "700")
    page.fill("#peak-angle", "200")
    page.click("#submit-plan")
    page.wait_for_selector("#plan-form ul.form-errors", timeout=60_000)
    items = page.eval_on_selector_all(
        "#plan-form ul.form-errors li", "ls => ls.map(l => l.innerText)"
    )
    assert len(items) == 2, items
    assert items[0].startswith("Duration:") and items[1].startswith("Elbow peak angle:"), items
    text = page.inner_text("#plan-form .banner.error")
    assert "2 fields need a change" in text
    assert "duration" not in text and "peak_angle_deg" not in text
    assert page.locator("#duration + .field-error").count() == 1
    assert page.locator("#peak-angle + .field-error").count() == 1

    # The upload form: the EMG rate and the load, both refused, both named in its words.
    page.goto(f"{live_server.url}/#/recordings")
    page.wait_for_selector("#upload-form")
    page.wait_for_selector("label[for='load'] .cap")  # the server's 100 kg, not the page's 500
    assert "max 100" in page.inner_text("label[for='load']")
    page.set_input_files("#file-input", str(shared_file(LANDMARKS)))
    page.click("#upload-form details summary")
    page.fill("#emg-rate", "5")
    page.fill("#load", "150")
    page.click("#upload-button")
    page.wait_for_selector("#upload-error ul.form-errors", timeout=60_000)
    items = page.eval_on_selector_all(
        "#upload-error ul.form-errors li", "ls => ls.map(l => l.innerText)"
    )
    assert sorted(i.split(":")[0] for i in items) == ["EMG rate", "Load"], items
    assert "emg_rate" not in page.inner_text("#upload-error")
    assert page.locator("#emg-rate + .field-error").count() == 1


def test_a_condition_from_bids_names_says_where_it_came_from(
    live_server: Server, page: Any
) -> None:
    folder = SHARED_DATA / "edf_emg_bids_examples/emg_CustomBipolar"
    stem = "sub-01_task-holdWeight"
    planted = "sub-07_task-curl_acq-supinated"
    files = [
        (f"{planted}{s}", (folder / f"{stem}{s}").read_bytes())
        for s in ("_emg.edf", "_channels.tsv", "_emg.json")
    ]
    rec = _upload(live_server, files)
    assert rec["condition"] == "supinated"
    page.goto(f"{live_server.url}/#/recordings/{rec['id']}")
    page.wait_for_selector("#rec-condition")
    assert page.input_value("#rec-condition") == "supinated"
    said = page.inner_text("#rec-condition-status")
    assert said == f"from the acq-supinated (BIDS acquisition) entity of {planted}_emg.edf"
    page.fill("#rec-condition", "neutral")
    page.click("#condition-form button[type=submit]")
    wait_for(lambda: "saved: neutral" in page.inner_text("#rec-condition-status"), 30, "saved")
    now = httpx.get(f"{live_server.url}/api/recordings/{rec['id']}", timeout=30).json()
    assert now["condition"] == "neutral" and "condition_from" not in now["options"]
