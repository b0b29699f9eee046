"""The Cohort page in a real browser (issue 29 item 1): two uploaded recordings with their
conditions, compared by condition from the page; the group table, the tests (here one
recording per group: "not tested: too few") and the CSV link are shown as the server computed
them."""

from __future__ import annotations

import uuid
from typing import Any

import httpx

from app.services.demo import synthetic_curls_csv
from tests.frontend.test_browser import wait_for
from tests.utils.browser import screenshot
from tests.utils.server import Server


def _upload(server: Server, name: str, data: bytes, condition: str) -> int:
    r = httpx.post(
        f"{server.url}/api/recordings",
        files=[("files", (name, data))],
        data={"condition": condition},
        timeout=120,
    )
    assert r.status_code == 201, r.text
    rid: int = r.json()["id"]
    return rid


def test_a_cohort_from_two_conditions(live_server: Server, page: Any) -> None:
    tag = uuid.uuid4().hex[:6]
    light, heavy = f"light-{tag}", f"heavy-{tag}"
    a = _upload(live_server, f"a_{tag}.csv", synthetic_curls_csv(lifts=2, seed=1), light)
    b = _upload(live_server, f"b_{tag}.csv", synthetic_curls_csv(lifts=2, seed=2, up=0.9), heavy)

    page.goto(f"{live_server.url}/#/cohort")
    page.wait_for_selector("#cohort-form")
    wait_for(lambda: page.locator(f'#cohort-recordings tr[data-id="{b}"]').count(), 30, "rows")
    # Only these two: every other recording is left out.
    boxes = page.locator("#cohort-recordings input.group-pick")
    for i in range(boxes.count()):
        box = boxes.nth(i)
        if box.is_enabled() and int(box.get_attribute("data-id")) not in (a, b):
            box.uncheck()
    assert page.is_checked(f'#cohort-recordings input[data-id="{a}"]')
    assert page.is_checked(f'#cohort-recordings input[data-id="{b}"]')
    page.select_option("#opt-correction", "fdr_bh")
    page.click("#cohort-submit")

    page.wait_for_selector("#cohort-groups", timeout=300_000)
    head = page.inner_text("#cohort-groups thead")
    assert f"{light} (n = 1)" in head and f"{heavy} (n = 1)" in head
    assert "±" in page.inner_text("#cohort-groups tbody")
    assert "Benjamini-Hochberg" in page.inner_text("#cohort-correction")
    tests = page.inner_text("#cohort-tests")
    assert "too few" in tests or page.locator("#cohort-tests .p-value").count()
    href = page.get_attribute("#cohort-csv", "href")
    cohort_id = int(page.url.rsplit("/", 1)[-1])
    assert href == f"/api/cohorts/{cohort_id}/csv"
    rows = httpx.get(live_server.url + href, timeout=60).text.strip().splitlines()
    assert len(rows) == 3 and rows[1].startswith(f"{a},{light},")
    wait_for(lambda: page.locator("#cohort-plots .cohort-plot .main-svg").count(), 60, "plots")
    assert page.inner_text("#cohort-orders")
    screenshot(page, "cohort_result")
