"""Robots: built-ins as the planning package loads them; uploaded URDFs checked against the XML."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

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


# ---------------------------------------------------------------- onboarding (issue 12)


def _ur5_package() -> bytes:
    """UR5's URDF and meshes zipped as example-robot-data lays them out (package:// paths)."""
    import io
    import zipfile

    from tests.utils.example_robots import UR5, robot_file, robots_dir

    urdf = robot_file(UR5)
    base = robots_dir().parent.parent  # .../share: package://example-robot-data/robots/...
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr(str(urdf.relative_to(base)), urdf.read_bytes())
        for mesh in (urdf.parents[1] / "meshes" / "ur5" / "visual").rglob("*"):
            if mesh.is_file():
                archive.writestr(str(mesh.relative_to(base)), mesh.read_bytes())
    return buffer.getvalue()


def _finished(client: TestClient, path: str, body: dict[str, object]) -> dict[str, object]:
    from tests.utils.api import wait_job

    r = client.post(path, json=body)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"], timeout=300)
    assert job["state"] == "succeeded", job
    out: dict[str, object] = client.get(job["result_url"]).json()
    return out


@pytest.mark.slow
def test_ur5_package_upload_plan_simulate_export(client: TestClient) -> None:
    """UR5 (example-robot-data) uploaded as a zip with meshes: described, planned, simulated
    through MuJoCo's URDF compiler, exported (URScript: a six-joint arm), viewed with meshes."""
    from app.planning import load_robot
    from tests.utils.example_robots import UR5, robot_file

    files = {"package": ("ur5.zip", _ur5_package(), "application/zip")}
    form = {"name": "ur5", "payload": "1.0", "elbow_joint": "elbow_joint",
            "shoulder_joint": "shoulder_lift_joint"}  # fmt: skip
    r = client.post("/api/robots", data=form, files=files)
    assert r.status_code == 201, r.text
    info = r.json()
    ref = load_robot(robot_file(UR5), payload=1.0)
    assert info["joint_names"] == list(ref.joint_names)
    np.testing.assert_allclose(info["tau_max"], ref.tau_max)
    assert (info["shoulder_joint"], info["elbow_joint"]) == ("shoulder_lift_joint", "elbow_joint")
    roles = {j["name"]: j["role"] for j in info["joints"]}
    assert roles["elbow_joint"] == "elbow" and roles["shoulder_lift_joint"] == "shoulder"
    assert {j["kind"] for j in info["joints"]} <= {"revolute", "continuous"}
    assert info["motors_modelled"] is False  # no sidecar: electrical metrics not modelled
    assert any(f["role"] == "mesh" for f in info["files"])
    assert client.get("/api/robots/ur5").json() == info

    body = {"robot": "ur5", "duration": 2.0, "particles": 10, "iterations": 8,
            "methods": ["quintic", "paper"]}  # fmt: skip
    plan = _finished(client, "/api/plans", body)
    result = plan["result"]
    assert isinstance(result, dict) and result["joint_names"] == list(ref.joint_names)
    assert result["standard"]["electrical_energy"] is None
    r = client.get(f"/api/plans/{plan['id']}/trajectory", params={"format": "script"})
    assert r.status_code == 200, r.text
    assert b"servoj" in r.content
    # The viewer loads the uploaded URDF with its meshes (package:// paths in the zip).
    services = client.app.state.services  # type: ignore[attr-defined]
    prepared = services.comparisons("plan", plan["id"])
    assert len(prepared.meshes) >= 7 and all(m.faces.size for m in prepared.meshes)
    sim = _finished(client, "/api/simulations", body)
    r = client.get(f"/api/simulations/{sim['id']}/trajectory", params={"format": "csv"})
    header = next(x for x in r.text.splitlines() if not x.startswith("#"))  # after the record
    assert r.status_code == 200 and "shoulder_lift_joint" in header


