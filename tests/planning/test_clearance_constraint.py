"""Optimal control keeps the mounting plane clear where it binds (issue 27).

Checked against things computed independently: Pinocchio's forward kinematics for the symbolic
one, the UR5's collision meshes (trimesh vertices placed by Pinocchio) for the covering
spheres, and the safety check (coal distances, swept between samples) for the re-solved bound.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from app.planning.clearance import clearance_constraint
from app.planning.optimal import HumanSpec, solve_optimal
from app.planning.planner import PlanTask, plan
from app.planning.robots import load_robot
from app.planning.safety import SafetyScene, check_safety
from app.planning.symbolic import symbolic_chain
from tests.conftest import TWO_LINK_URDF
from tests.planning.test_safety import UR5_SIDECAR, _lowest_vertex_z
from tests.utils.example_robots import UR5, robot_file

#: The mounting plane of the two-link arm [m] (it hangs from its base at 0 m; the plane is a
#: floor below it).
PLANE = -0.40
#: From folded up and back (lowest point about -0.1 m) to folded forward (about -0.2 m): the
#: forearm must point straight down somewhere on the way; with the shoulder moving at the same
#: time, it does so about 0.49 m down (the quintic), while keeping the shoulder back until the
#: elbow has folded keeps it above -0.35 m.
START, GOAL = np.array([-1.4, 0.0]), np.array([1.0, 2.0])
DURATION = 2.0


def _arm(tmp_path: Path, plane: float = PLANE) -> Any:
    """TWO_LINK_URDF with a 3 cm cylinder along each link and a floor at ``plane``."""
    urdf = TWO_LINK_URDF.replace(
        '<link name="upper">',
        '<link name="upper"><collision><origin xyz="0 0 -0.15"/><geometry>'
        '<cylinder radius="0.03" length="0.3"/></geometry></collision>',
    ).replace(
        '<link name="fore">',
        '<link name="fore"><collision><origin xyz="0 0 -0.125"/><geometry>'
        '<cylinder radius="0.03" length="0.25"/></geometry></collision>',
    )
    urdf = urdf.replace('lower="-1.0" upper="2.5"', 'lower="-1.5" upper="2.5"')
    (tmp_path / "arm.urdf").write_text(urdf)
    sidecar = tmp_path / "arm.yaml"
    sidecar.write_text(
        f"shoulder_joint: shoulder\nelbow_joint: elbow\nmount_plane: {{height: {plane}}}\n"
    )
    return load_robot(tmp_path / "arm.urdf", sidecar=sidecar)


@pytest.fixture(scope="module")
def ur5() -> Any:
    return load_robot(robot_file(UR5), sidecar=UR5_SIDECAR)


def test_symbolic_forward_kinematics_equals_pinocchio(ur5: Any) -> None:
    import casadi as ca

    chain = symbolic_chain(ur5)
    model = ur5.dynamics().model
    data = model.createData()
    q_sym = ca.SX.sym("q", ur5.n_joints)
    poses = chain.joint_placements(q_sym)
    fn = ca.Function("fk", [q_sym], [ca.vertcat(*[ca.vec(r) for r, _ in poses]),
                                     ca.vertcat(*[p for _, p in poses])])  # fmt: skip
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-np.pi, np.pi, ur5.n_joints)
        pin.framesForwardKinematics(model, data, q)
        rots, poss = (np.asarray(v, dtype=float).ravel() for v in fn(q))
        for i in range(chain.n_joints):
            placement = data.oMi[i + 1]
            assert np.allclose(rots[9 * i : 9 * i + 9].reshape(3, 3, order="F"),
                               placement.rotation, atol=1e-12)  # fmt: skip
            assert np.allclose(poss[3 * i : 3 * i + 3], placement.translation, atol=1e-12)


def test_the_spheres_cover_the_ur5_meshes(ur5: Any) -> None:
    """Each link's lowest sphere point is at or below its mesh's lowest vertex."""
    constraint = clearance_constraint(ur5, SafetyScene(mount_plane_height=0.0), margin=0.0)
    assert constraint is not None
    links = ["upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link"]
    assert set(links) <= set(constraint.links)
    rng = np.random.default_rng(5)
    for _ in range(3):
        q = rng.uniform(ur5.q_min, ur5.q_max)
        lowest = np.asarray(constraint.lowest(ur5, q), dtype=float).ravel()
        for link in links:
            spheres = [k for k, name in enumerate(constraint.links) if name == link]
            mesh = _lowest_vertex_z(ur5, link, q)
            assert lowest[spheres].min() <= mesh + 1e-9
            # ... and not absurdly below it (the covering is near the shape).
            assert lowest[spheres].min() > mesh - 0.15


def test_the_bound_is_re_solved_clear_of_the_plane(tmp_path: Path) -> None:
    robot = _arm(tmp_path)
    # Unconstrained, the bound dips through the plane (the safety check says so).
    free = solve_optimal(
        robot, START, GOAL, DURATION, objective="tau_sq", human=HumanSpec("none", 1)
    )
    unconstrained = check_safety(robot, {"bound": free.trajectory})
    assert unconstrained.ok is False
    assert {f.kind for f in unconstrained.findings} == {"plane"}
    assert max(f.depth for f in unconstrained.findings) > 0.05

    result = plan(
        robot, task=PlanTask(START, GOAL), duration=DURATION, objective="tau_sq",
        methods=("quintic", "bound"),
    )  # fmt: skip
    safety = result.to_dict()["safety"]
    assert safety["checked"] is True
    assert [f for f in safety["findings"] if f["method"] == "bound"] == []
    assert {f["method"] for f in safety["findings"]} == {"quintic"}  # the quintic dips too
    solver = result.methods["bound"].solver
    clearance = solver["clearance"]
    assert clearance["resolved"] is True and clearance["constraint"] == "mount plane"
    assert clearance["spheres"] == 10 and clearance["plane_m"] == PLANE
    assert "warning" not in clearance
    # Clear of the plane by the margin at least, per the independent check of the bound alone.
    alone = check_safety(robot, {"bound": result.methods["bound"].trajectory})
    assert alone.ok is True and alone.min_clearance is not None
    # A constraint costs: the objective is at least the unconstrained optimum.
    assert solver["objective"] >= free.solver.objective * (1 - 1e-9)
    # The quintic is cheaper or not, it goes below the plane: outside the bound's rules.
    assert "quintic" in solver["certificate"]["outside_rules"]
    assert solver["certificate"]["beaten_by"] == []


def test_a_start_below_the_plane_is_said_and_not_solved_again(tmp_path: Path) -> None:
    robot = _arm(tmp_path, plane=-0.5)
    start = np.array([0.0, 0.0])  # hanging straight down: 0.55 m, through the plane
    result = plan(
        robot, task=PlanTask(start, np.array([1.0, 2.0])), duration=DURATION,
        objective="tau_sq", methods=("quintic", "bound"),
    )  # fmt: skip
    clearance = result.methods["bound"].solver["clearance"]
    assert clearance["resolved"] is False
    assert "at the start" in clearance["warning"] and "fore" in clearance["warning"]
    assert "n_intervals" not in clearance  # no constrained solve was tried
    assert f"bound: {clearance['warning']}" in result.warnings  # the plan says it too
