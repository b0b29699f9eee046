"""Two bugs the JavaScript type check (tests/frontend/test_typecheck.py) found, shown fixed in a
real browser. The server's real answers are fed to the page with the one field that triggers
each bug changed (Playwright's routing), as a stored result can hold it:

- a cohort result without warnings: the page appended ``null`` to the result, which the DOM
  shows as the text "null" under the plots;
- a plan whose safety check ran but found no pair near (``min_clearance`` null, as
  app/planning/safety.py reports an infinite clearance): the Compare card said
  "min clearance 0 mm", a touching robot, where the server's own summary says "n/a".
"""

from __future__ import annotations

import json
import time
import uuid
from typing import Any

from app.services.demo import synthetic_curls_csv
from tests.frontend.test_browser import demo_ids
from tests.frontend.test_cohort_page import _upload
from tests.utils.server import Server


def _cohort(server: Server) -> dict[str, Any]:
    """A finished cohort of two uploaded recordings, one per group, as GET /api/cohorts/{id}."""
    tag = uuid.uuid4().hex[:6]
    a = _upload(server, f"a_{tag}.csv", synthetic_curls_csv(lifts=2, seed=3), f"a-{tag}")
    b = _upload(server, f"b_{tag}.csv", synthetic_curls_csv(lifts=2, seed=4, up=0.9), f"b-{tag}")
    r = server.post("/api/cohorts", json={"groups": {f"a-{tag}": [a], f"b-{tag}": [b]}})
    assert r.status_code == 202, r.text
    cid = r.json()["id"]
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        out: dict[str, Any] = server.get(f"/api/cohorts/{cid}")
        if out["job"]["state"] not in ("queued", "running"):
            assert out["job"]["state"] == "succeeded", out["job"]
            return out
        time.sleep(0.5)
    raise AssertionError(f"cohort #{cid} did not finish in 300 s")


def test_a_cohort_without_warnings_shows_no_null(live_server: Server, page: Any) -> None:
    out = _cohort(live_server)
    cid = out["id"]
    quiet = {**out, "result": {**out["result"], "warnings": []}}
    page.route(
        lambda url: url == f"{live_server.url}/api/cohorts/{cid}",
        lambda route: route.fulfill(
            status=200, content_type="application/json", body=json.dumps(quiet)
        ),
    )
    page.goto(f"{live_server.url}/#/cohort/{cid}")
    page.wait_for_selector("#cohort-orders")
    texts = page.evaluate(
        "() => [...document.getElementById('cohort-result').childNodes]"
        ".filter((n) => n.nodeType === Node.TEXT_NODE).map((n) => n.textContent)"
    )
    assert "null" not in texts, texts
    assert not page.inner_text("#cohort-result").rstrip().endswith("null")
    # No warnings, no warnings card; the rest of the result is drawn as before.
    assert page.locator("#cohort-result > details").count() == 0
    assert page.locator("#cohort-groups").count() == 1


def test_a_safety_check_without_a_clearance_says_n_a(live_server: Server, page: Any) -> None:
    plan = demo_ids(live_server)["plan"]
    real = live_server.get(f"/api/viewer/comparisons/plan/{plan}?points=10")["result"]["safety"]
    assert real["checked"] is True and real["findings"] == []

    def no_clearance(route: Any) -> None:
        response = route.fetch()
        body = response.json()
        body["result"]["safety"]["min_clearance"] = None
        route.fulfill(response=response, body=json.dumps(body))

    base = f"{live_server.url}/api/viewer/comparisons/plan/{plan}?"
    page.route(lambda url: url.startswith(base), no_clearance)
    page.goto(f"{live_server.url}/#/compare/plan/{plan}")
    page.wait_for_selector("#plan-safety")
    assert page.inner_text("#plan-safety") == "ok, min clearance n/a"
