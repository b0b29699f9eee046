"""Onboarding checks the default task safe before offering it (issue 27): the UR5 of
example-robot-data, whose default task lowers its wrist through the mounting plane."""

from __future__ import annotations

import numpy as np
import pytest

from tests.utils.api import TestClient
from tests.utils.ur5_package import ur5_package


def _wrist_position(link: str, time: float) -> np.ndarray:
    """(3,) position [m] of ``link``'s frame origin in the base frame at ``time`` [s] of the
    UR5's default quintic over 1 s (Pinocchio forward kinematics, not the check)."""
    import pinocchio as pin

    from app.planning import load_robot
    from tests.utils.example_robots import UR5, robot_file

    robot = load_robot(robot_file(UR5), payload=1.0)
    model = pin.buildModelFromUrdf(str(robot_file(UR5)))
    data = model.createData()
    u = time / 1.0
    s = u**3 * (10 - 15 * u + 6 * u**2)  # the quintic's shape with zero end speed and accel.
    start, goal = np.asarray(robot.default_start), np.asarray(robot.default_goal)
    q = np.zeros(model.nq)
    for name, value in zip(robot.joint_names, start + s * (goal - start), strict=True):
        q[model.idx_qs[model.getJointId(name)]] = value
    pin.framesForwardKinematics(model, data, q)
    base = data.oMf[model.getFrameId("base_link")]
    return np.array(base.actInv(data.oMf[model.getFrameId(link)]).translation, float)


def test_ur5_default_task_is_flagged_below_the_mount_plane(client: TestClient) -> None:
    """UR5 with its collision meshes: the default quintic is unsafe, its deepest contact a
    wrist link below the plane, as deep as forward kinematics puts that link's frame below it
    (the hull holds the frame's origin); a sidecar that lowers the plane past the arm's reach
    leaves only the wrist meeting the base column at the end."""
    files = {"package": ("ur5.zip", ur5_package(), "application/zip")}
    r = client.post("/api/robots", data={"name": "ur5c", "payload": "1.0"}, files=files)
    assert r.status_code == 201, r.text
    info = r.json()
    assert info["missing_meshes"] == []
    check = info["default_task_safety"]
    assert check["checked"] is True and check["ok"] is False, check
    assert check["findings"] >= 1 and check["summary"].startswith("UNSAFE: quintic")
    worst = check["worst"]
    assert worst["kind"] == "plane" and worst["obstacle"] == "mount plane"
    link = worst["links"][0]
    assert link in {"wrist_1_link", "wrist_2_link", "wrist_3_link", "ee_link"}
    below = -_wrist_position(link, worst["deepest_time"])[2]
    assert below > 0.2  # the frame itself is tens of centimetres under the plane
    assert worst["depth"] >= below - 1e-6  # the geometry reaches at least as deep
    assert worst["depth"] < below + 0.1  # and not more than a link's radius more
    assert check["min_clearance"] == pytest.approx(-worst["depth"])
    assert client.get("/api/robots/ur5c").json()["default_task_safety"] == check

    sidecar = ("ur5.yaml", b"mount_plane: {height: -1.5, enabled: true}\n")
    r = client.post("/api/robots", data={"name": "ur5low"}, files={**files, "sidecar": sidecar})
    assert r.status_code == 201, r.text
    low = r.json()["default_task_safety"]
    # Past the plane the task still ends with the wrist at the base column (issue 27).
    assert low["checked"] is True and low["ok"] is False, low
    assert low["worst"]["kind"] == "self"
    assert set(low["worst"]["links"]) == {"base_link", "wrist_2_link"}
    assert low["worst"]["deepest_time"] > 0.8
    assert low["min_clearance"] > check["min_clearance"]
    assert np.hypot(*_wrist_position("wrist_2_link", 1.0)[:2]) < 0.2  # FK: at the column


def test_ur5_urdf_alone_is_not_checked_and_says_why(client: TestClient) -> None:
    """The URDF alone: its 14 meshes are missing, so the check says "not checked", naming a
    collision mesh, never "ok"."""
    from tests.utils.example_robots import UR5, robot_file

    urdf = ("ur5.urdf", robot_file(UR5).read_bytes())
    r = client.post("/api/robots", data={"name": "ur5u"}, files={"urdf": urdf})
    assert r.status_code == 201, r.text
    info = r.json()
    assert len(info["missing_meshes"]) == 14
    check = info["default_task_safety"]
    assert check["checked"] is False and check["ok"] is None, check
    assert ".stl" in check["reason"] and "not found" in check["reason"]
