"""The viewer shows the safety check's contacts (issue 27): the UR5 of example-robot-data,
whose default task drives its wrist below the mounting plane, planned, then drawn."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from app.viewer.comparison import Comparison, comparison_from_arrays
from app.viewer.scene import (
    CONTACT_COLOR,
    ComparisonScene,
    PreparedComparison,
    contact_text,
)
from app.viewer.server import _safety_text
from tests.utils.example_robots import UR5, robot_file
from tests.viewer._fakes import FakeTarget


@pytest.fixture(scope="module")
def ur5_plan() -> tuple[Any, Any]:
    from app.planning import load_robot, plan

    robot = load_robot(robot_file(UR5), payload=1.0)
    result = plan(robot, duration=2.0, methods=("quintic", "bound"), n_samples=201)
    return robot, result


@pytest.fixture(scope="module")
def prepared(ur5_plan: tuple[Any, Any]) -> PreparedComparison:
    robot, result = ur5_plan
    comparison: Comparison = comparison_from_arrays(
        "plan", 3, result.arrays(), result.to_dict(), robot
    )
    return PreparedComparison(comparison, urdf_path=robot.urdf_path)


def _wrist_z(robot: Any, q: np.ndarray, link: str) -> float:
    """Height [m] of a link's frame origin in the base frame (Pinocchio, not the check)."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(robot.urdf_path))
    data = model.createData()
    full = np.zeros(model.nq)
    for name, value in zip(robot.joint_names, q, strict=True):
        full[model.idx_qs[model.getJointId(name)]] = value
    pin.framesForwardKinematics(model, data, full)
    base = data.oMf[model.getFrameId("base_link")]
    return float(base.actInv(data.oMf[model.getFrameId(link)]).translation[2])


def test_contacts_are_marked_on_their_links_from_their_time(
    ur5_plan: tuple[Any, Any], prepared: PreparedComparison
) -> None:
    robot, result = ur5_plan
    safety = result.to_dict()["safety"]
    assert safety["checked"] is True and safety["ok"] is False
    findings = [f for f in safety["findings"] if f["method"] == "quintic"]
    assert findings and {"plane"} <= {f["kind"] for f in findings}

    target = FakeTarget()
    scene = ComparisonScene(target, prepared)
    assert scene.shown["standard"] == "quintic"
    nodes = target.scene.nodes
    # One red sphere on every link of every quintic contact, under that link's frame.
    for k, finding in enumerate(findings):
        for m, link in enumerate(finding["links"]):
            name = f"/bioplan/standard/{'/'.join(prepared.link_paths[link])}/contact_{k}_{m}"
            assert nodes[name].kind == "add_icosphere" and nodes[name].color == CONTACT_COLOR
        label = [n for n in nodes if n.startswith("/bioplan/standard/")
                 and n.endswith(f"/{finding['links'][0]}/contact_{k}_label")]  # fmt: skip
        assert len(label) == 1 and nodes[label[0]].args[0] == contact_text(finding)

    # The deepest plane contact: the label's depth is the check's, and at its time the
    # link's frame is below the plane by forward kinematics (independent of the check).
    plane = max((f for f in findings if f["kind"] == "plane"), key=lambda f: f["depth"])
    text = contact_text(plane)
    assert f"{plane['links'][0]} – mount plane" in text
    assert f"{1000 * plane['depth']:.0f} mm deep" in text
    at = prepared.comparison.index_at(plane["deepest_time"])
    z = _wrist_z(robot, prepared.comparison.q["quintic"][at], plane["links"][0])
    assert z < 0.0 and plane["depth"] >= -z - 1e-6

    # Each contact hidden before it begins, shown from then on; nothing added while playing.
    keys = set(nodes)
    scene.show(len(prepared.comparison.t) - 1)
    assert len(scene.contacts_shown("standard")) == len(findings)
    later = [f for f in findings if f["time"] > 0.0]
    assert later  # the wrist meets the base column at the end of the task (issue 27)
    for finding in later:
        index = prepared.comparison.index_at(finding["time"])
        scene.show(index - 1)
        assert contact_text(finding) not in scene.contacts_shown("standard")
        scene.show(index)
        assert contact_text(finding) in scene.contacts_shown("standard")
    assert set(nodes) == keys

    # The plane the plan was checked against, translucent, at its height in each base frame.
    slab = nodes["/bioplan/standard/mount_plane"]
    assert slab.kind == "add_box" and slab.opacity < 1.0
    assert slab.position[2] + 0.5 * slab.dimensions[2] == pytest.approx(
        safety["mount_plane_height"]
    )
    assert "/bioplan/optimized/mount_plane" in nodes

    # The details panel names the first contact of each method.
    panel = _safety_text(scene)
    assert panel.startswith("**Unsafe**") and "mount plane" in panel