def test_panda_with_locked_fingers_and_joint_roles(client: TestClient) -> None:
    """Panda: fingers locked by name (prismatic, metres), shoulder and elbow chosen by name."""
    from app.planning import load_robot
    from tests.utils.example_robots import PANDA, PANDA_LOCKS, robot_file

    urdf = robot_file(PANDA)
    form = {"name": "panda", "lock": ["panda_finger_joint1=0.02"], "shoulder_joint": "panda_joint2",
            "elbow_joint": "panda_joint4", "payload": "1.0"}  # fmt: skip
    r = client.post("/api/robots", data=form, files={"urdf": ("panda.urdf", urdf.read_bytes())})
    assert r.status_code == 201, r.text
    info = r.json()
    ref = load_robot(urdf, locks=PANDA_LOCKS, payload=1.0, shoulder_joint="panda_joint2",
                     elbow_joint="panda_joint4")  # fmt: skip
    assert info["joint_names"] == list(ref.joint_names)
    assert info["locks"] == pytest.approx(dict(ref.locks))  # finger 2 mimics finger 1
    assert info["locks"]["panda_finger_joint1"] == pytest.approx(0.02)
    finger = next(j for j in info["joints"] if j["name"] == "panda_finger_joint1")
    assert finger["locked"] and finger["kind"] == "prismatic" and finger["unit"] == "m"
    assert info["elbow_joint"] == "panda_joint4"
    np.testing.assert_allclose(info["default_goal_deg"], np.degrees(ref.default_goal))
    body = {"robot": "panda", "duration": 3.0, "particles": 10, "iterations": 8,
            "methods": ["quintic", "paper"]}  # fmt: skip
    plan = _finished(client, "/api/plans", body)
    result = plan["result"]
    assert isinstance(result, dict)
    assert result["motion"]["locks"] == pytest.approx(dict(ref.locks))
    r = client.get(f"/api/plans/{plan['id']}/trajectory", params={"format": "yaml"})
    assert r.status_code == 200 and "panda_finger_joint1" not in r.text.split("points")[0]


def test_bad_onboarding_is_refused_naming_the_field(
    client: TestClient, two_link_urdf: str, tmp_path: object
) -> None:
    """Unknown joint names, a bad lock, an escaping zip, a mismatched URDF/MJCF pair: 4xx."""
    import io
    import zipfile

    from app.planning import load_robot

    urdf = ("arm.urdf", two_link_urdf.encode())
    r = client.post("/api/robots", data={"name": "a", "elbow_joint": "knee"}, files={"urdf": urdf})
    detail = assert_problem(r, 422, field="elbow_joint")["detail"]
    assert "knee" in detail and "shoulder" in detail  # the robot's joints are listed
    # Roles by name change the robot: swapped, the default task moves the other joint most.
    form = {"name": "swapped", "shoulder_joint": "elbow", "elbow_joint": "shoulder"}
    swapped = client.post("/api/robots", data=form, files={"urdf": urdf}).json()
    plain = client.post("/api/robots", data={"name": "plain"}, files={"urdf": urdf}).json()
    assert (plain["shoulder_joint"], plain["elbow_joint"]) == ("shoulder", "elbow")
    assert (swapped["shoulder_joint"], swapped["elbow_joint"]) == ("elbow", "shoulder")
    assert swapped["default_goal_deg"] != plain["default_goal_deg"]
    for name in ("swapped", "plain"):
        assert client.delete(f"/api/robots/{name}").status_code == 204
    r = client.post("/api/robots", data={"name": "a", "lock": ["j1"]}, files={"urdf": urdf})
    assert_problem(r, 422, field="lock")
    r = client.post("/api/robots", data={"name": "a", "lock": ["nope=3"]}, files={"urdf": urdf})
    assert "nope" in assert_problem(r, 422, field="lock")["detail"]
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("robot.urdf", two_link_urdf)
        archive.writestr("../../evil.txt", b"x")
    r = client.post("/api/robots", data={"name": "a"},
                    files={"package": ("evil.zip", buffer.getvalue())})  # fmt: skip
    assert "outside the archive" in assert_problem(r, 422, field="package")["detail"]
    r = client.post("/api/robots", data={"name": "a"})
    assert_problem(r, 422, field="urdf")
    # A member name the file system cannot hold (longer than NAME_MAX, a NUL byte) is no member
    # of the package, not a 500 (found by a 200-example fuzz: ENAMETOOLONG escaped).
    for member in ("x" * 300, "a\x00b"):
        r = client.post("/api/robots", data={"name": "a", "sidecar_member": member},
                        files={"urdf": urdf})  # fmt: skip
        detail = assert_problem(r, 422, field="sidecar")["detail"]
        assert "is not a file of the robot package" in detail and len(detail) < 300
    # A URDF paired with an MJCF whose upper arm is heavier: refused naming the joint.
    builtin = load_robot("curtain_wall_6dof")
    mjcf = builtin.mjcf_path.read_text()
    at = mjcf.index('mass="', mjcf.index("<body", mjcf.index("<worldbody") + 10) + 5)
    value = mjcf[at + 6 : mjcf.index('"', at + 6)]
    heavier = mjcf[: at + 6] + str(float(value) * 1.5 + 1.0) + mjcf[at + 6 + len(value) :]
    files = {"urdf": ("cw.urdf", builtin.urdf_path.read_bytes()),
             "mjcf": ("cw.xml", heavier.encode())}  # fmt: skip
    detail = assert_problem(client.post("/api/robots", data={"name": "cw"}, files=files), 422)[
        "detail"
    ]
    assert any(j in detail for j in builtin.joint_names), detail
    assert [x["builtin"] for x in client.get("/api/robots").json()] == [True, True]


