"""Optimal control keeps the sidecar's obstacles clear where they bind (issue 27).

The two-link arm of ``test_clearance_constraint`` swings from folded back to folded forward
and, unconstrained, hangs its forearm straight down half-way (tip about 0.51 m below the
shoulder, near x = -0.1 m). A box, a cylinder or a tilted plane planted there is entered by the
unconstrained bound (the safety check, coal, says so); the plan's bound is re-solved round it,
and the independent safety check (coal distances of the real collision cylinders, swept between
samples) finds it clear by the margin. The rows themselves are checked against coal's distances.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.planning.clearance import CLEARANCE_MARGIN, clearance_constraint
from app.planning.optimal import ExtraConstraints, HumanSpec, solve_optimal
from app.planning.planner import PlanTask, plan
from app.planning.robots import load_robot
from app.planning.robots._obstacles import Obstacle
from app.planning.safety import SafetyScene, check_safety
from tests.planning.test_clearance_constraint import DURATION, GOAL, START, _arm

#: The mounting plane, far below the 0.55 m arm: only the obstacles bind.
FLOOR = -1.0
BOX = "{name: stand, kind: box, position: [0, 0, -0.55], size: [0.3, 0.3, 0.2]}"
#: Axis along y (across the arm's x-z plane of motion).
CYLINDER = (
    "{name: pipe, kind: cylinder, position: [0, 0, -0.6], rpy_deg: [90, 0, 0], "
    "radius: 0.15, length: 0.4}"
)
#: A tilted floor: higher at -x (where the arm hangs), free side up.
PLANE = "{name: ramp, kind: plane, position: [0, 0, -0.47], normal: [-0.3, 0, 1]}"
FAR = "{name: far, kind: box, position: [3, 3, 3], size: [0.5, 0.5, 0.5]}"


def _robot(tmp_path: Path, *obstacles: str) -> Any:
    """The two-link arm of ``test_clearance_constraint`` with the obstacles in its sidecar."""
    _arm(tmp_path, plane=FLOOR)
    sidecar = tmp_path / "cell.yaml"
    lines = "".join(f"  - {o}\n" for o in obstacles)
    sidecar.write_text(
        "shoulder_joint: shoulder\nelbow_joint: elbow\n"
        f"mount_plane: {{height: {FLOOR}}}\n" + (f"obstacles:\n{lines}" if lines else "")
    )
    return load_robot(tmp_path / "arm.urdf", sidecar=sidecar)


def _free(robot: Any) -> Any:
    return solve_optimal(
        robot, START, GOAL, DURATION, objective="tau_sq", human=HumanSpec("none", 1)
    )


@pytest.fixture(scope="module")
def open_space(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Any]:
    """The arm without obstacles, and its unconstrained bound."""
    robot = _robot(tmp_path_factory.mktemp("open"))
    return robot, _free(robot)


@pytest.mark.parametrize(("spec", "name"), [(BOX, "stand"), (CYLINDER, "pipe"), (PLANE, "ramp")])
def test_the_bound_goes_round_an_obstacle(
    tmp_path: Path, open_space: tuple[Any, Any], spec: str, name: str
) -> None:
    robot = _robot(tmp_path, spec)
    # Unconstrained, the bound enters the obstacle (and nothing else).
    free = _free(robot)
    assert free.solver.objective == pytest.approx(open_space[1].solver.objective, rel=1e-9)
    before = check_safety(robot, {"bound": free.trajectory})
    assert before.ok is False
    assert {(f.kind, f.obstacle) for f in before.findings} == {("obstacle", name)}
    assert max(f.depth for f in before.findings) > 0.02

    result = plan(
        robot, task=PlanTask(START, GOAL), duration=DURATION, objective="tau_sq",
        methods=("quintic", "bound"),
    )  # fmt: skip
    solver = result.methods["bound"].solver
    clearance = solver["clearance"]
    assert clearance["resolved"] is True, clearance
    assert f"obstacle '{name}'" in clearance["constraint"]
    assert f"inside obstacle '{name}'" in clearance["first_contact"]
    # Only the forearm's spheres can reach it (the upper arm is 0.3 m long).
    assert 0 < clearance["obstacle_pairs"] <= 5
    # The independent check (coal, the real cylinders, swept between samples) of the bound
    # alone: clear by the spheres' margin (the spheres contain the links).
    after = check_safety(robot, {"bound": result.methods["bound"].trajectory})
    assert after.ok is True and after.min_clearance is not None
    assert after.min_clearance >= CLEARANCE_MARGIN - 1e-4
    assert [f for f in result.to_dict()["safety"]["findings"] if f["method"] == "bound"] == []
    # An obstacle can only cost.
    assert solver["objective"] >= free.solver.objective * (1 - 1e-9)
    assert solver["objective"] > free.solver.objective * 1.001


def test_a_far_obstacle_adds_no_rows_and_changes_nothing(
    tmp_path: Path, open_space: tuple[Any, Any]
) -> None:
    robot = _robot(tmp_path, FAR)
    far = Obstacle("far", "box", position=(3.0, 3.0, 3.0), size=(0.5, 0.5, 0.5))
    with_far = clearance_constraint(robot, SafetyScene(FLOOR, obstacles=(far,)))
    without = clearance_constraint(robot, SafetyScene(FLOOR))
    assert with_far is not None and without is not None
    assert with_far.obstacles == () and with_far.n_pairs == 0
    assert with_far.key() == without.key()  # one NLP structure: no row added
    # Without a plane, nothing is left to constrain.
    assert clearance_constraint(robot, SafetyScene(None, obstacles=(far,))) is None
    # Solved with it, the same optimum as with the floor alone.
    solved = [
        solve_optimal(
            robot, START, GOAL, DURATION, objective="tau_sq", human=HumanSpec("none", 1),
            extra=ExtraConstraints(clearance=constraint),
        ).solver.objective
        for constraint in (with_far, without)
    ]  # fmt: skip
    assert solved[0] == pytest.approx(solved[1], rel=1e-6)
    # Planned with it in the sidecar: the same bound as in open space.
    far_plan = plan(robot, task=PlanTask(START, GOAL), duration=DURATION, objective="tau_sq",
                    methods=("quintic", "bound"))  # fmt: skip
    open_plan = plan(open_space[0], task=PlanTask(START, GOAL), duration=DURATION,
                     objective="tau_sq", methods=("quintic", "bound"))  # fmt: skip
    assert "clearance" not in far_plan.methods["bound"].solver
    assert far_plan.methods["bound"].solver["objective"] == pytest.approx(
        open_plan.methods["bound"].solver["objective"], rel=1e-6
    )


def test_a_start_inside_an_obstacle_is_said_and_not_solved_again(tmp_path: Path) -> None:
    # Folded back at the start, the forearm's tip is at about (0.54, 0, -0.09) m: in the block.
    block = "{name: block, kind: box, position: [0.5, 0, -0.09], size: [0.1, 0.3, 0.1]}"
    robot = _robot(tmp_path, block)
    result = plan(
        robot, task=PlanTask(START, GOAL), duration=DURATION, objective="tau_sq",
        methods=("quintic", "bound"),
    )  # fmt: skip
    clearance = result.methods["bound"].solver["clearance"]
    assert clearance["resolved"] is False
    assert clearance["constraint"] == "mount plane, obstacle 'block'"
    warning = clearance["warning"]
    assert "obstacle 'block': at the start, fore is within 5 mm of it or inside" in warning
    assert "n_intervals" not in clearance  # no constrained solve was tried
    assert f"bound: {warning}" in result.warnings


def test_the_rows_agree_with_coal(tmp_path: Path) -> None:
    """The exact-distance row equals coal's distance from the point; each face row is at most
    it (a face is sufficient, not necessary)."""
    import casadi as ca
    import coal

    from app.planning.safety import _obstacle_geometry

    robot = _robot(tmp_path)
    box = Obstacle(
        "b", "box", position=(0.1, -0.2, 0.3), rpy=(0.3, -0.2, 0.9), size=(0.4, 0.2, 0.3)
    )
    cyl = Obstacle("c", "cylinder", position=(-0.1, 0.2, 0.1), rpy=(0.5, 0.4, 0.0), radius=0.15,
                   length=0.5)  # fmt: skip
    constraint = clearance_constraint(robot, SafetyScene(None, obstacles=(box, cyl)))
    assert constraint is not None
    # Both within reach of the forearm: both kept, with rows for some spheres.
    assert [o.name for o in constraint.obstacles] == ["b", "c"]
    rng = np.random.default_rng(7)
    point = ca.SX.sym("p", 3)
    for obstacle, rows in zip((box, cyl), constraint.obstacles, strict=True):
        fn = ca.Function("faces", [point], [ca.vertcat(*rows.faces(point))])
        shape, placement = _obstacle_geometry(obstacle)
        outside = 0
        for p in rng.uniform(-0.8, 0.8, (200, 3)):
            values = np.asarray(fn(p), dtype=float).ravel()
            result = coal.DistanceResult()
            tiny = coal.Sphere(1e-9)
            coal.distance(
                tiny, coal.Transform3s(np.eye(3), p), shape,
                coal.Transform3s(placement.rotation, placement.translation),
                coal.DistanceRequest(), result,
            )  # fmt: skip
            exact = max(float(result.min_distance) + 1e-9, 0.0)
            # Smoothed by ε = 1e-6 m at most twice, towards the obstacle (conservative).
            assert values[-1] == pytest.approx(exact, abs=3e-6)
            assert values[-1] <= exact + 1e-9
            assert np.all(values[:-1] <= exact + 1e-9)
            if exact > 0:
                outside += 1
                assert values[:-1].max() > 0  # outside: some face separates
            else:
                assert values[:-1].max() <= 1e-9  # inside: none does
        assert 50 < outside < 200


@pytest.mark.slow
def test_a_six_dof_bound_goes_round_a_cylinder() -> None:
    """The curtain-wall arm swinging all six joints: its wrist passes through a vertical
    cylinder (a pipe) unconstrained; with the cylinder constrained it is clear by the margin."""
    robot = load_robot("curtain_wall_6dof")
    start, goal = np.zeros(6), np.array([0.8, 0.349, 2.618, 0.4, 0.4, 0.4])
    spec, duration = HumanSpec("none", robot.elbow_joint), 2.5
    pipe = Obstacle("pipe", "cylinder", position=(0.55, 0.35, 0.75), radius=0.07, length=0.3)
    scene = SafetyScene(0.0, obstacles=(pipe,))
    free = solve_optimal(robot, start, goal, duration, objective="tau_sq", human=spec)
    before = check_safety(robot, {"bound": free.trajectory}, scene=scene)
    assert before.ok is False and {f.obstacle for f in before.findings} == {"pipe"}
    constraint = clearance_constraint(robot, scene)
    assert constraint is not None and constraint.n_pairs > 0
    kept = solve_optimal(
        robot, start, goal, duration, objective="tau_sq", human=spec,
        warm_start=free.trajectory, extra=ExtraConstraints(clearance=constraint),
    )  # fmt: skip
    after = check_safety(robot, {"bound": kept.trajectory}, scene=scene)
    assert after.ok is True and after.min_clearance is not None
    assert after.min_clearance >= CLEARANCE_MARGIN - 1e-4
    assert kept.solver.objective >= free.solver.objective * (1 - 1e-9)


def test_a_sphere_passing_through_goes_round_one_side() -> None:
    """Two spheres of one link pass straight through a box along x in the guess: each keeps
    the exact distance while clear, then the face it entered by (-x), the same third face
    (round the top, which they are nearer), the face it leaves by (+x): never opposite faces
    at consecutive points."""
    import casadi as ca

    from app.planning.clearance import _OPPOSITE, ObstacleRows, _choose_faces, _detours

    box = ObstacleRows("b", "box", np.eye(3), np.zeros(3), np.array([0.1, 0.2, 0.1]), (0,))
    point = ca.SX.sym("p", 3)
    fn = ca.Function("faces", [point], [ca.vertcat(*box.faces(point))])
    x = np.linspace(-0.4, 0.4, 81)
    clear = 0.05  # radius + margin
    beyond = [
        np.column_stack([np.asarray(fn([xi, 0.0, z]), dtype=float).ravel() for xi in x]) - clear
        for z in (0.03, 0.05)  # above the centre: the top is the nearer way round
    ]
    detours = _detours(beyond, _OPPOSITE["box"])
    assert detours == {(0, 1): 4}  # -x/+x passed through: round +z
    for values in beyond:
        rows = _choose_faces(values, _OPPOSITE["box"], detours)
        clear_points = values[-1] >= 0.0
        assert np.all(rows[clear_points] == 6)  # the exact distance where clear
        faces = [int(r) for r in rows[~clear_points]]
        assert faces[0] == 1 and faces[-1] == 0 and 4 in faces  # -x, then +z, then +x
        assert set(faces) == {0, 1, 4}
        opposite = _OPPOSITE["box"]
        assert all(opposite.get(int(a)) != int(b) for a, b in itertools.pairwise(rows))
