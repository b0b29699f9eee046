"""The Validate page in a real browser (issue 28 item 4): a robot log uploaded from the page for
an uploaded arm; the measured and predicted torque of every joint are plotted as the server
computed them, and a bad log is refused on the page naming the joint."""

from __future__ import annotations

import uuid
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from app.planning.robots import load_robot
from tests.frontend.test_browser import wait_for
from tests.utils.browser import screenshot
from tests.utils.robot_logs import arm_urdf, excitation, mujoco_torques, write_generic_csv
from tests.utils.server import Server

N = 3


def _log(folder: Path) -> tuple[Path, list[str]]:
    """An 8 s log of the arm with a 20 % heavier second link (MuJoCo's inverse dynamics)."""
    true = folder / "true.urdf"
    true.write_text(arm_urdf(N, masses=[4.0, 4.2, 3.0]))
    robot = load_robot(str(true))
    t, q, qd, qdd = excitation(8.0, 200.0, N, seed=4)
    tau = mujoco_torques(robot, q, qd, qdd)
    names = list(robot.joint_names)
    return write_generic_csv(folder / "arm_log.csv", t, names, q, tau), names


def test_upload_a_log_and_see_the_torque_plots(
    live_server: Server, page: Any, tmp_path: Path
) -> None:
    name = f"arm_{uuid.uuid4().hex[:6]}"
    r = httpx.post(
        f"{live_server.url}/api/robots",
        data={"name": name},
        files={"urdf": ("arm.urdf", arm_urdf(N).encode())},
        timeout=120,
    )
    assert r.status_code == 201, r.text
    log, names = _log(tmp_path)

    page.goto(f"{live_server.url}/#/validate")
    page.wait_for_selector("#log-form")
    assert page.locator('.tabs a[data-page="validate"]').get_attribute("class") == "active"
    page.select_option("#log-robot", name)
    # A log naming a joint the robot does not have is refused on the page, naming both.
    bad = tmp_path / "bad.csv"
    bad.write_text(log.read_text().replace("joint2/", "elbow/"))
    page.set_input_files("#log-file", str(bad))
    page.click("#log-submit")
    page.wait_for_selector("#log-error .banner.error")
    message = page.inner_text("#log-error")
    assert "bad.csv" in message and "joint2" in message and "elbow" in message

    page.set_input_files("#log-file", str(log))
    page.click("#log-submit")
    page.wait_for_selector("#validate-joints", timeout=120_000)
    log_id = int(page.url.rsplit("/", 1)[-1])
    rows = page.locator("#validate-joints tbody tr")
    assert [rows.nth(i).get_attribute("data-joint") for i in range(rows.count())] == names
    wait_for(lambda: page.locator(".validate-torque .main-svg").count() >= N, 60, "torque plots")

    # The plots hold the server's series: measured and predicted torque per joint.
    served = httpx.get(f"{live_server.url}/api/robot-logs/{log_id}/validation", timeout=60).json()
    for j, joint in enumerate(names):
        data = page.evaluate(
            f"Array.from(document.querySelector('.validate-torque[data-joint=\"{joint}\"]').data)"
            ".map(d => ({name: d.name, y: Array.from(d.y)}))"
        )
        by_name = {d["name"]: np.asarray(d["y"]) for d in data}
        assert np.allclose(by_name["measured"], served["series"]["measured"][j])
        assert np.allclose(by_name["predicted"], served["series"]["predicted"][j])
        residual = page.inner_text(f'#validate-joints tr[data-joint="{joint}"] td.residual')
        assert residual  # the table shows the server's residual, formatted
    # The nominal model misses the heavier second link: its residual is clearly not zero.
    assert served["joints"]["joint2"]["residual_rms"] > 0.1
    assert "measured" in page.inner_text("#validate-energy")
    screenshot(page, "validate")

    # Identify from the page: the job's progress, then the new version predicts the log better
    # and is offered on the Plan page beside the nominal robot.
    before = served["joints"]["joint2"]["residual_rms"]
    page.click("#identify-submit")
    page.wait_for_selector("#identify-done", timeout=300_000)
    version = f"{name}-identified"
    assert page.input_value("#validate-robot") == version
    cell = '#validate-joints tr[data-joint="joint2"] td.residual'
    wait_for(lambda: page.inner_text(cell) != f"{before:.4g}", 60, "the version's residuals")
    after = httpx.get(
        f"{live_server.url}/api/robot-logs/{log_id}/validation",
        params={"robot": version},
        timeout=60,
    ).json()["joints"]["joint2"]["residual_rms"]
    assert after < 0.5 * before
    page.goto(f"{live_server.url}/#/plan")
    page.wait_for_selector("#robot")
    option = page.locator(f'#robot option[value="{version}"]')
    assert option.count() == 1 and f"identified from {name}" in option.inner_text()
