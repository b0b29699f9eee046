"""The paper's own infeasible message names the binding limit and a verified duration (issue 27).

Independent reference: a closed form for the paper's family. Each of its two segments is a
quintic from rest to the via speed v with zero acceleration at both ends; with the speed never
above v (the peak constraint) and never negative (no reversal), the segment's velocity is
v (3τ² − 2τ³) + c τ² (1 − τ)² with −3 v ≤ c ≤ 3 v, so its mean speed lies in [0.4 v, 0.6 v].
Hence (a) the elbow's stroke takes at least |Δq| / (0.6 v_max) whatever the via time, and
(b) a via point closer than 10.5 % of the stroke to its start cannot be reached at any duration
(the first segment, at least 15 % of the duration, would need a mean speed below 0.4 v).
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from app.planning.evaluation import PlanTask
from app.planning.human_template import flexion_on_stroke
from app.planning.methods import PaperInfeasible
from app.planning.optimal import OptimalResult, SolverError
from app.planning.planner import PlanFailed, plan
from app.planning.profiles import Trajectory, quintic
from app.planning.robots import Robot, load_robot
from app.planning.shortest_duration import bracket_shortest, feasibility_probe, probe_warm_name
from tests.utils.example_robots import robot_file

KINOVA = "kinova_description/robots/kinova.urdf"
#: A small PSO budget where the search's cost, not the PSO's quality, is tested.
FAST = {"particles": 8, "iterations": 6, "report_samples": 300}


@pytest.fixture(scope="module")
def kinova() -> Robot:
    return load_robot(robot_file(KINOVA), payload=1.0)


def _family_bound(robot: Robot) -> float:
    """(a): the shortest duration of the paper's family under the elbow's speed limit [s]."""
    task, e = PlanTask.default(robot), robot.elbow_joint
    return abs(float(task.goal[e] - task.start[e])) / (0.6 * float(robot.qd_max[e]))


def test_kinova_at_6_s_names_the_elbow_speed_limit_and_a_verified_duration(
    kinova: Robot,
) -> None:
    """The paper's default PSO budget: its error names joint 3's 0.628 rad/s limit and a
    duration at which the paper then plans within every limit; the closed-form bound of the
    family lies inside the stated bracket, so the duration is within 1 % of the true shortest.
    The methods that succeed are kept and compared."""
    result = plan(
        kinova, duration=6.0, methods=("quintic", "paper", "jerk_limited"), report_samples=500
    )
    assert list(result.methods) == ["quintic", "jerk_limited"]
    error = result.to_dict()["method_errors"]["paper"]
    message = error["error"]
    assert error["kind"] == "infeasible" and "\n" not in message
    assert "the best breaks joint j2s6s200_joint_3's speed limit (0.628 rad/s)" in message
    found = re.search(r"at least ([0-9.]+) s \(verified.* at \1 s, ([0-9.]+) s is not", message)
    assert found is not None, message
    stated, below = float(found.group(1)), float(found.group(2))
    bound = _family_bound(kinova)  # 6.94 s
    assert below < bound <= stated * (1 + 1e-3) and stated <= 1.01 * below + 1e-3
    exc = result.method_errors["paper"].exception
    assert isinstance(exc, PaperInfeasible) and exc.shortest_duration == stated
    # Verified: at the stated duration (as typed back) the paper's method succeeds.
    again = plan(kinova, duration=float(f"{stated:.3f}"), methods=("quintic", "paper"),
                 report_samples=500)  # fmt: skip
    paper = again.methods["paper"].evaluated
    assert not paper.violations and not again.method_errors
    elbow = kinova.elbow_joint
    assert np.abs(paper.trajectory.qd[:, elbow]).max() <= kinova.qd_max[elbow] * (1 + 1e-9)


def test_a_via_point_no_duration_reaches_says_no_duration_helps(kinova: Robot) -> None:
    """(b): a peak 5 % into the elbow's stroke cannot be met at any duration; the message says
    so and names the breach, and the search stops at 16 times the asked duration."""
    task, e = PlanTask.default(kinova), kinova.elbow_joint
    q0, q1 = float(task.start[e]), float(task.goal[e])
    angle = float(flexion_on_stroke(np.array([q0 + 0.05 * (q1 - q0)]), q0, q1)[0])
    with pytest.raises(PaperInfeasible) as info:
        plan(kinova, duration=10.0, methods=("quintic", "paper"), peak_angle_deg=angle, **FAST)
    message = str(info.value)
    assert info.value.shortest_duration is None
    assert "no duration helps: none up to 160 s is feasible" in message
    assert "expected a duration" not in message
    assert re.search(r"the best breaks (no reversal: joint j2s6s200_joint_3|the elbow's)", message)
    # A peak well inside the stroke is reached at the same duration and budget.
    middle = float(flexion_on_stroke(np.array([q0 + 0.3 * (q1 - q0)]), q0, q1)[0])
    ok = plan(kinova, duration=10.0, methods=("quintic", "paper"), peak_angle_deg=middle, **FAST)
    assert "paper" in ok.methods


def test_the_smallest_verified_duration_leads_a_failed_plan(kinova: Robot) -> None:
    """At 4.3 s (above the mean-speed bound, below ruckig's time-optimal 4.467 s) the
    jerk-limited move and the paper's family both fail: the error leads with the shorter verified
    duration, ruckig's, whose joint it names; the paper's is at least its family's bound."""
    with pytest.raises(PlanFailed) as info:
        plan(kinova, duration=4.3, methods=("quintic", "paper", "jerk_limited"), **FAST)
    message = str(info.value)
    assert message.startswith("no method but the quintic succeeded: jerk_limited: infeasible")
    jerk = info.value.failures["jerk_limited"].exception
    assert getattr(jerk, "shortest_duration", None) == pytest.approx(4.467, abs=1e-3)
    assert "joint j2s6s200_joint_3 sets it" in message and "at least 4.467 s (verified" in message
    assert (
        "jerk_limited" in plan(kinova, duration=4.467, methods=("quintic", "jerk_limited")).methods
    )
    paper = info.value.failures["paper"].exception
    assert isinstance(paper, PaperInfeasible) and paper.shortest_duration is not None
    assert paper.shortest_duration >= _family_bound(kinova) * (1 - 1e-3)


def test_bracket_shortest_finds_a_threshold_to_its_step() -> None:
    """The search alone on a known threshold (2.3456 s): the stated duration is the first
    millisecond at or above it, the one below is refused, doubling gives up past max_factor."""
    tried: list[float] = []

    def feasible(d: float) -> bool:
        tried.append(d)
        return d >= 2.3456

    found = bracket_shortest(feasible, 1.0, rel_tol=1e-6, step=1e-3)
    assert found.feasible == 2.346 and found.infeasible == 2.345
    assert found.solves == len(tried) and all(d == round(d, 3) for d in tried)
    tried.clear()

    def never(d: float) -> bool:
        tried.append(d)
        return False

    none = bracket_shortest(never, 1.0, max_factor=16.0)
    assert none.feasible is None and none.searched == 16.0 and tried == [2.0, 4.0, 8.0, 16.0]


def test_a_probe_starts_from_the_nearest_longer_solved_motion_sped_up() -> None:
    """feasibility_probe on a known threshold (1.5 s): a failed solve is "none found" and is not
    kept; each probe's warm start is the nearest longer solved motion, stretched to its own
    duration. The fake solver's motion at duration d is the quintic from 0 to d rad, so the warm
    start names its donor, and a stretched quintic is the quintic of the new duration (closed
    form)."""
    calls: list[tuple[float, float | None]] = []  # duration, the warm start's donor

    def solve(duration: float, warm: Trajectory | None) -> OptimalResult:
        donor = None if warm is None else float(warm.q[-1, 0])
        calls.append((duration, donor))
        if warm is not None:
            exact = quintic(np.zeros(2), np.full(2, donor), duration, n_samples=11)
            for got, want in zip(
                (warm.t, warm.q, warm.qd, warm.qdd),
                (exact.t, exact.q, exact.qd, exact.qdd),
                strict=True,
            ):
                np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
        if duration < 1.5:
            raise SolverError("none found", infeasible=True)
        path = quintic(np.zeros(2), np.full(2, duration), duration, n_samples=11)
        return OptimalResult(trajectory=path, knots=None, solver=None)  # type: ignore[arg-type]

    feasible, solved = feasibility_probe(solve)
    assert feasible(4.0) and feasible(2.0) and not feasible(1.0) and feasible(3.0)
    assert sorted(solved) == [2.0, 3.0, 4.0]
    assert calls == [(4.0, None), (2.0, 4.0), (1.0, 2.0), (3.0, 4.0)]
    assert probe_warm_name(None) == "quintic"
    assert probe_warm_name(solved[2.0].trajectory) == "longer probe"
