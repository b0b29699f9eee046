"""``--human-constraint shape``: the person's own elbow-speed shape (issue 25, item 4).

The template is built from a real recording (the pyomeca upper-limb trial: three curls with
elbow kinematics); its band is checked against the lifts' own profiles, and the robot's elbow
speed against the band on a grid 500x finer than the solver's, between its nodes too.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from app.analysis import analyze_recordings
from app.errors import BioPlanError
from app.names import HUMAN_CONSTRAINTS
from app.planning import load_robot, plan
from app.planning.human_constraints import (
    SHAPE_TOP_DROP,
    human_likeness_distance,
    speed_band,
    template_speed_on_stroke,
)
from app.planning.human_template import HumanTemplate
from app.planning.optimal import DEFAULT_INTERVALS, PiecewiseCubic
from app.planning.optimal import HUMAN_CONSTRAINTS as LIBRARY_CONSTRAINTS
from app.planning.planner import PlanResult
from tests.analysis._data import pyomeca_c3d


@pytest.fixture(scope="module")
def recorded() -> tuple[HumanTemplate, np.ndarray]:
    """The template of the real trial and its lifts' (L, K) normalised velocity profiles."""
    result = analyze_recordings([pyomeca_c3d()], load_mass=2.0)
    profiles = np.stack([r.profile.velocity for r in result.lifts if r.profile.has_kinematics])
    return result.template, profiles


