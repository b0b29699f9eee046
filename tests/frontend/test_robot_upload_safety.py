"""The "Add your robot" card warns before a robot is offered (issue 27): the UR5's URDF alone
names 14 meshes that are missing; with its meshes, its default task is checked and found to
drive a wrist link below the mounting plane."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tests.frontend.test_browser import wait_for
from tests.utils.browser import screenshot
from tests.utils.example_robots import UR5, robot_file
from tests.utils.server import Server
from tests.utils.ur5_package import ur5_package


def _open_upload(page: Any, server: Server) -> None:
    page.goto(f"{server.url}/#/plan")
    page.wait_for_selector("#robot-upload-card")
    page.click("#robot-upload-card summary")


def test_upload_card_warns_of_missing_meshes_and_an_unsafe_default_task(
    live_server: Server, page: Any, tmp_path: Path
) -> None:
    _open_upload(page, live_server)
    page.set_input_files("#robot-model", str(robot_file(UR5)))
    page.fill("#robot-name", "ur5_bare")
    page.click("#robot-upload")
    wait_for(lambda: "Added ur5_bare" in page.inner_text("#robot-upload-status"), 120, "added")
    status = page.inner_text("#robot-upload-status")
    assert "14 mesh file(s)" in status and ".zip" in status, status
    assert "worse" in (page.get_attribute("#robot-upload-status", "class") or "")
    # Its collision meshes are missing too: said, never passed off as safe.
    safety = page.inner_text("#robot-upload-safety")
    assert "not checked" in safety and "Unsafe" not in safety, safety

    package = tmp_path / "ur5.zip"
    package.write_bytes(ur5_package())  # the card stays open for the next robot
    page.set_input_files("#robot-model", str(package))
    page.fill("#robot-name", "ur5_meshes")
    page.click("#robot-upload")
    wait_for(lambda: "Added ur5_meshes" in page.inner_text("#robot-upload-status"), 120, "added")
    assert "mesh file(s)" not in page.inner_text("#robot-upload-status")
    worst = live_server.get("/api/robots/ur5_meshes")["default_task_safety"]["worst"]
    text = page.inner_text("#robot-upload-safety")
    assert text.startswith("Unsafe default task"), text
    assert f"drives {worst['links'][0]} " in text and "below the mount plane" in text, text
    assert f"{100 * worst['depth']:.0f} cm" in text, text
    assert "mount plane" in text and "start and goal angles" in text, text
    assert "worse" in (page.get_attribute("#robot-upload-safety", "class") or "")
    screenshot(page, "robot-upload-unsafe-default-task")