def test_markers_follow_the_method_shown(prepared: PreparedComparison) -> None:
    """Swapping the two robots' methods moves each method's markers with it."""
    target = FakeTarget()
    scene = ComparisonScene(target, prepared)
    ghost = scene.shown["optimized"]
    ghost_contacts = prepared.contacts[ghost]
    scene.set_methods(ghost, "quintic")
    nodes = target.scene.nodes
    standard = [n for n in nodes if n.startswith("/bioplan/standard/") and "/contact_" in n]
    optimized = [n for n in nodes if n.startswith("/bioplan/optimized/") and "/contact_" in n]
    assert len(standard) == sum(len(f["links"]) + 1 for _, f, _ in ghost_contacts)
    assert len(optimized) == sum(len(f["links"]) + 1 for _, f, _ in prepared.contacts["quintic"])


def test_a_plan_without_a_check_draws_no_plane_and_no_marker(
    prepared: PreparedComparison,
) -> None:
    from dataclasses import replace

    c = prepared.comparison
    bare = PreparedComparison(replace(c, result={k: v for k, v in c.result.items()
                                                  if k != "safety"}))  # fmt: skip
    target = FakeTarget()
    ComparisonScene(target, bare)
    assert not [n for n in target.scene.nodes if "contact_" in n or "mount_plane" in n]


SIDECAR = """\
obstacles:
  - {name: table, kind: box, position: [0.6, 0.1, 0.2], rpy_deg: [0, 0, 30], size: [0.4, 0.8, 0.1]}
  - {name: column, kind: cylinder, position: [-0.5, 0.4, 1.0], rpy_deg: [90, 0, 0],
     radius: 0.15, length: 2.0}
  - {name: facade, kind: plane, position: [1.2, 0.3, 0.5], normal: [-1, 0, 0]}
"""


def test_sidecar_obstacles_are_drawn_where_the_check_puts_them(
    prepared: PreparedComparison, tmp_path: Any
) -> None:
    """Box, cylinder and plane of a sidecar, in the base frame of both robots; orientations
    checked with Pinocchio's roll-pitch-yaw (an independent convention)."""
    from dataclasses import replace

    import pinocchio as pin

    from app.planning import load_robot
    from app.viewer.comparison import workspace_obstacles

    sidecar = tmp_path / "ur5.yaml"
    sidecar.write_text(SIDECAR)
    robot = load_robot(robot_file(UR5), payload=1.0, sidecar=sidecar)
    obstacles = workspace_obstacles(robot)
    assert [o["name"] for o in obstacles] == ["table", "column", "facade"]
    assert workspace_obstacles(load_robot(robot_file(UR5))) == ()

    scene_prepared = PreparedComparison(replace(prepared.comparison, obstacles=obstacles))
    target = FakeTarget()
    ComparisonScene(target, scene_prepared)
    nodes = target.scene.nodes

    def rotation(wxyz: Any) -> np.ndarray:
        w, x, y, z = wxyz
        return np.asarray(pin.Quaternion(w, x, y, z).toRotationMatrix())

    for slot in ("standard", "optimized"):
        table, column, facade = (nodes[f"/bioplan/{slot}/obstacle_{k}"] for k in range(3))
        assert table.kind == "add_box" and table.opacity < 1.0
        np.testing.assert_allclose(table.dimensions, (0.4, 0.8, 0.1))
        np.testing.assert_allclose(table.position, (0.6, 0.1, 0.2))
        np.testing.assert_allclose(
            rotation(table.wxyz), pin.rpy.rpyToMatrix(0.0, 0.0, np.radians(30)), atol=1e-12
        )
        assert column.kind == "add_cylinder"
        assert (column.radius, column.height) == (0.15, 2.0)
        # Rolled 90 deg about x, the column's axis (viser's and the check's local z) is -y.
        np.testing.assert_allclose(rotation(column.wxyz)[:, 2], (0.0, -1.0, 0.0), atol=1e-12)
        # The facade: a slab whose top face lies on x = 1.2, its normal -x towards the robot.
        r = rotation(facade.wxyz)
        np.testing.assert_allclose(r[:, 2], (-1.0, 0.0, 0.0), atol=1e-12)
        top = np.asarray(facade.position) + 0.5 * facade.dimensions[2] * r[:, 2]
        assert top[0] == pytest.approx(1.2)
