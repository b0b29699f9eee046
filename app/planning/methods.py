"""The planning methods side by side: quintic, paper, human_optimal, bound, jerk_limited.

Each method makes one trajectory of the same task and duration; every trajectory is evaluated
the same way (:func:`app.planning.evaluation.evaluate_trajectory`) on the same report grid.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from app import names
from app.planning.energy import objective_values
from app.planning.evaluation import (
    EvaluatedTrajectory,
    PlanningError,
    PlanTask,
    evaluate_trajectory,
)
from app.planning.human_constraints import PhaseShares, phase_bound_angles, phase_shares
from app.planning.human_template import HumanTemplate
from app.planning.jerk_limited import jerk_limited
from app.planning.optimal import (
    HUMAN_CONSTRAINTS,
    HumanSpec,
    human_spec_peak,
    human_spec_phases,
    solve_optimal,
)
from app.planning.paper import PlanProblem
from app.planning.profiles import Trajectory, piecewise_quintic
from app.planning.pso import PSOResult, pso_minimize
from app.planning.robots import Robot
from app.progress import ProgressFn, report

__all__ = [
    "ALL_METHODS",
    "DEFAULT_METHODS",
    "MethodResult",
    "check_methods",
    "human_spec",
    "objective_value",
    "run_jerk_limited",
    "run_optimal",
    "run_paper",
    "share_of_achievable_pct",
]

#: Every method, in the order results list them (``app.names.METHODS``).
ALL_METHODS: tuple[str, ...] = tuple(names.METHODS)
#: What ``plan()`` computes unless told otherwise: the standard and the paper's method (the
#: service's and the sweeps' budget); the CLI asks for all of them.
DEFAULT_METHODS: tuple[str, ...] = ("quintic", "paper")


@dataclass(frozen=True)
class MethodResult:
    """One method's trajectory, evaluated, and how it was made.

    Attributes:
        name: the method (``app.names.METHODS``).
        evaluated: trajectory, torques, metrics, peak-velocity angle, violations.
        solver: how it was made (PSO, IPOPT or ruckig figures), or None for the quintic.
    """

    name: str
    evaluated: EvaluatedTrajectory
    solver: dict[str, Any] | None = None

    @property
    def trajectory(self) -> Trajectory:
        return self.evaluated.trajectory

    def to_dict(self) -> dict[str, Any]:
        out = self.evaluated.to_dict()
        out["label"] = names.METHODS[self.name].label
        out["solver"] = self.solver
        return out


def check_methods(methods: Sequence[str] | str) -> tuple[str, ...]:
    """Known method names in result order, the quintic always first (every saving's reference).

    Raises:
        PlanningError: an unknown or empty list.
    """
    items = [m.strip() for m in methods.split(",")] if isinstance(methods, str) else list(methods)
    unknown = [m for m in items if m not in ALL_METHODS]
    if unknown or not items:
        raise PlanningError(
            f"unknown method(s) {', '.join(unknown) or '(none given)'}: expected some of "
            f"{', '.join(ALL_METHODS)}"
        )
    return tuple(m for m in ALL_METHODS if m in items or m == "quintic")


def objective_value(robot: Robot, ev: EvaluatedTrajectory, objective: str) -> float:
    """The objective of one evaluated trajectory (``peak_torque``: largest |τ_j| / τ_max,j)."""
    tr = ev.trajectory
    if objective == "torque_change":
        rate = np.gradient(ev.tau, tr.t, axis=0)
        return float(np.trapezoid(np.sum(rate**2, axis=1), tr.t))
    value = objective_values(
        objective, tr.t, tr.qd, ev.tau, motors=robot.motors, tau_max=robot.tau_max
    )
    return float(value)


#: Below this saving of the bound (a fraction of the quintic's value) there is nothing to
#: achieve, and a share would only divide noise by noise (e.g. a slow lift whose quintic is
#: already on the abs_work floor) [-].
MIN_ACHIEVABLE_FRACTION = 0.01


def share_of_achievable_pct(quintic: float, method: float, bound: float) -> float:
    """100 (quintic − method) / (quintic − bound) [%]; NaN when the bound saves less than
    :data:`MIN_ACHIEVABLE_FRACTION` of the quintic's value."""
    gap = quintic - bound
    if not (math.isfinite(gap) and gap > MIN_ACHIEVABLE_FRACTION * abs(quintic)):
        return math.nan
    return 100.0 * (quintic - method) / gap


def run_paper(
    robot: Robot,
    task: PlanTask,
    *,
    duration: float,
    objective: str,
    q_via: float,
    target_deg: float,
    seed: int,
    particles: int,
    iterations: int,
    n_samples: int,
    report_samples: int,
    progress: ProgressFn | None,
) -> tuple[MethodResult, PSOResult, float]:
    """The paper's method (PSO over two quintics); returns it, the PSO result and the via time."""
    problem = PlanProblem.build(
        robot, task, duration=duration, objective=objective, q_via_elbow=q_via, n_samples=n_samples
    )

    def on_iteration(iteration: int, best_cost: float) -> None:
        report(
            progress,
            "pso",
            iteration,
            iterations,
            best=best_cost,
            message=f"PSO iteration {iteration}/{iterations}, best {objective} = {best_cost:.6g}",
        )

    result = pso_minimize(
        problem.swarm_cost,
        problem.lower,
        problem.upper,
        particles=particles,
        iterations=iterations,
        seed=seed,
        callback=on_iteration,
        initial=problem.initial,
    )
    if result.best_violation > 0:
        raise PlanningError(
            f"infeasible: no trajectory with the elbow's velocity peak at {target_deg:.1f} deg "
            f"satisfies the joint limits in {duration} s with {robot.payload.mass} kg "
            "(expected a longer duration, a lighter payload or wider limits)"
        )
    tk, qk, qdk, qddk = problem.design.knots(result.best_position[None, :])
    traj = piecewise_quintic(
        tk[0], qk[0], qdk[0], qddk[0], n_samples=report_samples, name="bio_optimized"
    )
    # No wall time here: it is in the result's ``optimizer`` (kept apart, so that the rest of a
    # result is the same bit for bit for the same inputs and seed).
    solver = {
        "kind": "pso",
        "iterations": result.iterations,
        "evaluations": result.evaluations,
        "seed": result.seed,
        "best_cost": result.best_cost,
        "via_time": float(tk[0, 1]),
    }
    evaluated = evaluate_trajectory(robot, traj, task)
    return MethodResult("paper", evaluated, solver), result, float(tk[0, 1])


def human_spec(
    kind: str, robot: Robot, task: PlanTask, template: HumanTemplate, q_via: float
) -> tuple[HumanSpec, PhaseShares | None]:
    """The human-likeness constraint of ``human_optimal`` in robot terms."""
    if kind not in HUMAN_CONSTRAINTS:
        raise PlanningError(
            f"unknown human constraint {kind!r}: expected one of {', '.join(HUMAN_CONSTRAINTS)}"
        )
    elbow = robot.elbow_joint
    if kind == "peak":
        return human_spec_peak(elbow, q_via), None
    if kind == "none":
        return HumanSpec("none", elbow), None
    q0, q1 = float(task.start[elbow]), float(task.goal[elbow])
    shares = phase_shares(template)
    angles = phase_bound_angles(template, q0, q1)
    return human_spec_phases(elbow, angles, shares.bounds), shares


def run_optimal(
    robot: Robot,
    task: PlanTask,
    *,
    name: str,
    duration: float,
    objective: str,
    spec: HumanSpec,
    warm: MethodResult | None,
    n_intervals: int,
    no_reversal: bool,
    report_samples: int,
) -> MethodResult:
    """``human_optimal`` or ``bound``: optimal control, warm-started from the paper's plan."""
    solution = solve_optimal(
        robot,
        task.start,
        task.goal,
        duration,
        objective=objective,
        human=spec,
        warm_start=None if warm is None else warm.trajectory,
        warm_start_name="quintic" if warm is None else warm.name,
        n_intervals=n_intervals,
        no_reversal=no_reversal,
        report_samples=report_samples,
        name=name,
    )
    solver = {"kind": "ipopt", **solution.solver.to_dict()}
    return MethodResult(name, evaluate_trajectory(robot, solution.trajectory, task), solver)


def run_jerk_limited(
    robot: Robot, task: PlanTask, *, duration: float, report_samples: int
) -> MethodResult:
    """The ruckig time-synchronised jerk-limited profile of the same duration."""
    traj = jerk_limited(robot, task.start, task.goal, duration, n_samples=report_samples)
    solver = {
        "kind": "ruckig",
        "max_velocity": [float(v) for v in robot.qd_max],
        "max_acceleration": [float(v) for v in np.asarray(robot.qdd_max)],
        "max_jerk": [float(v) for v in np.asarray(robot.jerk_max)],
    }
    return MethodResult("jerk_limited", evaluate_trajectory(robot, traj, task), solver)
