"""Robots: built-ins as the planning package loads them; uploaded URDFs checked against the XML."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from tests.utils.api import TestClient, assert_problem


def urdf_limits(text: str) -> dict[str, list[float]]:
    joints = [j for j in ET.fromstring(text).iter("joint") if j.get("type") != "fixed"]
    lim = [j.find("limit") for j in joints]
    return {
        "joint_names": [j.get("name") for j in joints],
        "q_min": [float(x.get("lower")) for x in lim],
        "q_max": [float(x.get("upper")) for x in lim],
        "qd_max": [float(x.get("velocity")) for x in lim],
        "tau_max": [float(x.get("effort")) for x in lim],
    }  # type: ignore[return-value]


def test_builtins_are_listed_with_their_limits(client: TestClient) -> None:
    from app.planning.robots import load_robot

    robots = {r["name"]: r for r in client.get("/api/robots").json()}
    assert {"human_arm_2dof", "curtain_wall_6dof"} <= set(robots)
    for name in ("human_arm_2dof", "curtain_wall_6dof"):
        info, robot = robots[name], load_robot(name)
        assert info["builtin"] and info["has_mjcf"]
        assert info["joint_names"] == list(robot.joint_names)
        np.testing.assert_allclose(info["tau_max"], robot.tau_max)
        np.testing.assert_allclose(info["q_max"], robot.q_max)
        assert client.get(f"/api/robots/{name}").json() == info
    assert robots["curtain_wall_6dof"]["payload"] == 4.0  # DESIGN.md: 4 kg by default
    assert len(robots["curtain_wall_6dof"]["joint_names"]) == 6


def test_upload_a_urdf_then_use_and_delete_it(client: TestClient, two_link_urdf: str) -> None:
    files = {"urdf": ("arm.urdf", two_link_urdf.encode(), "application/xml")}
    r = client.post("/api/robots", data={"name": "lab_arm", "payload": "2.5"}, files=files)
    assert r.status_code == 201, r.text
    info = r.json()
    assert (info["name"], info["builtin"], info["payload"]) == ("lab_arm", False, 2.5)
    assert not info["has_mjcf"] and info["urdf_name"] == "arm.urdf"
    for key, value in urdf_limits(two_link_urdf).items():
        assert info[key] == value, key
    assert client.get("/api/robots/lab_arm").json() == info
    assert "lab_arm" in [x["name"] for x in client.get("/api/robots").json()]

    assert_problem(client.post("/api/robots", data={"name": "lab_arm"}, files=files), 409)
    assert_problem(client.post("/api/robots", data={"name": "human_arm_2dof"}, files=files), 409)
    assert client.delete("/api/robots/lab_arm").status_code == 204
    assert_problem(client.get("/api/robots/lab_arm"), 404)
    assert_problem(client.delete("/api/robots/human_arm_2dof"), 409)


def test_bad_models_are_422_naming_the_file(client: TestClient, two_link_urdf: str) -> None:
    broken = two_link_urdf.replace('effort="40" ', "")  # a limit without effort
    for name, text in (("broken.urdf", broken), ("junk.urdf", "<robot")):
        r = client.post("/api/robots", data={"name": "bad"}, files={"urdf": (name, text.encode())})
        assert_problem(r, 422, file=name)
    r = client.post(
        "/api/robots", data={"name": "../x"}, files={"urdf": ("a.urdf", two_link_urdf.encode())}
    )
    assert_problem(r, 422, field="name")
    assert [x["builtin"] for x in client.get("/api/robots").json()] == [True, True]
