"""Trade-offs: Pareto fronts between two metrics (or a metric and the duration) by optimal control,
the shortest feasible duration, and the best duration inside a production cycle.

**Fronts by the epsilon-constraint method.** Between two objectives A and B (any two of
:data:`FRONT_METRICS`), the ends are the single-objective optima (min A; min B), each solved from
the quintic and converged; every point between them minimises A with B <= epsilon
(:class:`app.planning.optimal.ExtraConstraints`), for epsilon evenly spaced between the B values of
the two ends, each warm-started from its neighbour (walking from the A end). Every point is
converged like every optimal-control result (:data:`CONVERGENCE_TOLERANCE`: meshes N, 2N, ...
until A changes by less than 0.1 %), and carries its ``convergence`` evidence. Points dominated
by another (round-off aside) are dropped; the rest are sorted by A (so B falls).

**Duration as an axis.** The front between a metric M and the duration is {(T, min M at T)} for T
from the shortest feasible duration (:func:`shortest_duration`, solved at it) to ``max_duration``,
geometrically spaced, each solve warm-started from its neighbour's motion stretched in time.
A point whose M is not below every shorter point's is dominated and dropped.

**Knee.** With both axes normalised to [0, 1] between the ends, the knee is the interior point
farthest below the straight line joining the ends (the largest 1 - a - b): the best compromise,
where moving on costs the most of one objective for the least of the other.

**Throughput** (:func:`throughput`): a cycle of ``3600 / rate`` seconds holds one motion of
duration T and a hold of the goal pose for the rest (at least ``dwell`` seconds); the per-cycle
metric adds what the hold costs (``tau_sq``: the static torques squared times the hold;
``electrical_energy``:
the copper loss of the static torques; the work metrics and ``jerk``: nothing; the peaks: the
larger of the motion's and the hold's). The duration with the lowest per-cycle metric is reported
against the quintic that uses the whole time the cycle leaves (``3600 / rate - dwell``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from app.names import FRONT_AXES, FRONT_METRICS
from app.planning.actuators import actuator_limits, actuator_violation
from app.planning.evaluation import (
    EvaluatedTrajectory,
    PlanningError,
    PlanTask,
    evaluate_trajectory,
    validate_task,
)
from app.planning.human_constraints import human_likeness_distance, template_speed_on_stroke
from app.planning.human_template import HumanTemplate
from app.planning.methods import (
    CONVERGENCE_TOLERANCE,
    MAX_CONVERGENCE_INTERVALS,
    human_spec,
    mesh_error_estimate,
    objective_value,
)
from app.planning.optimal import (
    DEFAULT_INTERVALS,
    END_GRADING,
    ExtraConstraints,
    FloatArray,
    HumanSpec,
    OptimalResult,
    SolverError,
    report_resolved_grading,
    solve_optimal,
)
from app.planning.profiles import Trajectory, quintic, stretched, time_grid
from app.planning.robots import Robot
from app.planning.shortest_duration import PROBE_ITERATIONS, feasibility_probe, probe_warm_name
from app.progress import ProgressFn, report

__all__ = [
    "FRONT_AXES",
    "FRONT_METHODS",
    "FRONT_METRICS",
    "Front",
    "FrontPoint",
    "ShortestDuration",
    "Throughput",
    "check_front_options",
    "jerk_integral",
    "pareto_front",
    "shortest_duration",
    "throughput",
]

#: The optimal-control methods a front is made of.
FRONT_METHODS: tuple[str, ...] = ("human_optimal", "bound")
#: Default number of points of a front.
DEFAULT_POINTS = 9
#: Relative width of the shortest-duration search's final bracket [-].
DURATION_REL_TOL = 2e-3
#: ... and of the throughput scan's lower end [-].
THROUGHPUT_DURATION_REL_TOL = 1e-2
#: The duration axis runs to this multiple of the shortest feasible duration by default.
DEFAULT_MAX_DURATION_FACTOR = 3.0
#: A point is dominated when another is at least this much lower (relative) on one objective and
#: not higher on the other: smaller differences are the solver's round-off [-].
DOMINATION_TOLERANCE = 1e-6


# ----------------------------------------------------------------------------------------------
# Options and metrics
# ----------------------------------------------------------------------------------------------


def check_front_options(
    objectives: Sequence[str] | str,
    *,
    points: int,
    method: str,
    duration: float | None,
) -> tuple[str, str]:
    """The two objectives (A, B), checked with the other options.

    Raises:
        PlanningError: an unknown axis or method, the same axis twice, fewer than 2 points, or a
            fixed duration with duration as an axis; the message names the option.
    """
    items = (
        [o.strip() for o in objectives.split(",")]
        if isinstance(objectives, str)
        else [str(o) for o in objectives]
    )
    if len(items) != 2:
        raise PlanningError(
            f"--objectives {','.join(items)!r}: expected two comma-separated axes A,B from "
            f"{', '.join(FRONT_AXES)}"
        )
    unknown = [o for o in items if o not in FRONT_AXES]
    if unknown:
        raise PlanningError(
            f"--objectives: unknown metric {unknown[0]!r}: expected one of {', '.join(FRONT_AXES)}"
        )
    if items[0] == items[1]:
        raise PlanningError(
            f"--objectives: the same metric twice ({items[0]}): expected two different axes"
        )
    if points < 2:
        raise PlanningError(f"--points {points}: expected at least 2 points (the two ends)")
    if method not in FRONT_METHODS:
        raise PlanningError(f"--method {method!r}: expected one of {', '.join(FRONT_METHODS)}")
    if "duration" in items and duration is not None:
        raise PlanningError(
            "--duration is fixed but duration is an axis of --objectives: expected no --duration "
            "(use --max-duration for the axis' longest duration)"
        )
    return items[0], items[1]


def jerk_integral(traj: Trajectory) -> float:
    """∫ Σ_j q⃛_j² dt [rad²/s⁵]: exact from a piecewise cubic's knots (constant jerk on each
    interval), else the trapezoid of the sampled jerk."""
    if traj.knots is not None and len(traj.knots) == 4:
        t, _, _, qdd = traj.knots
        h = np.diff(t)
        if h.size and np.all(h > 0):
            jerk = np.diff(qdd, axis=0) / h[:, None]
            # A piecewise quintic's knots do not give constant jerk: only use the exact sum when
            # the sampled jerk agrees with the knots' (a constant-jerk trajectory).
            k = np.clip(np.searchsorted(t, traj.t, side="right") - 1, 0, h.size - 1)
            if np.allclose(jerk[k], traj.jerk, rtol=1e-6, atol=1e-9):
                return float(np.sum(h * np.sum(jerk**2, axis=1)))
    return float(np.trapezoid(np.sum(traj.jerk**2, axis=1), traj.t))


def _metric(robot: Robot, ev: EvaluatedTrajectory, name: str) -> float:
    if name == "duration":
        return ev.trajectory.duration
    if name == "jerk":
        return jerk_integral(ev.trajectory)
    return objective_value(robot, ev, name)


# ----------------------------------------------------------------------------------------------
# Converged solves
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Solved:
    evaluated: EvaluatedTrajectory
    result: OptimalResult
    convergence: dict[str, Any]


@dataclass(frozen=True)
class _Setup:
    """What every solve of one front shares."""

    robot: Robot
    task: PlanTask
    spec: HumanSpec
    n_intervals: int
    no_reversal: bool
    report_samples: int
    controller_limits: bool = False
    actuators: Any = None
    tolerance: float = CONVERGENCE_TOLERANCE
    #: Actuator limits kept lazily: a solution that breaks them is solved again with them.
    lazy_actuators: Any = None
    #: Graded ends, one L for every solve and mesh (the coarsest mesh's default, so the finer
    #: meshes nest in it); 0 on a front or scan with a jerk axis: a graded mesh concentrates the
    #: jerk of an optimum whose continuous jerk is unbounded at rest (``tau_sq``) in its finest
    #: pieces, so the jerk axis would measure the mesh, not the motion.
    end_grading: int = 0

    def extra(self, metric: str | None = None, bound: float = math.inf) -> ExtraConstraints:
        return ExtraConstraints(
            metric=metric,
            bound=bound,
            controller_limits=self.controller_limits,
            actuators=self.actuators,
        )


def _solve(
    setup: _Setup,
    duration: float,
    objective: str,
    warm: Trajectory | None,
    n_intervals: int,
    extra: ExtraConstraints,
    warm_name: str,
    max_iterations: int | None = None,
) -> OptimalResult:
    result = solve_optimal(
        setup.robot, setup.task.start, setup.task.goal, duration, objective=objective,
        human=setup.spec, warm_start=warm, warm_start_name=warm_name, n_intervals=n_intervals,
        no_reversal=setup.no_reversal, report_samples=setup.report_samples, explain=False,
        extra=extra, end_grading=setup.end_grading, max_iterations=max_iterations,
    )  # fmt: skip
    if setup.lazy_actuators is None or extra.actuators is not None:
        return result
    # The actuators' rows make a solve 2-3x slower and rarely bind: check, and only where the
    # solution breaks them solve again with them as constraints, from it (as plan() does).
    fine = result.knots.sample(time_grid(duration, _CHECK_SAMPLES))
    if actuator_violation(setup.robot, evaluate_trajectory(setup.robot, fine, setup.task)) is None:
        return result
    kept = dataclasses.replace(extra, actuators=setup.lazy_actuators)
    return _solve(
        setup, duration, objective, result.trajectory, n_intervals, kept, "itself", max_iterations
    )


def _warm_solve(
    setup: _Setup,
    duration: float,
    objective: str,
    warm: Trajectory | None,
    n_intervals: int,
    extra: ExtraConstraints,
    warm_name: str,
) -> OptimalResult:
    """A solve from a near-optimal start (a neighbour, a coarser mesh) with IPOPT's small
    initial barrier parameter, and again with the default one should that fail."""
    if warm is None or warm_name == "quintic":
        return _solve(setup, duration, objective, warm, n_intervals, extra, warm_name)
    try:
        quick = dataclasses.replace(extra, warm=True)
        return _solve(setup, duration, objective, warm, n_intervals, quick, warm_name)
    except SolverError as exc:
        if exc.infeasible:
            raise
        return _solve(setup, duration, objective, warm, n_intervals, extra, warm_name)


#: Samples of the actuator check of a solution whose report grid is coarser.
_CHECK_SAMPLES = 501


def _converged(
    setup: _Setup,
    duration: float,
    objective: str,
    warm: Trajectory | None,
    extra: ExtraConstraints,
    warm_name: str = "quintic",
    n_start: int | None = None,
) -> _Solved:
    """Solve on N intervals (``n_start``, default the setup's), then 2N, 4N, ... (each from the
    last) until the objective on the report grid changes by less than the setup's tolerance,
    or the Richardson estimate of the error left is (:func:`methods.mesh_error_estimate`).

    A point warm-started from a converged neighbour starts at half the neighbour's final mesh:
    the coarse meshes would only re-find what the neighbour already resolved."""
    n = setup.n_intervals if n_start is None else max(setup.n_intervals, n_start)
    result = _warm_solve(setup, duration, objective, warm, n, extra, warm_name)
    ev = evaluate_trajectory(setup.robot, result.trajectory, setup.task)
    value = _metric(setup.robot, ev, objective)
    sequence: list[dict[str, Any]] = [{"n_intervals": n, "objective": value}]
    values = [value]
    change, converged, estimate, extrapolated = math.nan, False, math.nan, False
    while 2 * n <= MAX_CONVERGENCE_INTERVALS:
        n *= 2
        try:
            finer = _warm_solve(
                setup, duration, objective, result.trajectory, n, extra, "coarser mesh"
            )
        except SolverError as exc:
            sequence.append({"n_intervals": n, "error": str(exc)})
            break
        ev_f = evaluate_trajectory(setup.robot, finer.trajectory, setup.task)
        new = _metric(setup.robot, ev_f, objective)
        sequence.append({"n_intervals": n, "objective": new})
        values.append(new)
        change = abs(new - value) / max(abs(value), abs(new), 1e-12)
        estimate, extrapolated = mesh_error_estimate(values)
        result, ev, value = finer, ev_f, new
        if change < setup.tolerance or estimate < setup.tolerance:
            converged = True
            break
    convergence = {
        "sequence": sequence,
        "relative_change": change,
        "error_estimate": estimate,
        "extrapolated": extrapolated,
        "converged": converged,
        "final_intervals": result.solver.n_intervals,
        "tolerance": setup.tolerance,
        "end_grading": result.solver.end_grading,
    }
    return _Solved(ev, result, convergence)


# ----------------------------------------------------------------------------------------------
# Shortest duration
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ShortestDuration:
    """The shortest duration [s] in which the task is feasible, verified by a solve at it.

    Attributes:
        duration: the shortest duration found feasible (solved at it) [s].
        infeasible_below: the longest duration found infeasible [s].
        solves: solves spent.
        rules: what it obeys (limits, human constraint).
    """

    duration: float
    infeasible_below: float
    solves: int
    rules: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        return {
            "duration": self.duration,
            "infeasible_below": self.infeasible_below,
            "relative_tolerance": DURATION_REL_TOL,
            "solves": self.solves,
            "rules": list(self.rules),
        }


def _rules(setup: _Setup) -> tuple[str, ...]:
    rules = ["joint position", "joint velocity", "joint torque", "rest to rest"]
    if setup.controller_limits:
        rules += ["joint acceleration", "joint jerk"]
    if setup.actuators is not None or setup.lazy_actuators is not None:
        rules += ["actuator torque-speed envelope", "actuator RMS torque"]
    if setup.no_reversal:
        rules.append("no joint reversal")
    if setup.spec.kind != "none":
        rules.append(f"human-like ({setup.spec.rules()})")
    return tuple(rules)


def _shortest(setup: _Setup, rel_tol: float = DURATION_REL_TOL) -> tuple[ShortestDuration, Any]:
    """Bisection on the duration with ``tau_sq`` solves (feasibility is monotone in the
    duration: see :mod:`app.planning.shortest_duration`)."""
    robot, task = setup.robot, setup.task
    stroke = np.abs(task.goal - task.start)
    # No rest-to-rest motion reaches its mean speed's limit: a strict lower bound.
    lo = float(np.max(stroke / np.asarray(robot.qd_max)))
    solves = 0

    def solve(duration: float, warm: Trajectory | None) -> OptimalResult:
        nonlocal solves
        solves += 1
        return _solve(
            setup, duration, "tau_sq", warm, setup.n_intervals, setup.extra(),
            probe_warm_name(warm), PROBE_ITERATIONS,
        )  # fmt: skip

    feasible, solved = feasibility_probe(solve)

    hi = 2.0 * lo if lo > 0 else 0.1
    while not feasible(hi):
        lo, hi = hi, 2.0 * hi
        if hi > 64.0 * max(float(np.max(stroke)), 0.1):
            raise PlanningError(
                f"no duration up to {hi:.3g} s is feasible for {robot.name} with "
                f"{robot.payload.mass:g} kg: expected a lighter payload or wider limits"
            )
    while hi > lo * (1.0 + rel_tol):
        mid = math.sqrt(lo * hi)
        if feasible(mid):
            hi = mid
        else:
            lo = mid
    return ShortestDuration(hi, lo, solves, _rules(setup)), solved[hi]


def _setup(
    robot: Robot,
    task: PlanTask | None,
    method: str,
    template: HumanTemplate | None,
    n_intervals: int,
    no_reversal: bool,
    report_samples: int,
    controller_limits: bool,
    actuators: Any,
    tolerance: float = CONVERGENCE_TOLERANCE,
    jerk_axis: bool = False,
) -> _Setup:
    task = task or PlanTask.default(robot)
    if method not in FRONT_METHODS:
        raise PlanningError(f"--method {method!r}: expected one of {', '.join(FRONT_METHODS)}")
    if method == "human_optimal":
        tmpl = template or HumanTemplate()
        e = robot.elbow_joint
        q_via = tmpl.peak_joint_angle(float(task.start[e]), float(task.goal[e]))
        spec, _ = human_spec("peak", robot, task, tmpl, q_via)
    else:
        spec = HumanSpec("none", robot.elbow_joint)
    if not 0 < tolerance < 1:
        raise PlanningError(f"--tolerance {tolerance}: expected a fraction in (0, 1)")
    lazy = actuator_limits(robot) if isinstance(actuators, str) and actuators == "auto" else None
    fixed = None if isinstance(actuators, str) else actuators
    return _Setup(
        robot, task, spec, n_intervals, no_reversal, report_samples, controller_limits, fixed,
        tolerance, lazy,
        0 if jerk_axis else report_resolved_grading(END_GRADING, n_intervals, report_samples),
    )  # fmt: skip


def shortest_duration(
    robot: Robot,
    task: PlanTask | None = None,
    *,
    method: str = "bound",
    template: HumanTemplate | None = None,
    n_intervals: int = DEFAULT_INTERVALS,
    no_reversal: bool = True,
    controller_limits: bool = False,
    actuators: Any = "auto",
    rel_tol: float = DURATION_REL_TOL,
) -> ShortestDuration:
    """The shortest duration [s] of the task under the limits (and, for ``human_optimal``, the
    human-like constraint), to ``rel_tol``, reported from above (a solved duration).

    ``controller_limits`` adds the robot's acceleration and jerk limits (those of the
    jerk-limited baseline); ``actuators``: ``"auto"`` (the robot's actuator limits, kept where a
    solution would break them), None (ignored), or ``ActuatorLimits`` (always constraints).
    """
    setup = _setup(
        robot, task, method, template, n_intervals, no_reversal, 11, controller_limits, actuators
    )
    found, _ = _shortest(setup, rel_tol)
    return found


# ----------------------------------------------------------------------------------------------
# Fronts
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class FrontPoint:
    """One point of a front.

    Attributes:
        id: the point's id within its front (``p0``, ``p1``, ... in front order).
        values: every metric (:data:`FRONT_METRICS`) and the duration [their units].
        peak_torques: joint -> max |τ| [Nm].
        human_likeness: the elbow-speed profile's distance to the template's (0 = the same).
        epsilon: the bound on B this point was solved under (None at the ends).
        role: ``"A end"``, ``"B end"`` or ``""``.
        convergence: the mesh sequence and error estimate of its solve.
        evaluated: the trajectory with its torques (not in ``to_dict``).
    """

    id: str
    values: dict[str, float]
    peak_torques: dict[str, float]
    human_likeness: float
    epsilon: float | None
    role: str
    convergence: dict[str, Any]
    evaluated: EvaluatedTrajectory
    violations: tuple[str, ...] = ()

    def to_dict(self, a: str, b: str, knee: bool) -> dict[str, Any]:
        out: dict[str, Any] = {"id": self.id, a: self.values[a], b: self.values[b]}
        out.update({k: v for k, v in self.values.items() if k not in (a, b)})
        out.update(
            peak_torques=self.peak_torques,
            human_likeness=self.human_likeness,
            epsilon=self.epsilon,
            end=self.role or None,
            knee=knee,
            convergence=self.convergence,
            violations=list(self.violations),
        )
        return out


@dataclass(frozen=True)
class Front:
    """A Pareto front between objectives ``a`` and ``b`` (``to_dict()``: ``bioplan front --json``).

    Attributes:
        a, b: the objectives (A is minimised with B <= epsilon).
        method: ``human_optimal`` or ``bound``.
        points: non-dominated points sorted by A (B falling).
        knee: index of the knee in ``points`` (None with fewer than 3 points).
        shortest_duration: with duration as an axis, the shortest feasible duration.
        dropped: points solved but dominated or failed, with why.
    """

    robot: str
    payload_mass: float
    a: str
    b: str
    method: str
    duration: float | None
    points: tuple[FrontPoint, ...]
    knee: int | None
    rules: tuple[str, ...]
    shortest_duration: ShortestDuration | None = None
    dropped: tuple[dict[str, Any], ...] = ()
    solves: int = 0
    seconds: float = 0.0
    notes: tuple[str, ...] = field(default=())

    def to_dict(self) -> dict[str, Any]:
        from app.jsonsafe import json_safe

        out: dict[str, Any] = {
            "robot": self.robot,
            "payload_mass": self.payload_mass,
            "objectives": [self.a, self.b],
            "method": self.method,
            "duration": self.duration,
            "rules": list(self.rules),
            "sorted_by": self.a,
            "knee": None if self.knee is None else self.points[self.knee].id,
            "points": [
                p.to_dict(self.a, self.b, i == self.knee) for i, p in enumerate(self.points)
            ],
            "ends": {
                self.a: self.points[0].values[self.a],
                self.b: self.points[-1].values[self.b],
            },
            "shortest_duration": (
                None if self.shortest_duration is None else self.shortest_duration.to_dict()
            ),
            "dropped": list(self.dropped),
            "solves": self.solves,
            "seconds": self.seconds,
            "notes": list(self.notes),
        }
        return dict(json_safe(out))


def _point(
    setup: _Setup,
    solved: _Solved,
    reference: FloatArray,
    epsilon: float | None,
    role: str,
) -> FrontPoint:
    robot, ev = setup.robot, solved.evaluated
    values = {m: _metric(robot, ev, m) for m in FRONT_AXES}
    e = robot.elbow_joint
    q0, q1 = float(setup.task.start[e]), float(setup.task.goal[e])
    tr = ev.trajectory
    likeness = human_likeness_distance(tr.q[:, e], tr.qd[:, e], q0, q1, reference)
    peaks = {
        n: float(v) for n, v in zip(robot.joint_names, np.abs(ev.tau).max(axis=0), strict=True)
    }
    return FrontPoint(
        id="",
        values=values,
        peak_torques=peaks,
        human_likeness=likeness,
        epsilon=epsilon,
        role=role,
        convergence=solved.convergence,
        evaluated=ev,
        violations=ev.violations,
    )


def _dominates(p: dict[str, float], q: dict[str, float], a: str, b: str) -> bool:
    def below(x: float, y: float) -> bool:
        return x < y - DOMINATION_TOLERANCE * max(abs(x), abs(y), 1e-12)

    def not_above(x: float, y: float) -> bool:
        return not below(y, x)

    return (not_above(p[a], q[a]) and not_above(p[b], q[b])) and (
        below(p[a], q[a]) or below(p[b], q[b])
    )


def _knee(points: Sequence[FrontPoint], a: str, b: str) -> int | None:
    if len(points) < 3:
        return None
    va = np.array([p.values[a] for p in points])
    vb = np.array([p.values[b] for p in points])
    span_a, span_b = va[-1] - va[0], vb[0] - vb[-1]
    if span_a <= 0 or span_b <= 0:
        return None
    na, nb = (va - va[0]) / span_a, (vb - vb[-1]) / span_b
    below = 1.0 - na - nb
    inner = int(np.argmax(below[1:-1])) + 1
    return inner


def pareto_front(
    robot: Robot,
    task: PlanTask | None = None,
    *,
    objectives: Sequence[str] | str,
    duration: float | None = None,
    method: str = "bound",
    points: int = DEFAULT_POINTS,
    template: HumanTemplate | None = None,
    n_intervals: int = DEFAULT_INTERVALS,
    no_reversal: bool = True,
    max_duration: float | None = None,
    controller_limits: bool = False,
    actuators: Any = "auto",
    report_samples: int = 1000,
    tolerance: float = CONVERGENCE_TOLERANCE,
    progress: ProgressFn | None = None,
) -> Front:
    """The Pareto front between two objectives (module docstring).

    Args:
        robot: the robot with its payload.
        task: start and goal; the robot's curl by default.
        objectives: "A,B" or (A, B), two of :data:`FRONT_AXES`.
        duration: motion time [s] (None: 1 s); must be None when ``duration`` is an axis.
        method: ``bound`` (the limits only) or ``human_optimal`` (and the human-like peak).
        points: points of the front (>= 2; the two ends included).
        template: the human template (``human_optimal``); the paper's by default.
        n_intervals: the coarsest mesh; every point is refined from it to convergence.
        no_reversal: no joint moves against its stroke.
        max_duration: the duration axis' longest duration [s]; default
            :data:`DEFAULT_MAX_DURATION_FACTOR` times the shortest.
        controller_limits: also keep the acceleration and jerk limits.
        actuators: ``"auto"``: the robot's actuator limits (``app.planning.actuators``), kept
            as constraints wherever a solution would break them; None: ignored;
            ``ActuatorLimits``: always constraints.
        report_samples: samples of every point's trajectory.
        tolerance: mesh refinement stops when the objective changes by less than this fraction.
        progress: called per point (stage ``front``).

    Raises:
        PlanningError: bad options (named), a task that cannot be planned.
        SolverError: an end could not be solved.
    """
    import time

    started = time.perf_counter()
    a, b = check_front_options(objectives, points=points, method=method, duration=duration)
    setup = _setup(
        robot, task, method, template, n_intervals, no_reversal, report_samples,
        controller_limits, actuators, tolerance, jerk_axis="jerk" in (a, b),
    )  # fmt: skip
    e = robot.elbow_joint
    q0, q1 = float(setup.task.start[e]), float(setup.task.goal[e])
    peak = template.peak_joint_angle(q0, q1) if template is not None else None
    reference, _ = template_speed_on_stroke(template or HumanTemplate(), q0, q1, peak_angle=peak)
    if "duration" in (a, b):
        front = _duration_front(setup, a, b, points, max_duration, reference, progress)
    else:
        duration = 1.0 if duration is None else float(duration)
        validate_task(robot, setup.task, duration)
        front = _metric_front(setup, a, b, duration, points, reference, progress)
    report(progress, "done", 1, 1, message="front done")
    return dataclasses.replace(front, seconds=time.perf_counter() - started)


def _finish(
    setup: _Setup,
    a: str,
    b: str,
    method: str,
    duration: float | None,
    raw: list[FrontPoint],
    dropped: list[dict[str, Any]],
    solves: int,
    shortest: ShortestDuration | None,
    notes: list[str],
) -> Front:
    kept: list[FrontPoint] = []
    for i, p in enumerate(raw):
        by = next(
            (q for j, q in enumerate(raw) if j != i and _dominates(q.values, p.values, a, b)), None
        )
        if by is not None:
            dropped.append(
                {
                    "epsilon": p.epsilon,
                    a: p.values[a],
                    b: p.values[b],
                    "why": f"dominated (a point with {a} {by.values[a]:.6g}, {b} "
                    f"{by.values[b]:.6g})",
                }
            )
        else:
            kept.append(p)
    kept.sort(key=lambda p: (p.values[a], -p.values[b]))
    if "duration" not in (a, b):
        kept = _ends_marked(kept, a, b, notes)
    kept = [dataclasses.replace(p, id=f"p{i}") for i, p in enumerate(kept)]
    if len(kept) == 1:
        notes.append(f"no trade-off: the {a} optimum is also the {b} optimum")
    robot = setup.robot
    return Front(
        robot=robot.name,
        payload_mass=float(robot.payload.mass),
        a=a,
        b=b,
        method=method,
        duration=duration,
        points=tuple(kept),
        knee=_knee(kept, a, b),
        rules=_rules(setup),
        shortest_duration=shortest,
        dropped=tuple(dropped),
        solves=solves,
        notes=tuple(notes),
    )


def _ends_marked(kept: list[FrontPoint], a: str, b: str, notes: list[str]) -> list[FrontPoint]:
    """A metric front's first and last points are its A and B ends. An end's own
    single-objective solve can be beaten by a neighbour on a coarse tolerance (then it is
    dominated and dropped): the neighbour is the best known optimum, marked as the end, said."""
    roles = {p.role for p in kept}
    out = list(kept)
    for index, role, metric in ((0, "A end", a), (-1, "B end", b)):
        p = out[index] if out else None
        if p is None or role in roles or p.role or p.epsilon is None:
            continue
        notes.append(
            f"the {metric} optimum's own solve was dominated by the point solved under {b} <= "
            f"{p.epsilon:.6g}, now the {role} ({metric} {p.values[metric]:.6g}); a tighter "
            "tolerance converges the end's solve further"
        )
        out[index] = dataclasses.replace(p, role=role)
    return out


def _method(setup: _Setup) -> str:
    return "human_optimal" if setup.spec.kind != "none" else "bound"


def _solves(solved: _Solved) -> int:
    return len(solved.convergence["sequence"])


def _metric_front(
    setup: _Setup,
    a: str,
    b: str,
    duration: float,
    points: int,
    reference: FloatArray,
    progress: ProgressFn | None,
) -> Front:
    end_a = _converged(setup, duration, a, None, setup.extra())
    report(progress, "front", 1, points, message=f"front: {a} end")
    end_b = _converged(setup, duration, b, None, setup.extra())
    report(progress, "front", 2, points, message=f"front: {b} end")
    solves = _solves(end_a) + _solves(end_b)
    raw = [_point(setup, end_a, reference, None, "A end")]
    dropped: list[dict[str, Any]] = []
    b_hi = _metric(setup.robot, end_a.evaluated, b)
    b_lo = _metric(setup.robot, end_b.evaluated, b)
    notes: list[str] = []
    if b_hi > b_lo * (1.0 + 1e-9) + 1e-12:
        warm = end_a.evaluated.trajectory
        n_warm = end_a.result.solver.n_intervals
        for i in range(1, points - 1):
            eps = b_hi - (b_hi - b_lo) * i / (points - 1)
            try:
                solved = _converged(
                    setup, duration, a, warm, setup.extra(b, eps), "neighbour", n_warm // 2
                )
            except SolverError as exc:
                dropped.append({"epsilon": eps, "why": str(exc)})
                continue
            solves += _solves(solved)
            raw.append(_point(setup, solved, reference, eps, ""))
            warm, n_warm = solved.evaluated.trajectory, solved.result.solver.n_intervals
            report(progress, "front", i + 2, points, message=f"front: {b} <= {eps:.6g}")
    raw.append(_point(setup, end_b, reference, None, "B end"))
    return _finish(setup, a, b, _method(setup), duration, raw, dropped, solves, None, notes)


def _duration_front(
    setup: _Setup,
    a: str,
    b: str,
    points: int,
    max_duration: float | None,
    reference: FloatArray,
    progress: ProgressFn | None,
) -> Front:
    metric = b if a == "duration" else a
    shortest, _ = _shortest(setup)
    report(progress, "front", 1, points, message=f"front: shortest {shortest.duration:.4g} s")
    t_max = (
        float(max_duration)
        if max_duration is not None
        else DEFAULT_MAX_DURATION_FACTOR * shortest.duration
    )
    if not t_max > shortest.duration:
        raise PlanningError(
            f"--max-duration {t_max:g} s: expected more than the shortest feasible duration "
            f"{shortest.duration:.4g} s"
        )
    durations = np.geomspace(shortest.duration, t_max, points)
    raw: list[FrontPoint] = []
    dropped: list[dict[str, Any]] = []
    solves = shortest.solves
    warm: Trajectory | None = None
    n_warm = 0
    for i, t in enumerate(durations):
        guess = None if warm is None else stretched(warm, float(t))
        try:
            solved = _converged(
                setup, float(t), metric, guess, setup.extra(), "neighbour", n_warm // 2
            )
        except SolverError as exc:
            if i == 0:
                raise
            dropped.append({"duration": float(t), "why": str(exc)})
            continue
        solves += _solves(solved)
        role = "duration end" if i == 0 else ""
        raw.append(_point(setup, solved, reference, float(t), role))
        warm, n_warm = solved.evaluated.trajectory, solved.result.solver.n_intervals
        report(progress, "front", i + 2, points + 1, message=f"front: {t:.4g} s")
    notes = [
        f"duration axis from the shortest feasible duration to {t_max:.4g} s; the {metric} end "
        "is the lowest over that range"
    ]
    front = _finish(setup, a, b, _method(setup), None, raw, dropped, solves, shortest, notes)
    return front


# ----------------------------------------------------------------------------------------------
# Throughput
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Throughput:
    """The best duration inside a production cycle (module docstring).

    Attributes:
        objective: the metric per cycle.
        cycle: the cycle time 3600 / rate [s]; dwell: the least hold per cycle [s].
        duration: the motion's duration with the lowest per-cycle metric [s].
        per_cycle: that lowest per-cycle value [metric unit]; motion, hold: its two parts.
        quintic_duration: the quintic's duration, the whole time the cycle leaves [s].
        quintic_per_cycle: the quintic's per-cycle value; saving_pct: 100 (quintic − best) /
            quintic [%].
        scanned: every (duration, per-cycle value) solved.
    """

    objective: str
    method: str
    cycle_rate: float
    cycle: float
    dwell: float
    duration: float
    per_cycle: float
    motion: float
    hold: float
    quintic_duration: float
    quintic_per_cycle: float
    saving_pct: float
    shortest_duration: float
    scanned: tuple[tuple[float, float], ...]
    convergence: dict[str, Any]
    hold_model: str

    def to_dict(self) -> dict[str, Any]:
        from app.jsonsafe import json_safe

        out = dataclasses.asdict(self)
        out["scanned"] = [{"duration": t, "per_cycle": v} for t, v in self.scanned]
        return dict(json_safe(out))


#: What holding the goal pose costs per second, per metric (the docstring's hold model).
_HOLD_MODEL = (
    "the arm holds the goal pose for the rest of the cycle: tau_sq adds the static torques "
    "squared, electrical_energy their copper loss; the work metrics and jerk add nothing; "
    "peak_torque takes the larger of the motion's and the hold's"
)


def _hold_cost(robot: Robot, task: PlanTask, objective: str, seconds: float) -> float:
    goal = np.asarray(task.goal, float)[None, :]
    rest = np.zeros_like(goal)
    tau = np.abs(robot.dynamics().inverse_dynamics(goal, rest, rest)[0])
    if objective == "tau_sq":
        return float(np.sum(tau**2) * seconds)
    if objective == "electrical_energy":
        if not robot.motors_modelled:
            return 0.0
        loss = sum(
            m.winding_resistance * (t / (m.gear_ratio * m.torque_constant)) ** 2
            for m, t in zip(robot.motors, tau, strict=True)
        )
        return float(loss * seconds)
    if objective == "peak_torque":
        return float(np.max(tau / np.asarray(robot.tau_max)))
    return 0.0


def _per_cycle(robot: Robot, task: PlanTask, objective: str, motion: float, hold_s: float) -> float:
    hold = _hold_cost(robot, task, objective, hold_s)
    return max(motion, hold) if objective == "peak_torque" else motion + hold


def _check_throughput(objective: str, cycle_rate: float, dwell: float, points: int) -> None:
    """Refuse a bad :func:`throughput` option, named as the CLI's flag.

    Raises:
        PlanningError: an unknown objective, a rate [lifts/h] not > 0, a dwell [s] not >= 0 or
            fewer than 2 points.
    """
    if objective not in FRONT_METRICS:
        raise PlanningError(
            f"--objective {objective!r}: expected one of {', '.join(FRONT_METRICS)}"
        )
    if not (math.isfinite(cycle_rate) and cycle_rate > 0):
        raise PlanningError(f"--cycle-rate {cycle_rate}: expected lifts per hour > 0")
    if not (math.isfinite(dwell) and dwell >= 0):
        raise PlanningError(f"--dwell {dwell}: expected a hold time >= 0 s")
    if points < 2:
        raise PlanningError(f"--points {points}: expected at least 2 durations to scan")


def _motion_window(
    robot: Robot, setup: _Setup, cycle_rate: float, dwell: float, longest: float
) -> ShortestDuration:
    """The shortest feasible duration of the motion, checked against the ``longest`` [s] the
    cycle (``cycle_rate`` [lifts/h] less ``dwell`` [s]) leaves for it.

    Raises:
        PlanningError: the cycle leaves less than the stroke at the speed limits needs (refused
            without a solve), or less than the shortest feasible duration.
    """
    stroke = np.abs(setup.task.goal - setup.task.start)
    at_least = float(np.max(stroke / np.asarray(robot.qd_max)))
    if longest <= at_least:  # below the speed limits' bound: no solve needed to refuse it
        raise PlanningError(
            f"--cycle-rate {cycle_rate:g}/h with --dwell {dwell:g} s leaves {longest:.3g} s for "
            f"the motion: expected more than {at_least:.3f} s, the stroke at the speed limits "
            "(fewer lifts per hour or a shorter dwell)"
        )
    # The scan's lower end needs no finer bracket than its own spacing.
    shortest, _ = _shortest(setup, THROUGHPUT_DURATION_REL_TOL)
    if longest < shortest.duration:
        raise PlanningError(
            f"--cycle-rate {cycle_rate:g}/h with --dwell {dwell:g} s leaves {longest:.3g} s for "
            f"the motion: expected at least the shortest feasible duration "
            f"{shortest.duration:.3f} s (fewer lifts per hour or a shorter dwell)"
        )
    return shortest


def _scan_durations(
    at: Callable[[float, Trajectory | None, int], float],
    scanned: dict[float, tuple[float, float, _Solved]],
    shortest: float,
    longest: float,
    points: int,
) -> None:
    """Solve at ``points`` durations from ``shortest`` to ``longest`` [s] (geometric), each
    warm-started from the previous one stretched, then once at the vertex of the parabola in
    log T through the best three when it falls between them.

    ``at(duration, warm, n_warm)`` solves one duration and records it in ``scanned``
    (duration [s] -> per-cycle value, motion value, solution).
    """
    durations = (
        np.geomspace(shortest, longest, points) if longest > shortest else np.array([longest])
    )
    warm: Trajectory | None = None
    n_warm = 0
    for t in durations:
        at(float(t), None if warm is None else stretched(warm, float(t)), n_warm)
        last = scanned[float(t)][2]
        warm, n_warm = last.evaluated.trajectory, last.result.solver.n_intervals
    ts = sorted(scanned)
    k = min(range(len(ts)), key=lambda i: scanned[ts[i]][0])
    if 0 < k < len(ts) - 1:
        # One step of successive parabolic interpolation in log T through the best three.
        x = np.log([ts[k - 1], ts[k], ts[k + 1]])
        y = np.array([scanned[ts[i]][0] for i in (k - 1, k, k + 1)])
        denom = (x[1] - x[0]) * (y[1] - y[2]) - (x[1] - x[2]) * (y[1] - y[0])
        if denom != 0:
            num = (x[1] - x[0]) ** 2 * (y[1] - y[2]) - (x[1] - x[2]) ** 2 * (y[1] - y[0])
            vertex = float(np.exp(x[1] - 0.5 * num / denom))
            if ts[k - 1] < vertex < ts[k + 1] and abs(vertex / ts[k] - 1) > 1e-3:
                near = scanned[ts[k]][2]
                at(
                    vertex,
                    stretched(near.evaluated.trajectory, vertex),
                    near.result.solver.n_intervals,
                )


def throughput(
    robot: Robot,
    task: PlanTask | None = None,
    *,
    objective: str,
    cycle_rate: float,
    dwell: float,
    method: str = "bound",
    template: HumanTemplate | None = None,
    points: int = 5,
    n_intervals: int = DEFAULT_INTERVALS,
    no_reversal: bool = True,
    report_samples: int = 1000,
    tolerance: float = CONVERGENCE_TOLERANCE,
    actuators: Any = "auto",
) -> Throughput:
    """The motion duration inside a cycle that minimises ``objective`` per cycle.

    Args:
        cycle_rate: lifts per hour (> 0).
        dwell: the least time per cycle the arm must hold still at the goal [s] (>= 0).
        actuators: as :func:`pareto_front`'s (default: the robot's, kept where they bind).
        points: durations scanned between the shortest feasible and the longest the cycle
            allows (geometric), then one refinement at the parabola through the best three.

    Raises:
        PlanningError: a bad rate or dwell (named), or a cycle too short for the motion.
    """
    _check_throughput(objective, cycle_rate, dwell, points)
    setup = _setup(
        robot, task, method, template, n_intervals, no_reversal, report_samples, False, actuators,
        tolerance, jerk_axis=objective == "jerk",
    )  # fmt: skip
    cycle = 3600.0 / cycle_rate
    longest = cycle - dwell
    shortest = _motion_window(robot, setup, cycle_rate, dwell, longest)
    task_ = setup.task
    scanned: dict[float, tuple[float, float, _Solved]] = {}

    def at(duration: float, warm: Trajectory | None, n_warm: int = 0) -> float:
        solved = _converged(
            setup, duration, objective, warm, setup.extra(), "neighbour", n_warm // 2
        )
        motion = _metric(robot, solved.evaluated, objective)
        value = _per_cycle(robot, task_, objective, motion, cycle - duration)
        scanned[duration] = (value, motion, solved)
        return value

    _scan_durations(at, scanned, shortest.duration, longest, points)
    best_t = min(scanned, key=lambda t: scanned[t][0])
    value, motion, solved = scanned[best_t]
    q = quintic(task_.start, task_.goal, longest, n_samples=report_samples)
    q_ev = evaluate_trajectory(robot, q, task_)
    q_value = _per_cycle(robot, task_, objective, _metric(robot, q_ev, objective), cycle - longest)
    saving = 100.0 * (q_value - value) / q_value if q_value != 0 else math.nan
    return Throughput(
        objective=objective,
        method=method,
        cycle_rate=float(cycle_rate),
        cycle=cycle,
        dwell=float(dwell),
        duration=float(best_t),
        per_cycle=value,
        motion=motion,
        hold=value - motion if objective != "peak_torque" else math.nan,
        quintic_duration=longest,
        quintic_per_cycle=q_value,
        saving_pct=saving,
        shortest_duration=shortest.duration,
        scanned=tuple((t, scanned[t][0]) for t in sorted(scanned)),
        convergence=solved.convergence,
        hold_model=_HOLD_MODEL,
    )
