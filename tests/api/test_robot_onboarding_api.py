"""Uploading third-party robots that need more than a file (issue 27): the meshes a URDF
names and the upload lacks are listed at once; a legged robot is refused with a 422 naming its
base link, and the ``base_link`` field makes the same upload load the arm alone."""

from __future__ import annotations

from tests.utils.api import TestClient, assert_problem
from tests.utils.example_robots import UR5, robot_file
from tests.utils.ur5_package import ur5_package

ANYMAL_KINOVA = "anymal_b_simple_description/robots/anymal-kinova.urdf"


def test_missing_meshes_are_listed_at_upload(client: TestClient) -> None:
    """The URDF alone: its 14 package:// meshes are missing (the viewer would draw no bodies);
    a zip with the visual meshes only: the 7 collision meshes; with both: none."""
    urdf = robot_file(UR5).read_bytes()
    r = client.post("/api/robots", data={"name": "ur5_alone"},
                    files={"urdf": ("ur5_robot.urdf", urdf)})  # fmt: skip
    assert r.status_code == 201, r.text
    missing = r.json()["missing_meshes"]
    assert len(missing) == 14 and missing[0].endswith("ur5/visual/base.dae")
    assert client.get("/api/robots/ur5_alone").json()["missing_meshes"] == missing
    for name, folders, expected in (
        ("ur5_visual", ("visual",), 7),
        ("ur5_full", ("visual", "collision"), 0),
    ):
        r = client.post("/api/robots", data={"name": name},
                        files={"package": ("ur5.zip", ur5_package(meshes=folders))})  # fmt: skip
        assert r.status_code == 201, r.text
        left = r.json()["missing_meshes"]
        assert len(left) == expected and all("/collision/" in m for m in left), name


def test_a_legged_robot_needs_its_arm_base_link(client: TestClient) -> None:
    files = {"urdf": ("anymal-kinova.urdf", robot_file(ANYMAL_KINOVA).read_bytes())}
    body = assert_problem(
        client.post("/api/robots", data={"name": "anymal"}, files=files),
        422, file="anymal-kinova.urdf", field="base_link",
    )  # fmt: skip
    assert "j2s6s200_link_base" in body["detail"] and "branch into 5 chains" in body["detail"]
    r = client.post(
        "/api/robots", data={"name": "anymal", "base_link": "j2s6s200_link_base"}, files=files
    )
    assert r.status_code == 201, r.text
    info = r.json()
    assert info["joint_names"] == [f"j2s6s200_joint_{i}" for i in range(1, 7)]
    assert len(info["locks"]) == 12  # the legs, off the arm
    bad = client.post("/api/robots", data={"name": "anymal2", "base_link": "nope"}, files=files)
    assert "base_link 'nope' is not a link" in assert_problem(bad, 422)["detail"]