def test_the_real_template_carries_the_band_of_its_lifts(
    recorded: tuple[HumanTemplate, np.ndarray],
) -> None:
    """Mean and SD over the three real lifts, recomputed here from the lifts' own profiles;
    the band holds 1 at the mean's peak, 0 below at both ends, and a clear top."""
    template, profiles = recorded
    assert template.n_lifts == profiles.shape[0] == 3 and not template.is_paper_default
    t = np.asarray(template.normalized_time)
    np.testing.assert_allclose(t, np.linspace(0.0, 1.0, profiles.shape[1]))
    np.testing.assert_allclose(template.velocity_mean, profiles.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(template.velocity_sd, profiles.std(axis=0, ddof=1), atol=1e-12)
    band = speed_band(template)
    mean = profiles.mean(axis=0) / profiles.mean(axis=0).max()
    sd = profiles.std(axis=0, ddof=1) / profiles.mean(axis=0).max()
    lower, upper = np.asarray(band.lower), np.asarray(band.upper)
    assert np.all(lower <= mean - sd + 1e-12) and np.all(lower >= 0.0)
    assert lower[0] == lower[-1] == 0.0  # the robot starts and ends at rest
    assert np.all(upper <= mean + sd + 1e-12) and np.all(upper >= mean - 1e-12)
    peak = int(np.argmax(mean))
    assert band.peak_time == pytest.approx(t[peak]) and upper[peak] >= 1.0 >= lower[peak]
    # Away from the mean's own top the speed must stay below 1 - drop: one clear top.
    outside = mean < 1.0 - SHAPE_TOP_DROP
    assert np.all(upper[outside] <= 1.0 - SHAPE_TOP_DROP + 1e-12)
    assert "3 recorded lifts" in band.source


def test_shape_is_a_constraint_everywhere_and_needs_recorded_lifts(tmp_path: Path) -> None:
    """Listed for the CLI and API (one tuple), and refused on the paper's default template
    (no recorded profile) and on one lift (no spread), naming why."""
    assert "shape" in HUMAN_CONSTRAINTS and HUMAN_CONSTRAINTS == LIBRARY_CONSTRAINTS
    with pytest.raises(BioPlanError, match=r"shape needs the elbow-speed profile.*paper default"):
        speed_band(HumanTemplate())
    one = HumanTemplate(
        normalized_time=(0.0, 0.5, 1.0), velocity_mean=(0.1, 1.0, 0.1),
        velocity_sd=(0.0, 0.0, 0.0), n_lifts=1, source="1 lift(s) with kinematics",
    )  # fmt: skip
    with pytest.raises(BioPlanError, match="at least 2 lifts"):
        speed_band(one)
    robot = load_robot("human_arm_2dof")
    with pytest.raises(BioPlanError, match="paper default"):
        plan(robot, methods=["human_optimal"], human_constraint="shape", safety=False)


def _elbow_speed(result: PlanResult, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """(τ, speed / its peak) of human_optimal's elbow on a fine grid, sampled exactly from the
    solution's piecewise cubic."""
    knots = result.methods["human_optimal"].trajectory.knots
    assert knots is not None
    tau = np.linspace(0.0, 1.0, samples)
    traj = PiecewiseCubic(*knots).sample(tau * result.duration)
    speed = np.abs(traj.qd[:, result.elbow_joint])
    return tau, speed / speed.max()


@pytest.mark.parametrize(
    ("robot_name", "objectives"),
    [("human_arm_2dof", ("tau_sq", "peak_power")), ("curtain_wall_6dof", ("tau_sq",))],
)
def test_shape_keeps_the_speed_inside_the_band_with_one_peak(
    recorded: tuple[HumanTemplate, np.ndarray], robot_name: str, objectives: tuple[str, ...]
) -> None:
    """Inside the band on a grid 500x finer than the solver's (the lower edge from the end of
    the first interval to the start of the last, where the elbow leaves and reaches rest),
    rising to one peak and falling after it, and closer to the template's shape than
    ``peak``'s optimum by the human-likeness score."""
    template, _ = recorded
    band = speed_band(template)
    robot = load_robot(robot_name)
    for objective in objectives:
        runs = {
            kind: plan(
                robot,
                template=template,
                methods=["human_optimal"],
                objective=objective,
                human_constraint=kind,
                safety=False,
            )
            for kind in ("shape", "peak")
        }
        shape = runs["shape"]
        tau, speed = _elbow_speed(shape, 500 * DEFAULT_INTERVALS + 1)
        lower = np.interp(tau, band.time, band.lower)
        upper = np.interp(tau, band.time, band.upper)
        assert np.max(speed - upper) < 1e-6, objective
        inner = (tau >= 1.0 / DEFAULT_INTERVALS) & (tau <= 1.0 - 1.0 / DEFAULT_INTERVALS)
        assert np.max((lower - speed)[inner]) < 1e-6, objective
        # Unimodal: non-decreasing up to the peak, non-increasing after it.
        top = int(np.argmax(speed))
        step = np.diff(speed)
        assert np.all(step[:top] >= -1e-9) and np.all(step[top:] <= 1e-9), objective
        assert abs(tau[top] - band.peak_time) <= 1.0 / DEFAULT_INTERVALS
        # Closer to the recorded shape than the single-peak constraint's optimum.
        e = robot.elbow_joint
        q0, q1 = float(shape.task.start[e]), float(shape.task.goal[e])
        reference, _ = template_speed_on_stroke(template, q0, q1)
        scores = {}
        for kind, result in runs.items():
            traj = result.methods["human_optimal"].trajectory
            scores[kind] = human_likeness_distance(traj.q[:, e], traj.qd[:, e], q0, q1, reference)
        assert scores["shape"] < scores["peak"], (objective, scores)
        assert json.loads(json.dumps(shape.to_dict()["conditions"]))["human_constraint"] == "shape"


def test_a_lowering_does_not_reuse_a_liftings_solver() -> None:
    """The human rules carry the stroke's direction inside the solver's graph: lowering after
    lifting (one process, as a server worker or a sweep) gives the lowering's own optimum, the
    same as with no solver built before (it was reported infeasible at every duration)."""
    from app.planning import optimal
    from app.planning.evaluation import PlanTask

    robot = load_robot("human_arm_2dof")
    lift = PlanTask.default(robot)
    lower = PlanTask(start=lift.goal, goal=lift.start)

    def tau_sq(task: PlanTask) -> float:
        result = plan(robot, task=task, methods=["human_optimal"], objective="tau_sq", safety=False)
        return float(result.objective_values["human_optimal"])

    tau_sq(lift)
    after_lift = tau_sq(lower)
    optimal._SOLVERS.clear()
    assert after_lift == pytest.approx(tau_sq(lower), rel=1e-6)
