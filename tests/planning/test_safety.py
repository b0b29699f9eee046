"""Collision and workspace checks (app.planning.safety) on real and built-in robots.

References are independent of the checker: Pinocchio forward kinematics with the STL vertices
read by trimesh, closed-form distances of the built-in robots' cylinders, and dense sampling
of the interpolated motion for the contacts that lie between two samples.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from app.planning.planner import SKIPPED, PlanTask, plan
from app.planning.profiles import quintic
from app.planning.robots import load_robot
from app.planning.robots._obstacles import Obstacle
from app.planning.safety import (
    NOT_CHECKED_NO_GEOMETRY,
    NOT_CHECKED_NO_PAIRS,
    SafetyScene,
    _hermite,
    check_safety,
    default_scene,
)
from tests.utils.example_robots import UR5, robot_file, robots_dir

REPO = Path(__file__).resolve().parents[2]
UR5_SIDECAR = REPO / "docs" / "examples" / "ur5.sidecar.yaml"
#: The safe UR5 task: the arm raised (shoulder -90 deg), a 20/100 deg curl above the base.
SAFE_START_DEG = (0.0, -90.0, 0.0, -90.0, 0.0)
SAFE_GOAL_DEG = (0.0, -70.0, 100.0, -90.0, 0.0)


@dataclass(frozen=True)
class Samples:
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray


@pytest.fixture(scope="module")
def ur5() -> Any:
    return load_robot(robot_file(UR5), sidecar=UR5_SIDECAR)


def _ur5_geometry(robot: Any) -> tuple[Any, Any, Any]:
    model = pin.buildModelFromUrdf(str(robot.urdf_path))
    geom = pin.buildGeomFromUrdf(
        model,
        str(robot.urdf_path),
        pin.GeometryType.COLLISION,
        package_dirs=[str(robots_dir().parent.parent)],
    )
    return model, geom, geom.createData()


def _lowest_vertex_z(robot: Any, link: str, q_free: np.ndarray) -> float:
    """The lowest point [m] of a link's collision mesh (STL read by trimesh, placed by
    Pinocchio forward kinematics), in the base frame."""
    import trimesh

    model, geom, gdata = _ur5_geometry(robot)
    data = model.createData()
    obj = next(o for o in geom.geometryObjects if model.frames[o.parentFrame].name == link)
    index = geom.getGeometryId(obj.name)
    pin.updateGeometryPlacements(model, data, geom, gdata, robot.full_configuration(q_free))
    mesh = trimesh.load(obj.meshPath, force="mesh")
    vertices = np.asarray(mesh.vertices) * np.asarray(obj.meshScale)
    placement = gdata.oMg[index]
    world = vertices @ np.asarray(placement.rotation).T + np.asarray(placement.translation)
    return float(world[:, 2].min())


def _default_ur5_plan(robot: Any) -> Any:
    return plan(robot, duration=2.0, methods=("quintic", "jerk_limited"), report_samples=1001)


def test_ur5_default_task_is_flagged_with_the_links_and_the_plane(ur5: Any) -> None:
    result = _default_ur5_plan(ur5)
    safety = result.to_dict()["safety"]
    assert safety["checked"] is True and safety["ok"] is False
    plane = [f for f in safety["findings"] if f["kind"] == "plane"]
    assert {f["method"] for f in plane} == {"quintic", "jerk_limited"}
    assert all(f["obstacle"] == "mount plane" and len(f["links"]) == 1 for f in plane)
    links = {f["links"][0] for f in plane if f["method"] == "quintic"}
    assert {"forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link"} <= links
    # Issue 27: tool0 dips more than 30 cm below the mounting plane (Pinocchio FK).
    model = pin.buildModelFromUrdf(str(ur5.urdf_path))
    data = model.createData()
    tool0 = model.getFrameId("tool0")
    quintic_q = result.methods["quintic"].trajectory.q
    lowest_tool0 = math.inf
    for q in quintic_q[::10]:
        pin.framesForwardKinematics(model, data, ur5.full_configuration(q))
        lowest_tool0 = min(lowest_tool0, float(data.oMf[tool0].translation[2]))
    assert lowest_tool0 < -0.3
    wrist3 = next(f for f in plane if f["method"] == "quintic" and f["links"] == ["wrist_3_link"])
    assert wrist3["depth"] > -lowest_tool0  # the mesh reaches below its flange frame
    # The depth is the mesh's lowest point at that time (trimesh vertices + Pinocchio FK).
    k = int(np.argmin(np.abs(result.methods["quintic"].trajectory.t - wrist3["deepest_time"])))
    reference = -_lowest_vertex_z(ur5, "wrist_3_link", quintic_q[k])
    assert wrist3["depth"] == pytest.approx(reference, abs=1e-6)
    assert safety["min_clearance"] <= -wrist3["depth"]


def test_plane_distance_matches_the_mesh_by_hand(ur5: Any) -> None:
    q = np.radians(SAFE_START_DEG)
    for link in ("forearm_link", "wrist_2_link"):
        trajectory = Samples(np.array([0.0]), q[None, :], np.zeros((1, 5)))
        scene = SafetyScene(mount_plane_height=_lowest_vertex_z(ur5, link, q) + 0.01)
        report = check_safety(ur5, {"still": trajectory}, scene=scene)
        hits = [f for f in report.findings if f.kind == "plane"]
        # the plane 10 mm above the link's lowest vertex: exactly that link (and those lower)
        mine = next(f for f in hits if f.links == (link,))
        assert mine.depth == pytest.approx(0.01, abs=1e-6)


def test_a_safe_ur5_task_passes(ur5: Any) -> None:
    task = PlanTask(np.radians(SAFE_START_DEG), np.radians(SAFE_GOAL_DEG))
    result = plan(
        ur5, task=task, duration=2.0, methods=("quintic", "jerk_limited"), report_samples=1001
    )
    safety = result.to_dict()["safety"]
    assert safety["checked"] is True and safety["ok"] is True and safety["findings"] == []
    assert safety["pairs"]["plane"] == 7 and safety["pairs"]["self"] > 0
    assert 0.0 < safety["min_clearance"] < 0.1
    assert safety["margin"] > 0.0 and "conservative advancement" in safety["sweep"]


def test_skipping_the_check_says_not_checked(ur5: Any) -> None:
    task = PlanTask(np.radians(SAFE_START_DEG), np.radians(SAFE_GOAL_DEG))
    result = plan(ur5, task=task, duration=2.0, methods=("quintic", "jerk_limited"), safety=False)
    safety = result.to_dict()["safety"]
    assert safety["checked"] is False and safety["ok"] is None and safety["reason"] == SKIPPED


def _two_samples(start: np.ndarray, goal: np.ndarray, duration: float = 1.0) -> Samples:
    """A rest-to-rest move given by its two end samples only (cubic Hermite in between)."""
    return Samples(np.array([0.0, duration]), np.vstack([start, goal]), np.zeros((2, len(start))))


def _dense(samples: Samples, n: int = 2001) -> Samples:
    """The same motion sampled densely (the interpolation the checker bisects)."""
    s = np.linspace(0.0, 1.0, n)
    h = float(samples.t[1] - samples.t[0])
    q = np.array(
        [_hermite(samples.q[0], samples.q[1], samples.qd[0] * h, samples.qd[1] * h, x) for x in s]
    )
    qd = np.gradient(q, s * h, axis=0)
    return Samples(samples.t[0] + s * h, q, qd)


def test_a_self_collision_between_two_samples_is_caught() -> None:
    # The curtain-wall arm swings its shoulder back by 52 deg: both ends clear the pedestal,
    # the hanging arm passes through it in between.
    robot = load_robot("curtain_wall_6dof")
    start = np.zeros(6)
    goal = start.copy()
    goal[1] = -0.9
    ends = {"swing": Samples(np.array([0.0]), goal[None, :], np.zeros((1, 6)))}
    assert check_safety(robot, ends).ok is True  # the end pose alone is clear
    report = check_safety(robot, {"swing": _two_samples(start, goal)})
    pedestal = [f for f in report.findings if f.kind == "self" and f.links[0] == "pedestal"]
    assert pedestal and all(f.between_samples for f in pedestal)
    dense = check_safety(robot, {"swing": _dense(_two_samples(start, goal))})
    first_dense = min(f.time for f in dense.findings if f.links[0] == "pedestal")
    first = min(f.time for f in pedestal)
    assert first == pytest.approx(first_dense, abs=2e-3)
    assert {f.links for f in pedestal} <= {f.links for f in dense.findings}


def test_an_obstacle_between_two_samples_is_caught(ur5: Any) -> None:
    # The forearm held level 0.51 m up; the base turns 90 deg in one sample interval, the
    # forearm sweeping through a 1 cm plate that stands radially at 45 deg.
    start = np.radians([0.0, -90.0, 90.0, -90.0, 0.0])
    goal = start.copy()
    goal[0] = math.radians(90.0)
    c = math.cos(math.pi / 4)
    wall = Obstacle(
        name="wall", kind="box", position=(0.35 * c, 0.35 * c, 0.514), rpy=(0.0, 0.0, math.pi / 4),
        size=(0.2, 0.01, 0.2),
    )  # fmt: skip
    scene = SafetyScene(mount_plane_height=0.0, obstacles=(wall,))
    ends = Samples(np.array([0.0, 1.0]), np.vstack([start, goal]), np.zeros((2, 5)))
    for q in ends.q:  # neither end touches the wall
        alone = Samples(np.array([0.0]), q[None, :], np.zeros((1, 5)))
        assert check_safety(ur5, {"m": alone}, scene=scene).ok is True
    report = check_safety(ur5, {"turn": ends}, scene=scene)
    hits = [f for f in report.findings if f.kind == "obstacle"]
    assert hits and all(f.obstacle == "wall" and f.between_samples for f in hits)
    dense = check_safety(ur5, {"turn": _dense(ends)}, scene=scene)
    assert {f.links for f in hits} <= {f.links for f in dense.findings}
    assert min(f.time for f in hits) == pytest.approx(min(f.time for f in dense.findings), abs=2e-3)
    # Without the wall the same motion is clear: the finding is the wall's.
    assert check_safety(ur5, {"turn": ends}, scene=SafetyScene()).ok is True


def test_a_robot_without_collision_geometry_is_not_checked(
    tmp_path: Path, two_link_urdf: str
) -> None:
    path = tmp_path / "two_link.urdf"
    path.write_text(two_link_urdf)
    robot = load_robot(path)
    result = plan(robot, duration=1.0, methods=("quintic", "jerk_limited"))
    safety = result.to_dict()["safety"]
    assert safety["checked"] is False and safety["ok"] is None
    assert safety["reason"] == NOT_CHECKED_NO_GEOMETRY
    assert safety["findings"] == [] and safety["min_clearance"] is None


def test_missing_collision_meshes_are_not_checked_naming_the_mesh(tmp_path: Path) -> None:
    # The UR5's URDF alone (its package:// meshes left behind): never "ok".
    urdf = tmp_path / "ur5_robot.urdf"
    urdf.write_text(robot_file(UR5).read_text())
    robot = load_robot(urdf)
    move = quintic(robot.default_start, robot.default_goal, 1.0, n_samples=11)
    report = check_safety(robot, {"quintic": move}).to_dict()
    assert report["checked"] is False and report["ok"] is None
    assert report["reason"] == (
        "not checked: the collision geometry of ur5_robot.urdf cannot be loaded "
        "(mesh base.stl not found)"
    )
    assert str(tmp_path) not in report["reason"]


def test_built_in_default_tasks_are_clear_by_the_closed_form_gaps() -> None:
    robot = load_robot("curtain_wall_6dof")
    still = Samples(np.array([0.0]), np.zeros((1, 6)), np.zeros((1, 6)))
    report = check_safety(robot, {"rest": still})
    # Hanging arm: upper arm (r 0.06) on an axis 0.15 m from the 0.08 m pedestal column;
    # the flange's lower face 1.3 - 0.495 - 0.45 - 0.1 - 0.08 - 0.06 = 0.115 m above the floor.
    assert report.ok is True
    assert report.min_clearance == pytest.approx(0.15 - 0.06 - 0.08, abs=1e-6)
    plane = SafetyScene(mount_plane_height=0.115 + 0.002)
    low = check_safety(robot, {"rest": still}, scene=plane)
    assert [(f.kind, f.links) for f in low.findings] == [("plane", ("flange",))]
    assert low.findings[0].depth == pytest.approx(0.002, abs=1e-6)
    for name in ("curtain_wall_6dof", "human_arm_2dof"):
        r = load_robot(name)
        move = quintic(r.default_start, r.default_goal, 1.0, n_samples=1001)
        assert check_safety(r, {"quintic": move}).ok is True, name


def test_the_human_arm_has_a_trunk_and_a_floor() -> None:
    robot = load_robot("human_arm_2dof")
    scene = default_scene(robot)
    assert scene.mount_plane_height == pytest.approx(-0.818 * 1.75)
    move = quintic(robot.default_start, robot.default_goal, 1.0, n_samples=501)
    report = check_safety(robot, {"curl": move})
    assert report.pairs["self"] == 2  # trunk against the forearm and the hand
    # The trunk box's face is 0.21 - 0.15 = 0.06 m from the arm's plane; the forearm's
    # radius is 0.035 m.
    assert report.min_clearance == pytest.approx(0.06 - 0.035, abs=1e-6)
    # A table under the curling hand: found, with the link that touches it.
    table = Obstacle(name="table", kind="box", position=(0.3, 0.0, -0.45), size=(0.3, 0.6, 0.1))
    with_table = check_safety(
        robot, {"curl": move}, scene=SafetyScene(scene.mount_plane_height, (table,))
    )
    assert with_table.ok is False
    assert {f.obstacle for f in with_table.findings} == {"table"}
    assert {f.links[0] for f in with_table.findings} == {"forearm_hand"}


def test_the_srdf_removes_its_pairs(ur5: Any, tmp_path: Path) -> None:
    srdf = robots_dir() / "ur_description" / "srdf" / "ur5.srdf"
    if not srdf.is_file():
        pytest.skip("example-robot-data has no ur5.srdf")
    move = quintic(ur5.default_start, ur5.default_goal, 2.0, n_samples=1001)
    plain = check_safety(ur5, {"quintic": move})
    honoured = check_safety(ur5, {"quintic": move}, scene=SafetyScene(0.0, (), srdf))
    assert honoured.pairs["self"] < plain.pairs["self"]
    # base_link-wrist_2_link is not disabled in ur5.srdf: that contact stays.
    touched = {f.links for f in honoured.findings if f.kind == "self"}
    assert ("base_link", "wrist_2_link") in touched
    for first, second in (("wrist_1_link", "wrist_3_link"), ("forearm_link", "wrist_2_link")):
        assert (first, second) not in touched
    # The same SRDF named by a sidecar (a path from the sidecar's folder) reaches the plan.
    sidecar = tmp_path / "ur5.yaml"
    sidecar.write_text(UR5_SIDECAR.read_text() + f"srdf: {srdf}\n")
    robot = load_robot(robot_file(UR5), sidecar=sidecar)
    assert default_scene(robot).srdf == srdf.resolve()
    assert check_safety(robot, {"quintic": move}).pairs == honoured.pairs


SIDECAR_HEAD = "robot: ur5\nshoulder_joint: shoulder_lift_joint\nelbow_joint: elbow_joint\n"


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ("obstacles: {name: a}\n", "obstacles"),
        ("obstacles:\n  - {kind: box, position: [0, 0, 0], size: [1, 1, 1]}\n",
         "obstacles[0].name"),
        ("obstacles:\n  - {name: a, kind: sphere, position: [0, 0, 0]}\n", "obstacles[0].kind"),
        ("obstacles:\n  - {name: a, kind: box, position: [0, 0, 0], size: [1, 0, 1]}\n",
         "obstacles[0].size"),
        ("obstacles:\n  - {name: a, kind: box, position: [0, 0], size: [1, 1, 1]}\n",
         "obstacles[0].position"),
        ("obstacles:\n  - {name: a, kind: cylinder, position: [0, 0, 0], radius: 0.1}\n",
         "obstacles[0].length"),
        ("obstacles:\n  - {name: a, kind: plane, position: [0, 0, 0], size: [1, 1, 1]}\n",
         "obstacles[0].size"),
        ("obstacles:\n  - {name: a, kind: plane, position: [0, 0, 0], normal: [0, 0, 0]}\n",
         "obstacles[0].normal"),
        ("obstacles:\n  - {name: a, kind: plane, position: [0, 0, 0]}\n"
         "  - {name: a, kind: plane, position: [0, 0, 1]}\n", "obstacles[1].name"),
        ("mount_plane: {height: low}\n", "mount_plane.height"),
        ("mount_plane: {enabled: 1}\n", "mount_plane.enabled"),
        ("mount_plane: {heigth: 0.1}\n", "mount_plane.heigth"),
        ("srdf: missing.srdf\n", "srdf is 'missing.srdf'"),
    ],
)  # fmt: skip
def test_bad_obstacles_name_the_field(tmp_path: Path, body: str, field: str) -> None:
    from app.planning.robots import RobotError
    from app.planning.robots._sidecar import read_sidecar

    path = tmp_path / "bad.yaml"
    path.write_text(SIDECAR_HEAD + body)
    with pytest.raises(RobotError) as info:
        read_sidecar(path)
    assert str(info.value).startswith("bad.yaml: ")
    assert field in str(info.value)


def test_sidecar_obstacles_and_plane_reach_the_plan(tmp_path: Path) -> None:
    sidecar = tmp_path / "ur5.yaml"
    sidecar.write_text(
        SIDECAR_HEAD
        + "mount_plane: {height: -0.5}\n"
        + "obstacles:\n"
        + "  - {name: facade, kind: plane, position: [0.5, 0, 0], normal: [-1, 0, 0]}\n"
        + "  - {name: post, kind: cylinder, position: [-0.6, 0, 0.5], radius: 0.05, length: 1}\n"
    )
    robot = load_robot(robot_file(UR5), sidecar=sidecar)
    scene = default_scene(robot)
    assert scene.mount_plane_height == -0.5
    assert [o.name for o in scene.obstacles] == ["facade", "post"]
    result = _default_ur5_plan(robot)
    safety = json.loads(json.dumps(result.to_dict()["safety"]))
    assert safety["obstacles"] == ["facade", "post"] and safety["mount_plane_height"] == -0.5
    kinds = {(f["kind"], f["obstacle"]) for f in safety["findings"]}
    # The default task reaches 0.817 m out along x at the start: through the facade at 0.5 m.
    assert ("obstacle", "facade") in kinds
    # With the plane lowered to -0.5 m, the 43 cm dip no longer touches it.
    assert not any(kind == "plane" for kind, _ in kinds)
    off = tmp_path / "off.yaml"
    off.write_text(SIDECAR_HEAD + "mount_plane: {enabled: false}\n")
    assert default_scene(load_robot(robot_file(UR5), sidecar=off)).mount_plane_height is None


def test_cli_plan_prints_the_safety_line(capsys: pytest.CaptureFixture[str]) -> None:
    from app.cli import main

    assert main(["plan", "--robot", "curtain_wall_6dof", "--method", "quintic,jerk_limited"]) == 0
    text = capsys.readouterr().out
    assert "safety: ok (min clearance 10.0 mm)" in text
    assert main(["plan", "--robot", "human_arm_2dof", "--method", "quintic,jerk_limited",
                 "--json"]) == 0  # fmt: skip
    payload = json.loads(capsys.readouterr().out)
    assert payload["safety"]["checked"] is True and payload["safety"]["ok"] is True


@pytest.mark.parametrize("which", ["ur5", "panda"])
def test_the_motion_bound_holds_on_random_moves(which: str) -> None:
    """The between-samples argument: a pair's distance never changes by more than the bound
    sum_j coef_j |Δq_j| (coal distances at random configurations a small move apart)."""
    from app.planning.safety import _collision_model
    from tests.utils.example_robots import PANDA, PANDA_LOCKS

    robot = (
        load_robot(robot_file(UR5), sidecar=UR5_SIDECAR)
        if which == "ur5"
        else load_robot(robot_file(PANDA), locks=PANDA_LOCKS)
    )
    model = _collision_model(robot, SafetyScene(mount_plane_height=0.0))
    rng = np.random.default_rng(7)
    lo = np.where(np.isfinite(robot.q_min), robot.q_min, -np.pi)
    hi = np.where(np.isfinite(robot.q_max), robot.q_max, np.pi)
    checked = 0
    for _ in range(60):
        q0 = rng.uniform(lo, hi)
        q1 = q0 + rng.normal(0.0, 0.05, robot.n_joints)
        d = model._all_distances_pin(model._pin_q(np.vstack([q0, q1])))
        bound = np.abs(q1 - q0) @ model.coefficients.T
        clear = (d[0] > 0) & (d[1] > 0)
        assert np.all(np.abs(d[1] - d[0])[clear] <= bound[clear] + 1e-9)
        checked += int(clear.sum())
        # the bound is not vacuous: of the order of the real change
        assert np.all(bound[clear] < 10.0 * np.abs(q1 - q0).sum() + 1e-12)
    assert checked > 500


def test_a_near_miss_between_samples_clears_and_the_margin_decides() -> None:
    # The hanging curtain-wall arm turns about J1 by 30 deg in one interval: the upper arm
    # keeps its 10 mm from the pedestal column throughout (a rotation about the column's axis).
    robot = load_robot("curtain_wall_6dof")
    goal = np.zeros(6)
    goal[0] = math.radians(30.0)
    move = {"turn": _two_samples(np.zeros(6), goal)}
    fine = check_safety(robot, move)
    assert fine.ok is True and fine.min_clearance == pytest.approx(0.01, abs=1e-9)
    # With a resolution coarser than the gap, the near miss counts as a contact.
    coarse = check_safety(robot, move, margin=0.1)
    assert coarse.ok is False
    assert {f.links for f in coarse.findings} >= {("pedestal", "upper_arm")}
    assert all(f.between_samples for f in coarse.findings)


def _two_link_with_mesh(two_link_urdf: str, filename: str) -> str:
    collision = f'<collision><geometry><mesh filename="{filename}"/></geometry></collision>'
    return two_link_urdf.replace(
        "</inertial></link>\n  <joint", f"</inertial>{collision}</link>\n  <joint", 1
    )


def test_collision_meshes_are_found_like_the_viewer_finds_them(
    tmp_path: Path, two_link_urdf: str
) -> None:
    stl = robots_dir() / "ur_description" / "meshes" / "ur5" / "collision" / "forearm.stl"
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(_two_link_with_mesh(two_link_urdf, str(stl)))
    assert "forearm.stl" in urdf.read_text()
    move = {"still": Samples(np.array([0.0]), np.zeros((1, 2)), np.zeros((1, 2)))}
    # One link with geometry and no plane: nothing can touch, so nothing is claimed.
    alone = check_safety(load_robot(urdf), move, scene=SafetyScene(mount_plane_height=None))
    assert alone.checked is False and alone.reason == NOT_CHECKED_NO_PAIRS
    # A local robot may name a mesh anywhere on the machine: checked.
    report = check_safety(load_robot(urdf), move, scene=SafetyScene(mount_plane_height=-5.0))
    assert report.checked is True and report.ok is True and report.pairs["plane"] == 1
    # A packaged robot (an upload) keeps its meshes in its folders: not checked, not read.
    packaged = load_robot(urdf, package_dirs=[tmp_path / "pkg"])
    refused = check_safety(packaged, move, scene=SafetyScene(mount_plane_height=None))
    assert refused.checked is False and refused.ok is None
    assert refused.reason == (
        "not checked: the collision geometry of arm.urdf cannot be loaded "
        "(mesh forearm.stl not found)"
    )
    # A device is not a mesh file: refused before anything reads it.
    urdf.write_text(_two_link_with_mesh(two_link_urdf, "/dev/zero"))
    device = check_safety(load_robot(urdf), move, scene=SafetyScene(mount_plane_height=None))
    assert device.checked is False and "mesh zero not found" in (device.reason or "")


def test_a_check_does_not_depend_on_what_was_checked_before() -> None:
    """The distance solver keeps guesses between calls: a reused one gave the same trajectory a
    clearance differing in the 11th digit after another check, so a plan served by the API was
    not the library's plan of the same request. Now the same trajectory gives the same bits
    whatever came before, equal to a fresh robot's."""
    robot = load_robot("human_arm_2dof", payload=10.0)
    task = PlanTask.default(robot)
    lift = {"lift": quintic(task.start, task.goal, 1.0, n_samples=1000)}
    other = {"other": quintic(task.start, 0.5 * task.goal, 1.3, n_samples=1000)}
    first = check_safety(robot, lift).min_clearance
    check_safety(robot, other)
    assert check_safety(robot, lift).min_clearance == first
    fresh = load_robot("human_arm_2dof", payload=10.0)
    assert check_safety(fresh, lift).min_clearance == first
