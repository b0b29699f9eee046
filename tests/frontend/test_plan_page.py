"""The Plan page: a real third-party robot added from the page (UR5 from example-robot-data),
the methods and the human constraint reaching the job, the convergence curve that never rises."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.frontend.test_browser import wait_for, wait_for_jobs
from tests.utils.browser import screenshot
from tests.utils.example_robots import UR5, robot_file
from tests.utils.server import Server

SIDECAR = Path(__file__).resolve().parents[2] / "docs" / "examples" / "ur5.sidecar.yaml"


def _open_upload(page: Any, server: Server) -> None:
    page.goto(f"{server.url}/#/plan")
    page.wait_for_selector("#robot-upload-card")
    page.click("#robot-upload-card summary")


def test_add_a_ur5_from_the_plan_page(live_server: Server, page: Any) -> None:
    urdf = robot_file(UR5)
    _open_upload(page, live_server)
    page.set_input_files("#robot-model", str(urdf))
    # The joints are read from the file in the browser and offered by name.
    wait_for(lambda: "elbow_joint" in page.inner_text("#robot-joints-found"), 30, "the joints")
    offered = page.eval_on_selector_all("#robot-joint-names option", "os => os.map(o => o.value)")
    assert {"shoulder_lift_joint", "elbow_joint", "wrist_3_joint"} <= set(offered)

    # A wrong joint: the server's message, in the form's words, listing the robot's joints.
    page.fill("#robot-name", "ur5_wrong")
    page.fill("#robot-elbow", "nope")
    page.click("#robot-upload")
    wait_for(lambda: "Elbow joint" in page.inner_text("#robot-upload-status"), 120, "the refusal")
    refusal = page.inner_text("#robot-upload-status")
    assert "nope" in refusal and "shoulder_lift_joint" in refusal, refusal
    assert all(r["name"] != "ur5_wrong" for r in live_server.get("/api/robots"))

    page.fill("#robot-name", "ur5_page")
    page.fill("#robot-shoulder", "shoulder_lift_joint")
    page.fill("#robot-elbow", "elbow_joint")
    page.click("#robot-add-lock")
    page.fill(".lock-joint", "wrist_3_joint")
    page.fill(".lock-value", "30")
    page.set_input_files("#robot-sidecar", str(SIDECAR))
    page.click("#robot-upload")
    wait_for(lambda: "Added ur5_page" in page.inner_text("#robot-upload-status"), 120, "the robot")
    stored = live_server.get("/api/robots/ur5_page")
    assert "wrist_3_joint" not in stored["joint_names"]  # locked, so not planned
    assert len(stored["joint_names"]) == 5
    assert page.eval_on_selector("#robot", "s => s.value") == "ur5_page"  # ready to plan
    assert "5 joints" in page.inner_text("#robot-info")
    screenshot(page, "plan-robot-added")


def _human_arm_without_slow_methods(page: Any, server: Server) -> None:
    """The Plan page on the human arm, with the two slowest methods unchecked."""
    page.goto(f"{server.url}/#/plan")
    page.wait_for_selector("#methods-fieldset")
    page.select_option("#robot", "human_arm_2dof")
    for method in ("human_optimal", "jerk_limited"):
        page.uncheck(f'#methods-fieldset input[data-method="{method}"]')


def test_methods_and_constraint_reach_the_job(live_server: Server, page: Any) -> None:
    _human_arm_without_slow_methods(page, live_server)
    page.select_option("#kind", "plan")
    assert page.is_disabled('#methods-fieldset input[data-method="quintic"]')
    page.select_option("#human-constraint", "phases")
    page.fill("#particles", "6")
    page.fill("#iterations", "5")
    page.click("#submit-plan")
    page.wait_for_selector("#open-compare", timeout=180_000)
    plan_id = int((page.get_attribute("#open-compare", "href") or "").rsplit("/", 1)[-1])
    job = live_server.get(f"/api/jobs/{plan_id}")
    assert job["params"]["methods"] == ["quintic", "paper", "bound"]
    assert job["params"]["human_constraint"] == "phases"
    assert list(live_server.get(f"/api/plans/{plan_id}")["result"]["methods"]) == [
        "quintic", "paper", "bound",
    ]  # fmt: skip


def test_the_best_so_far_never_rises(live_server: Server, page: Any) -> None:
    """A stage that reports a worse value than before (as optimal control's iterations can)
    must not draw a rising "best so far"."""
    page.goto(f"{live_server.url}/#/plan")
    page.wait_for_selector("#plan-form")
    ys = page.evaluate(
        """async () => {
            const { addProgressPoint } = await import('/js/plan.js');
            const curves = {};
            [[1, 5], [2, 3], [3, 4], [3, 1], [4, 2.5], [5, 2]].forEach(([done, best]) =>
                addProgressPoint(curves, { stage: 'pso', done, best }));
            return curves.pso.y;
        }"""
    )
    assert ys == [5, 3, 3, 2.5, 2]


def test_a_sweep_from_the_page_with_heat_maps_per_method(live_server: Server, page: Any) -> None:
    """Issue 15 item 5: sweeps could not be started from the page. The grid, methods and
    objective reach the job, progress is given per cell, and Compare draws a heat map per
    method beside a comparison of the same robot."""
    tiny = {
        "robot": "human_arm_2dof",
        "particles": 8,
        "iterations": 5,
        "methods": ["quintic", "paper"],
    }
    plan = live_server.post("/api/plans", json=tiny).json()  # a comparison of the same robot
    _human_arm_without_slow_methods(page, live_server)
    page.select_option("#objective", "tau_sq")
    page.fill("#particles", "8")
    page.fill("#iterations", "5")
    page.fill("#sweep-durations", "1 x")
    page.click("#submit-sweep")
    assert '"x" is not a number' in page.inner_text("#sweep-status")  # said before any request
    page.fill("#sweep-durations", "1, 1.5")
    page.fill("#sweep-payloads", "0")
    page.click("#submit-sweep")
    wait_for(lambda: "cell " in page.inner_text("#sweep-cells"), 120, "progress per cell")
    page.wait_for_selector("#open-sweep, #sweep-status .banner", timeout=300_000)
    assert page.locator("#open-sweep").count(), page.inner_text("#sweep-status")
    sweep = live_server.get("/api/sweeps?limit=1")["items"][0]
    params = sweep["job"]["params"]
    assert params["durations"] == [1.0, 1.5] and params["payloads"] == [0.0]
    assert params["objectives"] == ["tau_sq"] and params["methods"] == ["quintic", "paper", "bound"]
    assert "cell 2 of 2" in page.inner_text("#sweep-cells")
    assert live_server.get(f"/api/jobs/{plan['id']}")["state"] == "succeeded"

    page.click("#open-sweep")
    page.wait_for_selector("#sweep-card", timeout=120_000)
    assert f"Sweep #{sweep['id']}" in page.inner_text("#sweep-card")
    methods = page.eval_on_selector_all("#sweep-method option", "os => os.map(o => o.value)")
    assert methods == ["paper", "bound"]
    z = "document.getElementById('sweep-plot').data[0].z"
    wait_for(lambda: page.evaluate(z), 60, "the heat map")
    cells = sweep["result"]["cells"]
    by_duration = sorted(cells, key=lambda c: c["duration"])  # rows: durations; one payload
    expected = {m: [c["methods_change_pct"][m]["tau_sq"] for c in by_duration] for m in methods}

    def drawn() -> list[float]:
        return [row[0] for row in page.evaluate(z)]

    assert drawn() == pytest.approx(expected["paper"])
    page.select_option("#sweep-method", "bound")
    wait_for(lambda: page.get_attribute("#sweep-plot", "data-method") == "bound", 30, "bound")
    assert drawn() == pytest.approx(expected["bound"])
    assert expected["bound"] != pytest.approx(expected["paper"])


def test_a_refusal_is_shown_at_the_top_in_the_forms_words(live_server: Server, page: Any) -> None:
    """Issue 15: errors used the API's field names and sat at the bottom of the form."""
    page.goto(f"{live_server.url}/#/plan")
    page.wait_for_selector("#plan-form")
    page.fill("#particles", "1")
    page.click("#submit-plan")
    banner = "#plan-form .banner.error"
    page.wait_for_selector(banner, timeout=60_000)
    text = page.inner_text(banner)
    assert text.startswith("Particles:") and "particles" not in text, text
    assert page.locator(banner).bounding_box()["y"] < page.locator("#robot").bounding_box()["y"]


def test_templates_are_named_by_their_recording(live_server: Server, page: Any) -> None:
    """Issue 15: templates were named only by ids, and a deleted recording's analysis showed
    "recording #null". A template names its recording's label, subject and task; a deleted
    one says so."""
    from app.services.demo import DEMO_SUBJECT, synthetic_curls_csv
    from tests.frontend.test_browser import post_files

    status, rec = post_files(live_server, [("gone.csv", synthetic_curls_csv())])
    assert status == 201
    job = live_server.post("/api/analyses", json={"recording_id": rec["id"]}).json()
    wait_for(
        lambda: live_server.get(f"/api/jobs/{job['id']}")["state"] == "succeeded", 180, "analysis"
    )
    assert httpx.delete(f"{live_server.url}/api/recordings/{rec['id']}").status_code == 204
    page.goto(f"{live_server.url}/#/plan")
    page.wait_for_selector("#template")
    options = page.eval_on_selector_all("#template option", "os => os.map(o => o.textContent)")
    assert any(DEMO_SUBJECT in o for o in options), options
    gone = [o for o in options if o.startswith(f"analysis #{job['id']} ")]
    assert gone and "a deleted recording" in gone[0], options
    assert not any("#null" in o for o in options)


# ---- issue 29 item 2: a researcher's findings in a real browser -----------------------------

LONG_PLAN = {"particles": "400", "iterations": "2000"}


def _convergence_points(page: Any) -> int:
    return int(
        page.evaluate(
            "() => { const d = document.getElementById('convergence-plot')?.data || [];"
            " return d.reduce((n, t) => n + t.x.length, 0); }"
        )
    )


def test_the_form_and_the_running_plan_survive_leaving_and_reload(
    live_server: Server, page: Any
) -> None:
    """Leaving or reloading the Plan page emptied its progress panel and reset the form; the
    running job could be followed only in the drawer, without its convergence curve."""
    page.goto(f"{live_server.url}/#/plan")
    page.wait_for_selector("#methods-fieldset")
    page.select_option("#robot", "curtain_wall_6dof")
    page.select_option("#kind", "plan")
    for method in ("human_optimal", "jerk_limited", "bound"):
        page.uncheck(f'#methods-fieldset input[data-method="{method}"]')
    page.fill("#duration", "1.5")
    page.fill("#plan-label", "kept across pages")
    page.fill("#particles", LONG_PLAN["particles"])
    page.fill("#iterations", LONG_PLAN["iterations"])
    page.click("#submit-plan")
    page.wait_for_selector("#job-card h2:has-text('#'), #plan-form .banner.error", timeout=60_000)
    assert page.locator("#plan-form .banner.error").count() == 0, page.inner_text("#plan-form")
    job_id = int(page.inner_text("#job-card h2").split("#")[1])
    wait_for_jobs(
        live_server, lambda: _convergence_points(page) >= 2, "the convergence curve growing"
    )

    def kept() -> None:
        page.wait_for_selector("#plan-form")
        assert page.input_value("#robot") == "curtain_wall_6dof"
        assert page.input_value("#kind") == "plan"
        assert page.input_value("#duration") == "1.5"
        assert page.input_value("#plan-label") == "kept across pages"
        assert page.input_value("#iterations") == LONG_PLAN["iterations"]
        assert not page.is_checked('#methods-fieldset input[data-method="bound"]')
        wait_for(lambda: f"#{job_id}" in page.inner_text("#job-card"), 60, "the job re-attached")
        wait_for(lambda: _convergence_points(page) >= 2, 60, "the curve kept")

    page.click('.tabs a[data-page="recordings"]')
    page.wait_for_selector("#upload-form")
    page.click('.tabs a[data-page="plan"]')
    kept()
    page.reload()
    kept()
    # Cancelled from the re-attached panel (its PSO may also stop early on its own).
    if live_server.get(f"/api/jobs/{job_id}")["state"] == "running":
        page.click("#cancel-job", timeout=30_000)
    wait_for(lambda: page.is_hidden("#cancel-job"), 60, "the job's end shown")
    assert live_server.get(f"/api/jobs/{job_id}")["state"] in {"cancelled", "succeeded"}
    screenshot(page, "plan-reattached")


def test_an_analysis_without_lifts_is_not_offered_as_a_template(
    live_server: Server, page: Any
) -> None:
    """A wrong-rate analysis (0 or 1 spurious lift) was offered as a template, described like
    the right one."""
    from tests.frontend.test_browser import post_files
    from tests.utils.data import shared_file

    nt = shared_file("noraxon_curls_biceps_brachioradialis/NT-01.mat")
    status, rec = post_files(live_server, [(nt.name, nt.read_bytes())])
    assert status == 201, rec
    job = live_server.post("/api/analyses", json={"recording_id": rec["id"]}).json()
    wait_for(
        lambda: live_server.get(f"/api/jobs/{job['id']}")["state"] == "succeeded", 180, "analysis"
    )
    summary = live_server.get(f"/api/analyses/{job['id']}")["summary"]
    assert summary["files"][0]["rate_check"], summary  # run at the stored 20 kHz
    page.goto(f"{live_server.url}/#/plan")
    page.wait_for_selector("#template")
    values = page.eval_on_selector_all("#template option", "os => os.map(o => o.value)")
    assert str(job["id"]) not in values
    assert "wrong-looking EMG rate" in page.inner_text("#template-hidden")
    # Asked for by a link, it is there, saying what it is.
    page.goto(f"{live_server.url}/#/plan?analysis={job['id']}")
    page.wait_for_selector(f'#template option[value="{job["id"]}"]', state="attached")
    text = page.inner_text(f'#template option[value="{job["id"]}"]')
    assert "wrong-looking EMG rate" in text and "not a template" in text, text
    others = page.eval_on_selector_all(
        "#template option[data-lifts]", "os => os.map(o => o.textContent)"
    )
    assert all("lift" in o for o in others), others


def test_a_robot_name_with_a_space_is_refused_in_words(live_server: Server, page: Any) -> None:
    """A name with a space got the server's regular expression as its message."""
    _open_upload(page, live_server)
    page.set_input_files("#robot-model", str(robot_file(UR5)))
    page.fill("#robot-name", "my robot")
    page.click("#robot-upload")
    wait_for(lambda: "Name" in page.inner_text("#robot-upload-status"), 60, "the refusal")
    text = page.inner_text("#robot-upload-status")
    assert "no spaces" in text and "my_robot" in text, text
    assert "pattern" not in text and "^[" not in text, text
