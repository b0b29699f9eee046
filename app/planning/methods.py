"""The planning methods side by side: quintic, paper, human_optimal, bound, bound_unrestricted,
jerk_limited.

Each method makes one trajectory of the same task and duration; every trajectory is evaluated
the same way (:func:`app.planning.evaluation.evaluate_trajectory`) on the same report grid.
The bounds are certified below every method under their rules (:func:`run_bound`), so a share of
the achievable saving is never above 100 % (:func:`share_of_achievable_pct`; docs/planning.md).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app import names
from app.errors import BioPlanError
from app.planning.actuators import actuator_limits, actuator_violation
from app.planning.clearance import clearance_constraint
from app.planning.energy import objective_values
from app.planning.evaluation import (
    EvaluatedTrajectory,
    PlanningError,
    PlanTask,
    evaluate_trajectory,
)
from app.planning.human_constraints import (
    PhaseShares,
    phase_bound_angles,
    phase_shares,
    speed_band,
)
from app.planning.human_template import HumanTemplate, flexion_on_stroke, joint_on_stroke
from app.planning.jerk_limited import JerkLimitedError, jerk_limited
from app.planning.optimal import (
    HUMAN_CONSTRAINTS,
    PEAK_BAND_DEG,
    PEAK_CONCAVE_DEG,
    TORQUE_MARGIN,
    ExtraConstraints,
    HumanSpec,
    OptimalResult,
    PiecewiseCubic,
    SolverError,
    human_spec_peak,
    human_spec_phases,
    human_spec_shape,
    solve_optimal,
)
from app.planning.paper import PlanProblem
from app.planning.profiles import Trajectory, piecewise_quintic
from app.planning.pso import PSOResult, pso_minimize
from app.planning.robots import Robot, RobotError
from app.planning.safety import Finding, check_safety, default_scene
from app.planning.shortest_duration import shortest_paper_duration
from app.progress import ProgressFn, report

__all__ = [
    "ALL_METHODS",
    "BOUND_TOLERANCE",
    "DEFAULT_METHODS",
    "METHOD_ERRORS",
    "BoundRules",
    "BoundViolation",
    "MethodFailure",
    "MethodResult",
    "PaperInfeasible",
    "beats_bound",
    "bound_rules",
    "check_methods",
    "failure_of",
    "human_spec",
    "mesh_error_estimate",
    "objective_value",
    "refine_to_convergence",
    "rule_breach",
    "run_bound",
    "run_jerk_limited",
    "run_optimal",
    "run_paper",
    "share_of_achievable_pct",
    "simulated_share_of_achievable_pct",
]

logger = logging.getLogger("bioplan.planning")
FloatArray = NDArray[np.float64]

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


#: A method's own failure (reported beside the others' results, docs/planning.md); any other
#: exception is a bug and still stops the plan.
METHOD_ERRORS: tuple[type[Exception], ...] = (PlanningError, SolverError, JerkLimitedError)


@dataclass(frozen=True)
class MethodFailure:
    """One method's own error, reported in place of its result.

    Attributes:
        name: the method (``app.names.METHODS``).
        error: the one-line message of its error.
        kind: ``infeasible`` (its limits or rules cannot be met in the duration),
            ``not_converged`` (IPOPT stopped without a solution) or ``refused`` (its input
            does not suit it, e.g. no finite speed limit for ``jerk_limited``).
        exception: the error itself (re-raised when it is the plan's only failure).
    """

    name: str
    error: str
    kind: str
    exception: Exception = dataclasses.field(repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        return {"error": self.error, "kind": self.kind, "label": names.METHODS[self.name].label}


def failure_of(name: str, exc: Exception) -> MethodFailure:
    """The :class:`MethodFailure` of one of :data:`METHOD_ERRORS`."""
    message = str(exc)
    if isinstance(exc, SolverError):
        kind = "infeasible" if exc.infeasible else "not_converged"
    else:
        kind = "infeasible" if message.startswith("infeasible") else "refused"
    # INFO: the plan states it (``method_errors``, ``warnings``) or fails with it.
    logger.info("%s failed (%s): %s", name, kind, message)
    return MethodFailure(name, message, kind, exc)


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


#: A method may be below the bound by this fraction of the bound's value and still count as on
#: it (share 100 %): the report grid's trapezoid and peak sampling differ between trajectories
#: (by up to 1.7e-5 of the value where graded ends put pieces near a report step: the human
#: arm's human-like `abs_work`, 1.5e-3 J below the floor |ΔPE| = 87.576 J by its net work's
#: trapezoid error), and the bound's smoothing term (``optimal.REGULARIZATION``) may hold it up
#: to 1e-5 above its optimum on objectives with many optima [-].
BOUND_TOLERANCE = 5e-5
#: Warm starts of the bound: the best this many methods' trajectories under its rules.
BOUND_STARTS = 2
#: The bound is refined from a method that still beats it up to this many times the intervals.
BOUND_MAX_REFINEMENT = 4


class BoundViolation(RuntimeError):
    """A method beats the bound on its objective by more than :data:`BOUND_TOLERANCE`: the bound
    is not one (a bug, or a method outside the bound's rules); never reported as a share."""


def beats_bound(
    method: float, bound: float, tolerance: float = BOUND_TOLERANCE, *, scale: float = 0.0
) -> bool:
    """Whether ``method`` is below ``bound`` by more than ``tolerance`` of the larger of the
    bound's value and ``scale`` (the task's size of the objective, e.g. the quintic's value:
    a bound of 0 J, a lowering that regenerates nothing, has no relative round-off)."""
    return method < bound - tolerance * max(abs(bound), abs(scale), 1e-12)


def share_of_achievable_pct(
    quintic: float, method: float, bound: float, *, tolerance: float = BOUND_TOLERANCE
) -> float:
    """100 (quintic − method) / (quintic − bound) [%], never above 100.

    NaN when the bound saves less than :data:`MIN_ACHIEVABLE_FRACTION` of the quintic's value.
    A method on the bound within ``tolerance`` of its value scores 100.

    Raises:
        BoundViolation: the method beats the bound by more than ``tolerance``.
    """
    gap = quintic - bound
    if not (math.isfinite(gap) and gap > MIN_ACHIEVABLE_FRACTION * abs(quintic)):
        return math.nan
    if beats_bound(method, bound, tolerance, scale=quintic):
        raise BoundViolation(
            f"a method ({method:.9g}) beats the bound ({bound:.9g}) by more than "
            f"{tolerance:g} of its value: the bound does not bound"
        )
    if method <= bound:  # on the bound, within the tolerance
        return 100.0
    return 100.0 * (quintic - method) / gap


#: A simulated method may beat the simulated bound by this fraction of its value and still
#: count as on it: the tracking simulation moves each plan's metrics by up to about 0.1 %
#: (computed torque, 1 ms steps), so a method planned within that of the bound can cross it [-].
SIMULATED_BOUND_TOLERANCE = 2e-3


def simulated_share_of_achievable_pct(quintic: float, method: float, bound: float) -> float:
    """:func:`share_of_achievable_pct` of simulated values, with the simulation's tolerance
    :data:`SIMULATED_BOUND_TOLERANCE`; NaN (with a logged error) instead of a share above 100 %
    when a simulated method beats the simulated bound by more than that."""
    try:
        return share_of_achievable_pct(quintic, method, bound, tolerance=SIMULATED_BOUND_TOLERANCE)
    except BoundViolation as exc:
        logger.error("simulated share not given: %s", exc)
        return math.nan


class PaperInfeasible(PlanningError):
    """The paper's PSO found no trajectory of its family (elbow velocity peak at the template
    angle) within the limits; the task itself may still be feasible for the other methods.

    Attributes:
        shortest_duration: the shortest duration [s] at which the same PSO found one within
            every limit (None: no duration helps).
    """

    def __init__(self, message: str, *, shortest_duration: float | None = None) -> None:
        super().__init__(message)
        self.shortest_duration = shortest_duration


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
    logger.info(
        "paper: PSO of %d particles x %d iterations, seed %d, %s over %g s, via angle %.1f deg",
        particles, iterations, seed, objective, duration, target_deg,
    )  # fmt: skip
    started = time.perf_counter()

    def on_iteration(iteration: int, best_cost: float) -> None:
        logger.debug("paper: PSO iteration %d/%d, best %s = %.6g", iteration, iterations,
                     objective, best_cost)  # fmt: skip
        report(
            progress,
            "pso",
            iteration,
            iterations,
            best=best_cost,
            message=f"PSO iteration {iteration}/{iterations}, best {objective} = {best_cost:.6g}",
        )

    def swarm(at: float, callback: Any = None) -> tuple[PlanProblem, PSOResult]:
        """The paper's PSO at the duration ``at`` [s] (the same seed and budget)."""
        problem = PlanProblem.build(
            robot, task, duration=at, objective=objective, q_via_elbow=q_via, n_samples=n_samples
        )
        return problem, pso_minimize(
            problem.swarm_cost,
            problem.lower,
            problem.upper,
            particles=particles,
            iterations=iterations,
            seed=seed,
            callback=callback,
            initial=problem.initial,
        )

    problem, result = swarm(duration, on_iteration)
    logger.info(
        "paper: best %s = %.6g after %d evaluations, violation %.3g, in %.2f s",
        objective, result.best_cost, result.evaluations, result.best_violation,
        time.perf_counter() - started,
    )  # fmt: skip
    if result.best_violation > 0:
        # The family only slows down with a longer duration: search the shortest one at which
        # the same PSO finds a trajectory within every limit (or say that none helps).
        found = shortest_paper_duration(
            robot, task, duration, (problem, result), swarm, report_samples=report_samples
        )
        raise PaperInfeasible(
            f"infeasible: no trajectory with the elbow's velocity peak at {target_deg:.1f} deg "
            f"satisfies the joint limits in {duration:g} s with {robot.payload.mass:g} kg (the "
            f"best breaks {found.breach}): {found.describe()}",
            shortest_duration=found.duration,
        )
    method, via_time = _paper_method(robot, task, problem, result, report_samples)
    return method, result, via_time


def _paper_method(
    robot: Robot, task: PlanTask, problem: PlanProblem, result: PSOResult, report_samples: int
) -> tuple[MethodResult, float]:
    """The paper's trajectory (``report_samples`` samples) from the PSO's best particle,
    evaluated, with the solver's summary; and its via time [s]."""
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
    return MethodResult("paper", evaluated, solver), float(tk[0, 1])


def _peak_spec(elbow: int, task: PlanTask, q_via: float) -> HumanSpec:
    """The ``peak`` constraint with its side angles :data:`PEAK_BAND_DEG` and
    :data:`PEAK_CONCAVE_DEG` of flexion from the peak (an angle is left out when it would not
    lie strictly inside the stroke)."""
    q0, q1 = float(task.start[elbow]), float(task.goal[elbow])
    peak_deg = float(flexion_on_stroke(np.array([q_via]), q0, q1)[0])
    lo, hi = sorted((q0, q1))
    margin = 1e-3 * (hi - lo)

    def side(offset: float) -> float | None:
        angle = joint_on_stroke(peak_deg + offset, q0, q1)
        return angle if lo + margin < angle < hi - margin else None

    return human_spec_peak(
        elbow,
        q_via,
        near=(side(-PEAK_BAND_DEG), side(PEAK_BAND_DEG)),
        wide=(side(-PEAK_CONCAVE_DEG), side(PEAK_CONCAVE_DEG)),
    )


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
        return _peak_spec(elbow, task, q_via), None
    if kind == "none":
        return HumanSpec("none", elbow), None
    if kind == "shape":
        band = speed_band(template)
        return human_spec_shape(elbow, band.time, band.lower, band.upper, band.peak_time), None
    q0, q1 = float(task.start[elbow]), float(task.goal[elbow])
    shares = phase_shares(template)
    angles = phase_bound_angles(template, q0, q1)
    return human_spec_phases(elbow, angles, shares.bounds), shares


def _within_actuators(
    robot: Robot, task: PlanTask, duration: float, limits: Any, solve: dict[str, Any]
) -> tuple[OptimalResult, EvaluatedTrajectory]:
    """``solve`` (:func:`solve_optimal`'s keywords, warm-started from the violating solution)
    again with the actuators' ``limits`` as constraints. Kept at the evaluation points, they may
    still be crossed between them on a coarse mesh: then once more on twice the intervals (a
    uniform mesh)."""
    first = n = int(solve["n_intervals"])
    while True:
        solution = solve_optimal(
            robot, task.start, task.goal, duration, extra=ExtraConstraints(actuators=limits),
            **{**solve, "n_intervals": n},
        )  # fmt: skip
        evaluated = evaluate_trajectory(robot, solution.trajectory, task)
        if actuator_violation(robot, evaluated) is None or n >= 2 * first:
            return solution, evaluated
        n *= 2
        solve = {**solve, "warm_start": solution.trajectory, "interval_weights": None,
                 "segment_counts": None}  # fmt: skip


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
    near_optimum: bool = False,
    interval_weights: Sequence[float] | None = None,
    segment_counts: Sequence[int] | None = None,
    end_grading: int | None = None,
) -> MethodResult:
    """``human_optimal`` or ``bound``: optimal control, warm-started from the paper's plan.

    ``near_optimum``: ``warm`` is already an optimum of this problem on a coarser mesh (mesh
    refinement): IPOPT starts from it with a small barrier parameter
    (``ExtraConstraints.warm``), and again with its default options should that fail.
    ``interval_weights``, ``segment_counts``, ``end_grading``: the mesh (:func:`solve_optimal`);
    the re-solves clear of obstacles on more intervals take the default grading.
    """
    solve: dict[str, Any] = {
        "objective": objective, "human": spec, "n_intervals": n_intervals,
        "warm_start": None if warm is None else warm.trajectory,
        "warm_start_name": "quintic" if warm is None else warm.name,
        "no_reversal": no_reversal, "report_samples": report_samples, "name": name,
        "interval_weights": interval_weights, "segment_counts": segment_counts,
        "end_grading": end_grading,
    }  # fmt: skip
    solution = _first_solve(
        robot, task, duration, solve, warm_refine=near_optimum and warm is not None
    )
    evaluated = evaluate_trajectory(robot, solution.trajectory, task)
    # Actuators that can say no (issue 26): a solution outside the actuators' torque-speed
    # envelopes or RMS limits is solved again with them as constraints, from itself. Only then:
    # their rows make every solve 2-3x slower and rarely bind.
    limits = actuator_limits(robot)
    said_no = actuator_violation(robot, evaluated) if limits is not None else None
    if said_no is not None and limits is not None:
        solve.update(warm_start=solution.trajectory, warm_start_name=name)
        solution, evaluated = _within_actuators(robot, task, duration, limits, solve)
    # Clearance where it binds (issue 27): a solution that the safety check finds below the
    # mounting plane or inside an obstacle is solved again with the plane and the obstacles as
    # constraints, from itself. Only then, as the actuators above: most tasks stay clear
    # unconstrained.
    finding = world_finding(robot, name, solution.trajectory)
    clearance: dict[str, Any] | None = None
    if finding is not None:
        what = "mount plane" if finding.kind == "plane" else f"obstacle '{finding.obstacle}'"
        clearance = {"constraint": what, "first_contact": finding.describe()}
        solve = {
            "objective": objective, "human": spec, "no_reversal": no_reversal,
            "report_samples": report_samples, "name": name, "warm_start_name": name,
            "actuators": limits if said_no is not None else None,
        }  # fmt: skip
        solution, evaluated = _keep_clearance(robot, task, solution, evaluated, duration,
                                              n_intervals, solve, clearance)  # fmt: skip
    solver = {"kind": "ipopt", **solution.solver.to_dict()}
    logger.info(
        "%s: IPOPT %s in %d iterations, %.2f s, %d intervals, warm start %s, objective %.6g%s%s",
        name, solution.solver.status, solution.solver.iterations, solution.solver.seconds,
        solution.solver.n_intervals, solution.solver.warm_start, solution.solver.objective,
        ", re-solved within the actuators' limits" if said_no is not None else "",
        f", re-solved clear of the {clearance['constraint']}" if clearance else "",
    )  # fmt: skip
    if said_no is not None:
        solver["actuators"] = {"constrained": True, "first_violation": said_no}
    if clearance is not None:
        solver["clearance"] = clearance
    return MethodResult(name, evaluated, solver)


def _first_solve(
    robot: Robot, task: PlanTask, duration: float, solve: dict[str, Any], *, warm_refine: bool
) -> OptimalResult:
    """:func:`solve_optimal` with the keyword arguments ``solve``, over ``duration`` [s].

    ``warm_refine``: the warm start is an optimum on a coarser mesh; IPOPT first starts from it
    with a small barrier parameter, then with its default options should that fail (not when
    the problem is infeasible).
    """
    if warm_refine:
        try:
            return solve_optimal(
                robot, task.start, task.goal, duration, explain=False,
                extra=ExtraConstraints(warm=True), **solve,
            )  # fmt: skip
        except SolverError as exc:
            if exc.infeasible:
                raise
            logger.info("%s: the warm refinement on %d intervals failed (%s): default options",
                        solve["name"], solve["n_intervals"], exc)  # fmt: skip
    return solve_optimal(robot, task.start, task.goal, duration, **solve)


def world_finding(robot: Robot, name: str, trajectory: Trajectory) -> Finding | None:
    """The safety check's first finding of ``trajectory`` below the mounting plane or inside
    an obstacle, or None (also when the robot cannot be checked)."""
    report = check_safety(robot, {name: trajectory})
    return next((f for f in report.findings if f.kind in ("plane", "obstacle")), None)


def _keep_clearance(
    robot: Robot,
    task: PlanTask,
    solution: Any,
    evaluated: EvaluatedTrajectory,
    duration: float,
    n_intervals: int,
    solve: dict[str, Any],
    info: dict[str, Any],
) -> tuple[Any, EvaluatedTrajectory]:
    """Re-solve with the mounting plane and the obstacles as constraints (spheres covering the
    links, at the evaluation points), on N then 2N intervals until the safety check finds no
    plane or obstacle contact (each solve chooses the obstacles' faces at its warm start).

    ``info`` gains ``constraint`` (what is kept clear), ``spheres``, ``margin_m``, ``plane_m``,
    ``obstacle_pairs`` (sphere-obstacle pairs with rows), ``n_intervals``, ``resolved`` and,
    when it is not, ``warning`` (the start or goal itself is within the margin of the plane or
    an obstacle, the constrained problem failed, or a contact is left between the points:
    ``remaining``).
    """
    info["resolved"] = False
    try:
        constraint = clearance_constraint(robot, default_scene(robot))
    except RobotError as exc:
        constraint, info["warning"] = None, f"clearance not constrained: {exc}"
    if constraint is None:
        info.setdefault(
            "warning", "clearance not constrained: no plane, no reachable obstacle or no moving "
            "geometry"
        )  # fmt: skip
        logger.warning("%s", info["warning"])
        return solution, evaluated
    info.update(
        constraint=constraint.describe(), spheres=constraint.n_spheres,
        margin_m=constraint.margin, plane_m=constraint.plane, obstacle_pairs=constraint.n_pairs,
    )  # fmt: skip
    for where, q in (("start", task.start), ("goal", task.goal)):
        blocked = constraint.blocked(robot, q)
        if blocked:
            # No trajectory from or to there keeps the clearance: say so, do not try.
            what, links = blocked[0]
            side = "below" if what == "the mount plane" else "inside"
            info["warning"] = (
                f"no trajectory keeps clear of {what}: at the {where}, {', '.join(links)} is "
                f"within {1000 * constraint.margin:.0f} mm of it or {side}"
            )
            logger.warning("%s", info["warning"])
            return solution, evaluated
    actuators = solve.pop("actuators")
    n = n_intervals
    while n <= 2 * n_intervals:
        try:
            solution = solve_optimal(
                robot, task.start, task.goal, duration, warm_start=solution.trajectory,
                n_intervals=n, explain=False,
                extra=ExtraConstraints(actuators=actuators, clearance=constraint),
                **solve,
            )  # fmt: skip
        except SolverError as exc:
            info["warning"] = f"the clearance of {constraint.describe()} could not be kept: {exc}"
            logger.warning("%s", info["warning"])
            return solution, evaluated
        evaluated = evaluate_trajectory(robot, solution.trajectory, task)
        info["n_intervals"] = n
        left = world_finding(robot, str(solve["name"]), solution.trajectory)
        if left is None:
            info["resolved"] = True
            info.pop("remaining", None)
            return solution, evaluated
        info["remaining"] = left.describe()
        n *= 2
    info["warning"] = f"a contact is left between the points: {info['remaining']}"
    logger.warning("%s", info["warning"])
    return solution, evaluated


#: Mesh refinement stops when the objective changes by less than this fraction [-] ...
CONVERGENCE_TOLERANCE = 1e-3
#: ... or at this many intervals.
MAX_CONVERGENCE_INTERVALS = 320
#: The largest ratio of successive changes trusted by :func:`mesh_error_estimate` (second
#: order: halving the intervals divides the error by 4) [-].
_MAX_OBSERVED_RATIO = 4.0


def mesh_error_estimate(values: Sequence[float], *, halving: bool = True) -> tuple[float, bool]:
    """The error estimate of the last of the objectives on meshes N, 2N, 4N, ... and whether
    it is an extrapolation (Richardson's, from the observed order).

    With three or more values whose last two changes d1 = J(N/2) − J(N) and d2 = J(N) − J(2N)
    shrink with the same sign (ratio r = d1 / d2 >= 2: at least first order), the error left in
    the last value is the geometric tail d2 / (r − 1) (r capped at 4, second order). Otherwise
    the last change itself |d2| (the error of a first-order sequence, an upper estimate of a
    faster one). Relative to the last value [-]; NaN with fewer than two values.

    ``halving=False`` (adaptive meshes, :func:`refined_mesh`): a step halves only some
    intervals, so the ratio of two changes is no order of the method and "at least first
    order" (r >= 2) is no longer known. Then the geometric tail d2 / (r − 1) is used for any
    shrinking ratio r > 1 (capped at 4), which is larger than the last change when the changes
    shrink slower than by half, and the last change itself otherwise (not an extrapolation).
    """
    if len(values) < 2:
        return math.nan, False
    last = values[-1]
    size = max(abs(values[-2]), abs(last), 1e-12)
    d2 = values[-2] - last
    change = abs(d2) / size
    if len(values) >= 3 and d2 != 0.0:
        ratio = (values[-3] - values[-2]) / d2
        if ratio >= (2.0 if halving else 1.0 + 1e-9):
            return change / (min(ratio, _MAX_OBSERVED_RATIO) - 1.0), True
    return change, False


#: Whether :func:`refine_to_convergence` refines adaptively by default (halving only the
#: intervals :func:`refined_mesh` flags) instead of doubling the mesh.
ADAPTIVE_MESH = False
#: Adaptive refinement (:func:`refined_mesh`): an interval is halved when a limit is within
#: this fraction of binding on it (torque, speed, position, or the no-reversal rule's zero
#: speed, relative to the joint's limit) [-] ...
ACTIVE_BAND = 0.01
#: ... and, so that every step makes progress where the solution is smooth too, at least this
#: fraction of the intervals: those whose jerk jumps most to a neighbour (the constant-jerk
#: transcription's local error) [-].
PROGRESS_FRACTION = 0.25
#: An interval whose jerk jump is this many times the progress fraction's is quartered [-].
QUARTER_ABOVE = 16.0
#: Points per interval at which the indicator is evaluated (Pinocchio's inverse dynamics).
_INDICATOR_POINTS = 9


def mesh_of(result: MethodResult) -> tuple[FloatArray, tuple[int, ...]]:
    """The node times (N+1,) [s] and the intervals per segment of an optimal-control result."""
    knots = result.trajectory.knots
    if knots is None:
        raise BioPlanError(f"{result.name}: the result carries no mesh (knots)")
    t = np.asarray(knots[0], dtype=np.float64)
    durations = list((result.solver or {}).get("segment_durations") or [t[-1] - t[0]])
    joins = [int(np.argmin(np.abs(t - j))) for j in np.cumsum(durations)[:-1]]
    counts = tuple(int(c) for c in np.diff([0, *joins, t.size - 1]))
    return t, counts


def refined_mesh(
    robot: Robot, result: MethodResult, objective: str, no_reversal: bool, task: PlanTask
) -> tuple[int, tuple[float, ...], tuple[int, ...], int]:
    """The next adaptive mesh: the intervals of ``result``'s mesh where the error sits, split.

    Evaluated at :data:`_INDICATOR_POINTS` points of every interval (the knots sampled exactly,
    the robot's inverse dynamics): an interval is halved where a limit switches between
    binding and not within it (within :data:`ACTIVE_BAND`: torque with the solver's margin,
    speed, position, the no-reversal rule's zero speed of a moving joint), and so are its
    neighbours; then, to at least :data:`PROGRESS_FRACTION` of all intervals, those whose jerk
    jumps most to a neighbour (scaled by the stroke, times the shorter interval); an interval
    whose jump is :data:`QUARTER_ABOVE` times that fraction's, the first and last intervals
    (rest to rest) and both sides of every segment join (the human rules) are quartered
    (flagging where a peak objective is near its peak flags nearly every interval: measured,
    left out). The meshes are nested: a cubic on an interval is a cubic on its pieces.

    Returns:
        (N', relative interval lengths (N',), intervals per segment, intervals split).
    """
    t, counts = mesh_of(result)
    traj = result.trajectory
    assert traj.knots is not None
    _, kq, kqd, kqdd = (np.asarray(a, dtype=np.float64) for a in traj.knots)
    n_int = t.size - 1
    h = np.diff(t)
    frac = np.linspace(0.0, 1.0, _INDICATOR_POINTS)
    times = (t[:-1, None] + h[:, None] * frac[None, :]).ravel()
    times = np.clip(times, t[0], t[-1])
    sampled = PiecewiseCubic(t=t, q=kq, qd=kqd, qdd=kqdd).sample(times)
    tau = robot.dynamics().inverse_dynamics(sampled.q, sampled.qd, sampled.qdd)
    shape = (n_int, _INDICATOR_POINTS)
    tau_max = np.asarray(robot.tau_max, dtype=np.float64)
    qd_max = np.asarray(robot.qd_max, dtype=np.float64)
    torque = (np.abs(tau) / tau_max).max(axis=1).reshape(shape)
    speed = (np.abs(sampled.qd) / qd_max).max(axis=1).reshape(shape)
    # Each limit's activity at every point (N, P); an interval is flagged where one switches
    # (some points active, some not): there constant jerk cannot follow the solution's kink.
    # Where a limit holds throughout (a joint resting at zero speed) halving changes nothing.
    active = [
        torque >= 1.0 - TORQUE_MARGIN - ACTIVE_BAND,
        speed >= 1.0 - ACTIVE_BAND,
    ]
    q_min, q_max = np.asarray(robot.q_min, float), np.asarray(robot.q_max, float)
    span = np.where(np.isfinite(q_max - q_min), q_max - q_min, np.inf)
    gap = np.minimum(sampled.q - q_min, q_max - sampled.q) / span
    active.append((gap.min(axis=1) <= ACTIVE_BAND).reshape(shape))
    stroke = task.goal - task.start
    moving = np.abs(stroke) > 0
    if no_reversal and moving.any():
        along = (np.sign(stroke) * sampled.qd / qd_max)[:, moving].min(axis=1).reshape(shape)
        # Interior points only: every joint is at rest at both ends by the boundary conditions.
        ends = (times <= t[0] + 1e-12) | (times >= t[-1] - 1e-12)
        active.append((along <= ACTIVE_BAND) & ~ends.reshape(shape))
    flags = np.zeros(n_int, dtype=bool)
    for act in active:
        flags |= act.any(axis=1) & ~act.all(axis=1)
    flags = flags | np.r_[flags[1:], False] | np.r_[False, flags[:-1]]
    scale = np.maximum(np.abs(stroke), 0.1) / float(t[-1] - t[0]) ** 3
    jerk = np.diff(kqdd, axis=0) / h[:, None] / scale
    # The jump between intervals k and k + 1 times the shorter of them: the change of the
    # acceleration the jump stands for. It does not shrink where the solution's jerk is
    # singular (the rest-to-rest ends: q̈ = 0 there, the optimum wants a step), so those
    # intervals are halved again and again, a mesh graded towards the end.
    jumps = np.abs(np.diff(jerk, axis=0)).max(axis=1) * np.minimum(h[:-1], h[1:])
    local = np.maximum(np.r_[jumps, 0.0], np.r_[0.0, jumps])
    least = math.ceil(PROGRESS_FRACTION * n_int)
    threshold = float(np.sort(local)[::-1][least - 1])
    if int(flags.sum()) < least:
        order = np.argsort(-np.where(flags, -np.inf, local), kind="stable")
        flags[order[: least - int(flags.sum())]] = True
    # Far above the rest (a singular end), quarters: two levels in one step.
    pieces = np.where(flags, 2, 1)
    pieces[local >= QUARTER_ABOVE * max(threshold, 1e-300)] = 4
    # Always quartered: the intervals at both ends (rest to rest holds q̈ = 0 there while the
    # optimum wants a step of the acceleration) and on both sides of every segment join (the
    # human rules switch there: the elbow's q̈ changes sign at the peak).
    joins = np.cumsum(counts)[:-1]
    pieces[[0, n_int - 1, *(joins - 1), *joins]] = 4
    lengths, new_counts = _split(h, counts, pieces)
    return sum(new_counts), lengths, new_counts, int((pieces > 1).sum())


def _split(
    h: FloatArray, counts: tuple[int, ...], pieces: NDArray[np.int_]
) -> tuple[tuple[float, ...], tuple[int, ...]]:
    """Intervals ``h`` (N,) [s] cut into ``pieces`` (N,) equal parts each: the new relative
    lengths within each segment (N',) and the new intervals per segment."""
    lengths: list[float] = []
    new_counts, first = [], 0
    for count in counts:
        seg_h = h[first : first + count] / h[first : first + count].sum()
        seg_pieces = pieces[first : first + count]
        for length, k in zip(seg_h, seg_pieces, strict=True):
            lengths.extend([float(length) / int(k)] * int(k))
        new_counts.append(int(seg_pieces.sum()))
        first += count
    return tuple(lengths), tuple(new_counts)


def _interval_extent(result: MethodResult) -> tuple[float, float]:
    """The smallest and largest interval [s] of an optimal-control result's mesh (NaN without
    one)."""
    knots = result.trajectory.knots
    if knots is None:
        return math.nan, math.nan
    h = np.diff(np.asarray(knots[0], dtype=np.float64))
    return float(h.min()), float(h.max())


def refine_to_convergence(
    robot: Robot,
    task: PlanTask,
    result: MethodResult,
    *,
    duration: float,
    objective: str,
    spec: HumanSpec,
    no_reversal: bool,
    report_samples: int,
    keep_lowest: bool,
    adaptive: bool | None = None,
) -> MethodResult:
    """An optimal-control result refined on meshes of 2N, 4N, ... intervals, each warm-started
    from the last with IPOPT's small initial barrier parameter (``near_optimum``), until its
    objective (on the report grid) changes by less than :data:`CONVERGENCE_TOLERANCE`, or from
    the third mesh on the Richardson estimate of the error left (:func:`mesh_error_estimate`)
    is below it (or :data:`MAX_CONVERGENCE_INTERVALS`, or a failed solve).

    ``adaptive`` (None = :data:`ADAPTIVE_MESH`): each finer mesh halves only the intervals
    :func:`refined_mesh` picks, up to :data:`MAX_CONVERGENCE_INTERVALS` in all, and stops only
    on the error estimate (``halving=False``) from the third mesh on (a step that halves a few
    intervals changes the objective less than the error left). ``shape`` is always uniform.

    The result's ``solver`` gains ``convergence``: ``sequence`` (every mesh's intervals,
    objective, ``smallest_interval`` and ``largest_interval`` [s]), ``relative_change`` (the
    last step's), ``error_estimate`` (of the final value) and ``extrapolated`` (whether it is
    Richardson's), ``converged``, ``final_intervals``, ``tolerance`` and ``adaptive``.
    ``keep_lowest`` (bounds): the meshes are nested (a cubic on an interval is cubic on its
    halves), so a finer optimum is never above a coarser one; should IPOPT return one that is,
    the lower is kept.
    """
    n = int((result.solver or {}).get("n_intervals", 0))
    # The first mesh's graded ends are kept: the finer meshes nest in it, their pieces shrink.
    grading = int((result.solver or {}).get("end_grading", 0))
    adaptive = ADAPTIVE_MESH if adaptive is None else adaptive
    adaptive = adaptive and spec.kind != "shape" and result.trajectory.knots is not None
    value = objective_value(robot, result.evaluated, objective)
    sequence: list[dict[str, Any]] = [_mesh_entry(result, n, value)]
    values = [value]
    best, best_value, change, converged = result, value, math.nan, False
    estimate, extrapolated = math.nan, False
    current = result
    while n > 0:
        mesh = _next_mesh(robot, task, current, objective, no_reversal, n, adaptive)
        if mesh is None:
            break
        n, weights, counts = mesh
        try:
            finer = run_optimal(
                robot, task, name=result.name, duration=duration, objective=objective,
                spec=spec, warm=current, n_intervals=n, no_reversal=no_reversal,
                report_samples=report_samples, near_optimum=True,
                interval_weights=weights, segment_counts=counts, end_grading=grading,
            )  # fmt: skip
        except SolverError as exc:
            sequence.append({"n_intervals": n, "error": str(exc)})
            logger.warning("%s: refinement stopped at %d intervals: %s", result.name, n, exc)
            break
        new = objective_value(robot, finer.evaluated, objective)
        sequence.append(_mesh_entry(finer, n, new))
        values.append(new)
        change = abs(new - value) / max(abs(value), abs(new), 1e-12)
        estimate, extrapolated = mesh_error_estimate(values, halving=not adaptive)
        logger.debug("%s: %d intervals, %s = %.6g (change %.2g, error estimate %.2g)",
                     result.name, n, objective, new, change, estimate)  # fmt: skip
        current, value = finer, new
        if not keep_lowest or new <= best_value:
            best, best_value = finer, new
        stop = estimate < CONVERGENCE_TOLERANCE and (not adaptive or len(values) >= 3)
        if stop or (not adaptive and change < CONVERGENCE_TOLERANCE):
            converged = True
            break
    evidence = {
        "sequence": sequence, "relative_change": change, "error_estimate": estimate,
        "extrapolated": extrapolated, "converged": converged, "tolerance": CONVERGENCE_TOLERANCE,
        "adaptive": adaptive,
    }  # fmt: skip
    return _with_evidence(result, best, evidence)


def _with_evidence(
    first: MethodResult, best: MethodResult, evidence: dict[str, Any]
) -> MethodResult:
    """``best`` (the refined result kept) with the first solve's multistart and certificate
    records and ``convergence`` = ``evidence`` + ``final_intervals``."""
    out = dict(best.solver or {})
    for key in ("multistart", "starts", "rules", "certificate"):
        if key in (first.solver or {}):
            out[key] = (first.solver or {})[key]
    final = int(out.get("n_intervals", 0))
    logger.info(
        "%s: mesh refinement %s at %d intervals (last change %.2g, tolerance %g)", first.name,
        "converged" if evidence["converged"] else "did not converge", final,
        evidence["relative_change"], CONVERGENCE_TOLERANCE,
    )  # fmt: skip
    out["convergence"] = {**evidence, "final_intervals": final}
    return MethodResult(first.name, best.evaluated, out)


def _mesh_entry(result: MethodResult, n: int, value: float) -> dict[str, Any]:
    """One mesh of a refinement's ``sequence``: intervals, objective, interval extent [s]."""
    small, large = _interval_extent(result)
    return {"n_intervals": n, "objective": value, "smallest_interval": small,
            "largest_interval": large}  # fmt: skip


def _next_mesh(
    robot: Robot,
    task: PlanTask,
    current: MethodResult,
    objective: str,
    no_reversal: bool,
    n: int,
    adaptive: bool,
) -> tuple[int, tuple[float, ...] | None, tuple[int, ...] | None] | None:
    """The refinement's next mesh after ``current`` of ``n`` intervals: (N', weights, counts),
    the weights and counts None for a uniform doubling; None past
    :data:`MAX_CONVERGENCE_INTERVALS`."""
    if adaptive:
        n, weights, counts, _ = refined_mesh(robot, current, objective, no_reversal, task)
        return None if n > MAX_CONVERGENCE_INTERVALS else (n, weights, counts)
    return (2 * n, None, None) if 2 * n <= MAX_CONVERGENCE_INTERVALS else None


@dataclass(frozen=True)
class BoundRules:
    """What a bound obeys (stated in its result).

    Attributes:
        limits: the limits it keeps (joint position, velocity, torque).
        rest_to_rest: zero velocity and acceleration at both ends.
        monotone_joints: joints that never move against their stroke (none when reversal is
            allowed).
        held_joints: joints whose start equals their goal and that stay put (none when reversal
            is allowed: they may move and come back).
    """

    limits: tuple[str, ...]
    rest_to_rest: bool
    monotone_joints: tuple[str, ...]
    held_joints: tuple[str, ...]

    @property
    def reversal_allowed(self) -> bool:
        return not (self.monotone_joints or self.held_joints)

    def to_dict(self) -> dict[str, Any]:
        return {
            "limits": list(self.limits),
            "rest_to_rest": self.rest_to_rest,
            "monotone_joints": list(self.monotone_joints),
            "held_joints": list(self.held_joints),
            "reversal_allowed": self.reversal_allowed,
        }


def bound_rules(joint_names: Sequence[str], task: PlanTask, no_reversal: bool) -> BoundRules:
    """The rules of the task's ``bound`` (``no_reversal``) or of ``bound_unrestricted``."""
    moving = np.abs(task.goal - task.start) > 0
    names_ = list(joint_names)
    return BoundRules(
        limits=("joint position", "joint velocity", "joint torque"),
        rest_to_rest=True,
        monotone_joints=tuple(n for n, m in zip(names_, moving, strict=True) if m and no_reversal),
        held_joints=tuple(n for n, m in zip(names_, moving, strict=True) if not m and no_reversal),
    )


#: Slack of the rule check on a sampled trajectory: joint speed against the stroke [rad/s] and
#: motion of a held joint [rad].
_RULE_SLACK = 1e-6


def rule_breach(
    robot: Robot, task: PlanTask, ev: EvaluatedTrajectory, rules: BoundRules
) -> str | None:
    """Why a trajectory lies outside a bound's rules (its feasible set), or None."""
    if ev.violations:
        return "violates limits: " + ev.violations[0]
    said_no = actuator_violation(robot, ev)  # the bound keeps the actuators' limits too
    if said_no is not None:
        return "violates actuator limits: " + said_no
    tr, names_ = ev.trajectory, list(robot.joint_names)
    direction = np.sign(task.goal - task.start)
    for j, name in enumerate(names_):
        if name in rules.held_joints and np.max(np.abs(tr.q[:, j] - task.start[j])) > _RULE_SLACK:
            return f"moves the held joint {name}"
        if name in rules.monotone_joints and np.min(direction[j] * tr.qd[:, j]) < -_RULE_SLACK:
            return f"moves joint {name} against its stroke"
    return None


def _outside_rules(
    robot: Robot, task: PlanTask, candidates: Mapping[str, MethodResult], rules: BoundRules
) -> dict[str, str]:
    """The candidates outside the bound's ``rules``, each with why (:func:`rule_breach`)."""
    return {
        n: why
        for n, m in candidates.items()
        if (why := rule_breach(robot, task, m.evaluated, rules))
    }


@dataclasses.dataclass
class _BoundSearch:
    """The bound's solves (optimal control under the bound's rules, no human constraint) from
    the candidates' trajectories as warm starts: every attempt in ``solves``, the best
    solution so far in ``best`` (its objective value and result) and IPOPT's failures in
    ``errors``."""

    robot: Robot
    task: PlanTask
    name: str
    duration: float  # [s]
    objective: str
    candidates: Mapping[str, MethodResult]
    no_reversal: bool
    report_samples: int
    solves: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    best: list[tuple[float, MethodResult]] = dataclasses.field(default_factory=list)
    errors: list[SolverError] = dataclasses.field(default_factory=list)

    def attempt(self, warm: str | None, n: int) -> bool:
        """Solve from the candidate ``warm`` (None: the quintic) on ``n`` intervals, keeping
        the solution when it is the best so far; False when IPOPT failed.

        Raises:
            SolverError: the problem is infeasible.
        """
        name = self.name
        try:
            res = run_optimal(
                self.robot, self.task, name=name, duration=self.duration,
                objective=self.objective, spec=HumanSpec("none", self.robot.elbow_joint),
                warm=None if warm is None else self.candidates[warm], n_intervals=n,
                no_reversal=self.no_reversal, report_samples=self.report_samples,
            )  # fmt: skip
        except SolverError as exc:
            if exc.infeasible:
                raise
            logger.info("%s: the start from %s on %d intervals failed: %s", name,
                        warm or "quintic", n, exc)  # fmt: skip
            self.errors.append(exc)
            self.solves.append(
                {"warm_start": warm or "quintic", "n_intervals": n, "error": str(exc)}
            )
            return False
        value = objective_value(self.robot, res.evaluated, self.objective)
        self.solves.append(
            {
                "warm_start": warm or "quintic",
                "n_intervals": n,
                "objective": value,
                "iterations": (res.solver or {}).get("iterations"),
            }
        )
        if not self.best or value < self.best[0][0]:
            self.best[:] = [(value, res)]
        return True

    def refine(
        self, other: str, value: float, n_intervals: int, size: float, *, first: bool
    ) -> None:
        """While the candidate ``other`` (objective ``value``) still beats the best solution,
        solve again from it on N (``first``: it was no start yet), 2N, ... up to
        :data:`BOUND_MAX_REFINEMENT` N intervals; ``size`` is the task's scale of the objective
        (:func:`beats_bound`)."""
        n = n_intervals if first else 2 * n_intervals
        while (
            self.best
            and beats_bound(value, self.best[0][0], scale=size)
            and n <= (BOUND_MAX_REFINEMENT * n_intervals)
        ):
            if not self.attempt(other, n):
                break  # a finer mesh will not converge from there either
            n *= 2

    def outcome(
        self,
        stricter: str | None,
        eligible: Sequence[str],
        values: Mapping[str, float],
        size: float,
    ) -> tuple[float, MethodResult, str | None]:
        """The bound's value, its result and its incumbent: the ``stricter`` candidate when no
        solve improves on it (its trajectory, renamed), else None.

        Raises:
            SolverError: every start failed (the last failure).
        """
        best = self.best
        incumbent = None
        if (
            stricter is not None
            and stricter in eligible
            and (not best or beats_bound(values[stricter], best[0][0], scale=size))
        ):
            incumbent = stricter
            best[:] = [(values[stricter], self.candidates[stricter])]
        if not best:
            raise self.errors[-1]
        value, result = best[0]
        if incumbent is not None:
            traj = dataclasses.replace(result.evaluated.trajectory, name=self.name)
            result = MethodResult(
                self.name,
                dataclasses.replace(result.evaluated, trajectory=traj),
                {**(result.solver or {}), "warm_start": incumbent},
            )
        return value, result, incumbent


def _drop_world_contacts(
    robot: Robot,
    candidates: Mapping[str, MethodResult],
    eligible: list[str],
    outside: dict[str, str],
) -> None:
    """Move the candidates that go below the mounting plane or into an obstacle from
    ``eligible`` to ``outside`` (with why): a bound that keeps them clear does not apply to
    them (they may well be cheaper)."""
    for other in list(eligible):
        below = world_finding(robot, other, candidates[other].trajectory)
        if below is not None:
            into = "below the mount plane" if below.kind == "plane" else "into an obstacle"
            outside[other] = f"goes {into}: " + below.describe()
            eligible.remove(other)


def run_bound(
    robot: Robot,
    task: PlanTask,
    *,
    name: str,
    duration: float,
    objective: str,
    candidates: Mapping[str, MethodResult],
    n_intervals: int,
    no_reversal: bool,
    report_samples: int,
    stricter: str | None = None,
) -> MethodResult:
    """A bound no method under its rules beats on the objective, with its certificate.

    Solved from the :data:`BOUND_STARTS` best of ``candidates`` (the other methods'
    trajectories under the bound's rules) as warm starts; if one of them still beats the best
    solution by more than :data:`BOUND_TOLERANCE`, the bound is re-solved from that method's
    trajectory on finer meshes (N, 2N, ... up to :data:`BOUND_MAX_REFINEMENT` N). The result's
    ``solver`` holds ``multistart`` (how many starts), ``starts`` (every solve: warm start,
    intervals, objective), ``rules`` and ``certificate``: ``checked`` (the methods compared),
    ``outside_rules`` (the methods the bound does not apply to, and why), ``beaten_by`` (the
    methods still below it; empty unless something is wrong, which the plan flags as an error)
    and ``tolerance``.

    ``stricter`` names a candidate that is itself the optimum under stricter rules (the task's
    bound, for ``bound_unrestricted``): it is the only warm start, and its trajectory, a
    feasible point of this problem, is the bound's incumbent when no solve improves on it
    (``certificate.incumbent``; the optimum under fewer rules is at most the stricter one's).

    Raises:
        SolverError: every start failed, or the problem is infeasible.
    """
    rules = bound_rules(robot.joint_names, task, no_reversal)
    values = {n: objective_value(robot, m.evaluated, objective) for n, m in candidates.items()}
    outside = _outside_rules(robot, task, candidates, rules)
    eligible = sorted((n for n in candidates if n not in outside), key=values.__getitem__)
    size = max((abs(v) for v in values.values()), default=0.0)
    if stricter is not None and stricter in eligible:
        starts: list[str | None] = [stricter]
    else:
        starts = list(eligible[:BOUND_STARTS]) or [None]
    logger.info(
        "%s: warm starts %s; outside its rules: %s", name,
        ", ".join(w or "quintic" for w in starts), ", ".join(outside) or "none",
    )  # fmt: skip
    search = _BoundSearch(
        robot, task, name, duration, objective, candidates, no_reversal, report_samples
    )
    for warm in starts:
        search.attempt(warm, n_intervals)
    # With a stricter optimum among the candidates, every other candidate is above it (its own
    # certificate), and it is this bound's incumbent below: nothing to refine.
    refine = [] if stricter is not None and starts == [stricter] else eligible
    for other in refine:
        search.refine(other, values[other], n_intervals, size, first=other not in starts)
    value, result, incumbent = search.outcome(stricter, eligible, values, size)
    if ((result.solver or {}).get("clearance") or {}).get("resolved"):
        _drop_world_contacts(robot, candidates, eligible, outside)
    beaten = [o for o in eligible if beats_bound(values[o], value, scale=size)]
    if beaten:
        logger.warning("%s: still beaten by %s: not a bound", name, ", ".join(beaten))
    logger.info("%s: %s = %.6g after %d solve(s)%s", name, objective, value, len(search.solves),
                f", incumbent {incumbent}" if incumbent else "")  # fmt: skip
    solver = dict(result.solver or {})
    solver.update(
        multistart=len(starts),
        starts=search.solves,
        rules=rules.to_dict(),
        certificate={
            "checked": eligible,
            "outside_rules": outside,
            "beaten_by": beaten,
            "tolerance": BOUND_TOLERANCE,
            "incumbent": incumbent,
        },
    )
    return MethodResult(name, result.evaluated, solver)


def run_jerk_limited(
    robot: Robot, task: PlanTask, *, duration: float, report_samples: int
) -> MethodResult:
    """The ruckig time-synchronised jerk-limited profile of the same duration.

    Raises:
        JerkLimitedError: ruckig refuses the input, or its time-optimal move is slower than
            ``duration``: then the error names the joint that sets that time and its limits,
            and ``shortest_duration`` [s] holds it rounded up to 1 ms (ruckig plans at it).
    """
    try:
        traj = jerk_limited(robot, task.start, task.goal, duration, n_samples=report_samples)
    except JerkLimitedError as exc:
        if not str(exc).startswith("infeasible"):
            raise
        raise _jerk_infeasible(robot, task, exc) from None
    logger.info("jerk_limited: ruckig profile over %g s", duration)
    solver = {
        "kind": "ruckig",
        "max_velocity": [float(v) for v in robot.qd_max],
        "max_acceleration": [float(v) for v in np.asarray(robot.qdd_max)],
        "max_jerk": [float(v) for v in np.asarray(robot.jerk_max)],
    }
    return MethodResult("jerk_limited", evaluate_trajectory(robot, traj, task), solver)


def _jerk_infeasible(robot: Robot, task: PlanTask, exc: JerkLimitedError) -> JerkLimitedError:
    """``exc`` with the joint whose own time-optimal move is the slowest (ruckig's
    ``independent_min_durations``) and ``shortest_duration``: the time-optimal duration rounded
    up to 1 ms, verified by planning the move at it (ruckig synchronises every joint to it)."""
    from app.planning.jerk_limited import _calculate

    start, goal = np.asarray(task.start, float), np.asarray(task.goal, float)
    profile: Any = _calculate(robot, start, goal, None)
    alone = np.asarray(profile.independent_min_durations, float)
    j = int(np.argmax(alone))
    steps = math.ceil(float(profile.duration) * 1000.0 - 1e-9)
    for extra in range(3):  # round-off of the rounded duration: at most a step or two more
        shortest = (steps + extra) / 1000.0
        try:
            jerk_limited(robot, start, goal, shortest, n_samples=11)
        except JerkLimitedError:
            continue
        break
    qdd_max, jerk_max = np.asarray(robot.qdd_max, float), np.asarray(robot.jerk_max, float)
    out = JerkLimitedError(
        f"{exc}: expected a duration of at least {shortest:.3f} s (verified: ruckig plans the "
        f"move at it; joint {robot.joint_names[j]} sets it, alone it needs {alone[j]:.3f} s "
        f"with its {robot.qd_max[j]:.3g} rad/s, {qdd_max[j]:.3g} rad/s² and "
        f"{jerk_max[j]:.3g} rad/s³ limits)"
    )
    out.shortest_duration = shortest  # type: ignore[attr-defined]
    return out