def test_a_sidecar_models_the_motors_and_a_bad_one_is_refused(client: TestClient) -> None:
    """UR5 with the documented sidecar: motors modelled; a negative gear ratio: 422 naming it."""
    from pathlib import Path

    from tests.utils.example_robots import UR5, robot_file

    urdf = ("ur5.urdf", robot_file(UR5).read_bytes())
    sidecar = Path(__file__).parents[2] / "docs" / "examples" / "ur5.sidecar.yaml"
    text = sidecar.read_text()
    files = {"urdf": urdf, "sidecar": ("ur5.yaml", text.encode())}
    r = client.post("/api/robots", data={"name": "ur5m"}, files=files)
    assert r.status_code == 201, r.text
    assert r.json()["motors_modelled"] is True
    plain = client.post("/api/robots", data={"name": "ur5p"}, files={"urdf": urdf}).json()
    assert plain["motors_modelled"] is False
    assert "gear_ratio: 101" in text
    bad = text.replace("gear_ratio: 101", "gear_ratio: -101", 1)
    files = {"urdf": urdf, "sidecar": ("ur5.yaml", bad.encode())}
    r = client.post("/api/robots", data={"name": "ur5b"}, files=files)
    assert "gear" in assert_problem(r, 422, field="sidecar")["detail"]


def test_an_mjcf_alone_is_a_robot(client: TestClient) -> None:
    """An MJCF without a URDF: its joints and limits as the library reads it, and it plans."""
    from app.planning import load_robot

    builtin = load_robot("human_arm_2dof")
    files = {"mjcf": ("arm.xml", builtin.mjcf_path.read_bytes())}
    r = client.post("/api/robots", data={"name": "mj_arm"}, files=files)
    assert r.status_code == 201, r.text
    info = r.json()
    ref = load_robot(builtin.mjcf_path)
    assert info["has_mjcf"] and info["urdf_name"] is None and info["mjcf_name"] == "arm.xml"
    assert info["joint_names"] == list(ref.joint_names)
    np.testing.assert_allclose(info["q_max"], ref.q_max)
    body = {"robot": "mj_arm", "methods": ["quintic"], "particles": 4, "iterations": 2}
    plan = _finished(client, "/api/plans", body)
    assert isinstance(plan["result"], dict) and "quintic" in plan["result"]["methods"]


@pytest.mark.api_contract
def test_mjcf_files_are_confined_to_the_upload(client: TestClient) -> None:
    """Issue 14 item 5: an uploaded MJCF's ``<include file="/etc/passwd"/>`` was read (and the
    error told whether a file exists). Paths outside the upload are refused from the text
    alone, with one message whether the file exists or not; an include inside a zip works."""
    import io
    import zipfile

    from app.planning import load_robot

    arm = load_robot("human_arm_2dof").mjcf_path.read_text()
    outside = {
        "include": '<mujoco><include file="{p}"/></mujoco>',
        "mesh": '<mujoco><asset><mesh name="m" file="{p}"/></asset><worldbody/></mujoco>',
        "meshdir": '<mujoco><compiler meshdir="{p}"/><worldbody/></mujoco>',
    }
    for element, template in outside.items():
        answers = []
        for target in ("/etc/passwd", "/etc/no-such-file-here", "../../etc/passwd", "C:\\x"):
            model = template.format(p=target).encode()
            r = client.post("/api/robots", data={"name": "mj_x"}, files={"mjcf": ("m.xml", model)})
            problem = assert_problem(r, 422)
            assert "outside the uploaded robot's files" in problem["detail"], problem
            answers.append(problem["detail"].replace(target, "<path>"))
        assert len(set(answers)) == 1, answers  # no existence oracle
        assert f"<{element}" in answers[0] or "<compiler" in answers[0]
    # An include of a file inside the upload (a zip) is fine.
    head, _, rest = arm.partition("<worldbody>")
    body, _, tail = rest.partition("</worldbody>")
    main = f'{head}<include file="parts/body.xml"/>{tail}'
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("arm/robot.xml", main)
        z.writestr("arm/parts/body.xml", f"<mujoco><worldbody>{body}</worldbody></mujoco>")
    r = client.post(
        "/api/robots",
        data={"name": "mj_zip", "mjcf_member": "arm/robot.xml"},
        files={"package": ("arm.zip", buf.getvalue())},
    )
    assert r.status_code == 201, r.text
    assert r.json()["joint_names"] == list(load_robot("human_arm_2dof").joint_names)
