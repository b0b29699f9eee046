"""Plan a task with every method side by side: quintic, paper, human_optimal, bound, jerk_limited.

* ``quintic`` (standard): one quintic per joint (zero velocity and acceleration at both ends).
* ``paper``: the paper's method (:mod:`app.planning.paper`), two quintics joined at the
  template's angle, tuned by PSO.
* ``human_optimal``: optimal control (:mod:`app.planning.optimal`) with the template's
  constraint (``human_constraint``: the elbow's speed peak at the template's angle, or the A/B/C
  phase shares), warm-started from the paper's plan.
* ``bound``: the same optimal control under the task's rules only (limits, rest to rest,
  monotone and held joints), solved from the best other methods and improved until none beats it.
* ``bound_unrestricted`` (on request): limits only, reversal allowed; never above ``bound``.
* ``jerk_limited``: what a robot controller runs, a ruckig time-synchronised jerk-limited move.

Every method is evaluated on the same fine grid (``report_samples``) with Pinocchio, reported with
every metric and the task's floors, and ranked by its share of the achievable saving of the
objective, (quintic − method) / (quintic − bound). No result may be below a floor.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.jsonsafe import json_safe
from app.options import OptionsError
from app.planning.actuators import plan_actuators
from app.planning.energy import (
    FLOOR_NOTES,
    Floors,
    cumulative_energy,
    improvement_pct,
    power_curve,
)
from app.planning.evaluation import (
    EvaluatedTrajectory,
    PlanningError,
    PlanTask,
    check_floors,
    elbow_flexion_deg,
    evaluate_trajectory,
    phase_boundary_times,
    task_floors_of,
    validate_task,
)
from app.planning.human_constraints import (
    PhaseShares,
    human_likeness_distance,
    template_speed_on_stroke,
)
from app.planning.human_template import HumanTemplate, flexion_on_stroke, joint_on_stroke
from app.planning.methods import (
    ALL_METHODS,
    DEFAULT_METHODS,
    METHOD_ERRORS,
    BoundViolation,
    MethodFailure,
    MethodResult,
    beats_bound,
    bound_rules,
    check_methods,
    failure_of,
    human_spec,
    objective_value,
    refine_to_convergence,
    run_bound,
    run_jerk_limited,
    run_optimal,
    run_paper,
    share_of_achievable_pct,
)
from app.planning.optimal import HumanSpec
from app.planning.options import PlanOptions
from app.planning.paper import PlanProblem
from app.planning.profiles import quintic
from app.planning.pso import PSOResult
from app.planning.robots import Robot
from app.planning.safety import SafetyReport, check_safety, not_checked
from app.planning.shortest_duration import rest_overload, shortest_verified_duration
from app.progress import ProgressFn, report, within

__all__ = [
    "ALL_METHODS",
    "DEFAULT_METHODS",
    "EvaluatedTrajectory",
    "MethodFailure",
    "MethodResult",
    "PlanFailed",
    "PlanProblem",
    "PlanResult",
    "PlanTask",
    "PlanningError",
    "elbow_flexion_deg",
    "evaluate_trajectory",
    "phase_boundary_times",
    "plan",
    "validate_task",
]

FloatArray = NDArray[np.float64]

#: The safety report's reason when ``plan(..., safety=False)`` skipped the check.
SKIPPED = "not checked: skipped on request (safety=False)"


class PlanFailed(PlanningError):
    """No method but the quintic succeeded although others were asked for.

    Attributes:
        failures: every failed method's own error, by name.
    """

    def __init__(self, message: str, failures: dict[str, MethodFailure]) -> None:
        super().__init__(message)
        self.failures = failures


@dataclass(frozen=True)
class PlanResult:
    """Every requested method on the same task, with metrics, floors and shares.

    ``standard`` is the quintic and ``optimized`` the paper's method (None when it was not
    requested or failed); ``methods`` holds every method that succeeded by name
    (``result.methods["bound"].trajectory``) and ``method_errors`` every one that failed, with
    its own error (a plan needs the quintic and at least one other method, docs/planning.md).
    ``to_dict()`` is the JSON of ``bioplan plan --json`` (DESIGN.md's CLI contract).
    """

    robot: str
    objective: str
    duration: float
    payload_mass: float
    task: PlanTask
    template: HumanTemplate
    target_peak_angle_deg: float
    standard: EvaluatedTrajectory
    optimized: EvaluatedTrajectory | None
    floors: Floors
    optimizer: PSOResult | None
    via_time: float | None
    elbow_joint: int
    phase_bounds_deg: tuple[float, float]
    warnings: tuple[str, ...] = field(default=())
    methods: dict[str, MethodResult] = field(default_factory=dict)
    objective_values: dict[str, float] = field(default_factory=dict)
    human_constraint: str = "peak"
    no_reversal: bool = True
    phase_shares: PhaseShares | None = None
    joint_names: tuple[str, ...] = field(default=())
    human_rule: str = ""
    #: Collision and workspace check of every method (``app.planning.safety``).
    safety: SafetyReport = field(default_factory=lambda: not_checked(SKIPPED))
    method_errors: dict[str, MethodFailure] = field(default_factory=dict)
    #: Each method's margins to the actuator limits (``app.planning.actuators``; {} without).
    actuators: dict[str, Any] = field(default_factory=dict)

    @property
    def improvement_pct(self) -> dict[str, Any]:
        """100 (standard - paper) / standard per metric ({} without the paper's method)."""
        if self.optimized is None:
            return {}
        return improvement_pct(self.standard.metrics, self.optimized.metrics)

    @property
    def share_of_achievable_pct(self) -> dict[str, float]:
        """Per method, 100 (quintic − method) / (quintic − bound) on the objective [%], never
        above 100: NaN for ``bound_unrestricted`` (outside the task's rules, it may go below the
        task's bound) and for a method that beats the bound by more than round-off (an error,
        named in ``warnings``)."""
        values = self.objective_values
        if "bound" not in values:
            return {}
        q, b = values["quintic"], values["bound"]
        out: dict[str, float] = {}
        for name, v in values.items():
            try:
                out[name] = (
                    math.nan if name == "bound_unrestricted" else share_of_achievable_pct(q, v, b)
                )
            except BoundViolation:
                out[name] = math.nan
        return out

    @property
    def human_likeness(self) -> dict[str, float]:
        """Per method, the human-likeness distance of its elbow speed profile to the template's
        (:func:`app.planning.human_constraints.human_likeness_distance`; 0 = the same shape)."""
        e = self.elbow_joint
        q0, q1 = float(self.task.start[e]), float(self.task.goal[e])
        reference, _ = self._likeness_template()
        return {
            name: human_likeness_distance(
                m.trajectory.q[:, e], m.trajectory.qd[:, e], q0, q1, reference
            )
            for name, m in self.methods.items()
        }

    def lift(self) -> dict[str, Any]:
        """Whether the task lifts or lowers: ``delta_pe_j``, the potential-energy change of the
        robot and its payload from start to goal [J] (the net work every method does), and
        ``lifts`` (ΔPE > 0; a lowering gives energy back, which the floors account for)."""
        delta = float(self.floors.delta_potential)
        return {"delta_pe_j": delta, "lifts": delta > 0.0}

    def method(self, name: str) -> MethodResult:
        """One method's result by name."""
        try:
            return self.methods[name]
        except KeyError:
            raise PlanningError(
                f"method {name!r} was not planned: expected one of {', '.join(self.methods)}"
            ) from None

    def _methods_dict(self) -> dict[str, Any]:
        shares = self.share_of_achievable_pct
        likeness = self.human_likeness
        out: dict[str, Any] = {}
        for name, m in self.methods.items():
            d = m.to_dict()
            d["objective_value"] = self.objective_values.get(name)
            d["improvement_pct"] = improvement_pct(self.standard.metrics, m.evaluated.metrics)
            d["share_of_achievable_pct"] = shares.get(name)
            d["human_likeness"] = likeness[name]
            d["rules"] = self._rules(name, m)
            out[name] = d
        return out

    def _rules(self, name: str, m: MethodResult) -> dict[str, Any] | None:
        """What an optimal-control method obeys (None for the others)."""
        if m.solver and "rules" in m.solver:
            return dict(m.solver["rules"])
        if name != "human_optimal":
            return None
        return {
            **bound_rules(self.joint_names, self.task, self.no_reversal).to_dict(),
            "human": self.human_rule,
        }

    def _optimizer_dict(self) -> dict[str, Any] | None:
        if self.optimizer is None:
            return None
        return {
            "iterations": self.optimizer.iterations,
            "evaluations": self.optimizer.evaluations,
            "seconds": self.optimizer.seconds,
            "seed": self.optimizer.seed,
            "best_cost": self.optimizer.best_cost,
            "stopped_early": self.optimizer.stopped_early,
            "history": [float(c) for c in self.optimizer.history],
        }

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "joint_names": list(self.joint_names),
            "duration": self.duration,
            "task": {
                "start_deg": np.degrees(self.task.start).tolist(),
                "goal_deg": np.degrees(self.task.goal).tolist(),
                **self.lift(),
            },
            "standard": self.standard.to_dict(),
            "floors": self.floors.to_dict(),
            "improvement_pct": json_safe(self.improvement_pct),
            "peak_velocity_angle_deg": (
                None if self.optimized is None else self.optimized.peak_velocity_angle_deg
            ),
            "target_peak_velocity_angle_deg": self.target_peak_angle_deg,
            "optimizer": self._optimizer_dict(),
            "conditions": self._conditions(),
            "warnings": list(self.warnings),
            "methods": self._methods_dict(),
            "method_errors": {n: f.to_dict() for n, f in self.method_errors.items()},
            "share_of_achievable_pct": self.share_of_achievable_pct,
            "floor_notes": dict(FLOOR_NOTES),
            "human_likeness_reference": self._likeness_reference(),
            "safety": self.safety.to_dict(),
            "actuators": self.actuators,
        }
        if self.optimized is not None:
            out["optimized"] = self.optimized.to_dict()
        return dict(json_safe(out))

    def _likeness_template(self) -> tuple[FloatArray, str]:
        e = self.elbow_joint
        q0, q1 = float(self.task.start[e]), float(self.task.goal[e])
        peak = joint_on_stroke(self.target_peak_angle_deg, q0, q1)
        return template_speed_on_stroke(self.template, q0, q1, peak_angle=peak)

    def _likeness_reference(self) -> str:
        _, source = self._likeness_template()
        return (
            "root-mean-square difference of the elbow speed over its peak against the fraction "
            f"of the elbow stroke, to {source}; 0 = the same shape"
        )

    def _conditions(self) -> dict[str, Any]:
        return {
            "robot": self.robot,
            "objective": self.objective,
            "duration": self.duration,
            "payload": self.payload_mass,
            "start_deg": np.degrees(self.task.start).tolist(),
            "goal_deg": np.degrees(self.task.goal).tolist(),
            "via_time": self.via_time,
            "phase_bounds_deg": list(self.phase_bounds_deg),
            "template": self.template.source,
            "template_lifts": self.template.n_lifts,
            "template_is_paper_default": self.template.is_paper_default,
            "methods": list(self.methods),
            "failed_methods": list(self.method_errors),
            "human_constraint": self.human_constraint,
            "no_reversal": self.no_reversal,
            "phase_shares": None if self.phase_shares is None else self.phase_shares.to_dict(),
        }

    def arrays(self) -> dict[str, FloatArray]:
        """Arrays for plots on one common time grid.

        Keys are ``t`` (T,) [s] and, per method, ``<method>_<q|qd|qdd|tau>`` (T, n) in SI
        units, ``<method>_power`` (T,) [W] (sum over joints of |tau * qd|) and
        ``<method>_energy`` (T,) [J] (its running integral); ``standard_*`` and ``optimized_*``
        repeat the quintic's and the paper's.
        """
        out: dict[str, FloatArray] = {"t": self.standard.trajectory.t}
        labels = [(name, m.evaluated) for name, m in self.methods.items()]
        labels.append(("standard", self.standard))
        if self.optimized is not None:
            labels.append(("optimized", self.optimized))
        for label, ev in labels:
            tr = ev.trajectory
            out[f"{label}_q"] = tr.q
            out[f"{label}_qd"] = tr.qd
            out[f"{label}_qdd"] = tr.qdd
            out[f"{label}_tau"] = ev.tau
            power = power_curve(tr.qd, ev.tau)
            out[f"{label}_power"] = power
            out[f"{label}_energy"] = cumulative_energy(tr.t, power)
        return out

    def phase_times(self, label: str = "optimized") -> tuple[float, float]:
        """Times [s] at which the elbow crosses the A/B and B/C phase bounds.

        ``label`` is ``"standard"``, ``"optimized"`` or a method name.
        """
        if label == "standard":
            ev = self.standard
        elif label == "optimized" and self.optimized is not None:
            ev = self.optimized
        else:
            ev = self.method("paper" if label == "optimized" else label).evaluated
        return phase_boundary_times(
            ev.trajectory, self.elbow_joint, self.task, self.phase_bounds_deg
        )


def _bound_warnings(
    objective: str, methods: dict[str, MethodResult], values: dict[str, float]
) -> list[str]:
    """Errors when a method under a bound's rules still beats it, notes when one outside them
    does (no share is given to either)."""
    out: list[str] = []
    for bound in ("bound", "bound_unrestricted"):
        if bound not in methods:
            continue
        cert = (methods[bound].solver or {}).get("certificate", {})
        for name, value in values.items():
            if name == bound or not beats_bound(value, values[bound], scale=values["quintic"]):
                continue
            if name == "bound_unrestricted" and bound == "bound":
                continue  # outside the task's rules by definition
            gap = 100.0 * (values[bound] - value) / abs(values[bound])
            why = cert.get("outside_rules", {}).get(name)
            if why is None:
                out.append(
                    f"error: {name} beats {bound} on {objective} by {gap:.3g} % after the "
                    "bound's improvement: the bound does not bound, no share is given"
                )
            else:
                out.append(
                    f"{name} is {gap:.3g} % below {bound} on {objective} but outside its rules "
                    f"({why}): no share is given"
                )
    return out


def _peak_target(
    robot: Robot, task: PlanTask, template: HumanTemplate, peak_angle_deg: float | None
) -> tuple[float, float]:
    """The elbow's peak-velocity angle on the stroke [rad] and as human flexion [deg]."""
    elbow = robot.elbow_joint
    q0_e, q1_e = float(task.start[elbow]), float(task.goal[elbow])
    if peak_angle_deg is None:
        q_via = template.peak_joint_angle(q0_e, q1_e)
        target_deg = float(flexion_on_stroke(np.array([q_via]), q0_e, q1_e)[0])
    else:
        target_deg = float(peak_angle_deg)
        q_via = joint_on_stroke(peak_angle_deg, q0_e, q1_e)
    lo_e, hi_e = sorted((q0_e, q1_e))
    if not lo_e < q_via < hi_e:
        raise PlanningError(
            f"peak-velocity angle {target_deg:.1f} deg lies outside the elbow's stroke "
            f"[{math.degrees(lo_e):.1f}, {math.degrees(hi_e):.1f}] deg (expected an angle "
            "strictly inside it)"
        )
    return q_via, target_deg


def _options_of(options: PlanOptions | None, overrides: dict[str, Any]) -> PlanOptions:
    """``options`` (default: ``PlanOptions()``) with ``overrides`` by name, as a PlanningError
    naming the option when one is unknown or out of range."""
    try:
        base = PlanOptions() if options is None else options
        return base.replace(**overrides) if overrides else base
    except OptionsError as exc:
        raise PlanningError(str(exc)) from None


def _plan_warnings(
    given_template: HumanTemplate | None, methods: dict[str, MethodResult]
) -> list[str]:
    warnings: list[str] = []
    if given_template is not None and given_template.is_paper_default:
        warnings.append(
            f"the human template ({given_template.source}) holds the paper's default values: "
            "no recorded lift with kinematics shaped this plan"
        )
    for name, m in methods.items():
        if m.evaluated.violations:
            what = "the standard quintic" if name == "quintic" else f"{name} (fine report grid)"
            warnings.append(f"{what} violates limits: " + "; ".join(m.evaluated.violations))
        clearance = (m.solver or {}).get("clearance") or {}
        if clearance.get("warning"):  # the mounting plane could not be kept clear
            warnings.append(f"{name}: {clearance['warning']}")
    return warnings


@dataclass(frozen=True)
class _Optimal:
    spec: HumanSpec
    shares: PhaseShares | None
    n_intervals: int
    no_reversal: bool
    converge: bool = False


@dataclass
class _Outcome:
    """What ``_run_methods`` made: results and failures by method, the PSO run, the via time."""

    results: dict[str, MethodResult] = field(default_factory=dict)
    failures: dict[str, MethodFailure] = field(default_factory=dict)
    pso: PSOResult | None = None
    via_time: float | None = None

    def attempt(self, name: str, run: Any) -> MethodResult | None:
        """``run()``'s result stored under ``name``, or its own error (METHOD_ERRORS) stored
        as the method's failure; anything else is a bug and propagates."""
        try:
            result: MethodResult = run()
        except METHOD_ERRORS as exc:
            self.failures[name] = failure_of(name, exc)
            self.results.pop(name, None)
            return None
        self.results[name] = result
        return result


def _run_methods(
    robot: Robot,
    task: PlanTask,
    chosen: tuple[str, ...],
    *,
    duration: float,
    objective: str,
    paper_args: dict[str, Any],
    optimal: _Optimal,
    report_samples: int,
    progress: ProgressFn | None,
) -> _Outcome:
    """Run every chosen method (the quintic always) on the same report grid; a method's own
    error is kept as its failure and the others still run."""
    out = _Outcome()
    out.attempt("quintic", lambda: MethodResult(
        "quintic",
        evaluate_trajectory(
            robot, quintic(task.start, task.goal, duration, n_samples=report_samples), task
        ),
    ))  # fmt: skip
    optimal_share = 0.5 if "paper" in chosen else 0.0
    if "paper" in chosen:

        def paper() -> MethodResult:
            result, out.pso, out.via_time = run_paper(
                robot, task, duration=duration, objective=objective,
                report_samples=report_samples, progress=within(progress, 0.0, optimal_share),
                **paper_args,
            )  # fmt: skip
            return result

        out.attempt("paper", paper)
    if "jerk_limited" in chosen:
        out.attempt("jerk_limited", lambda: run_jerk_limited(
            robot, task, duration=duration, report_samples=report_samples
        ))  # fmt: skip
    todo = [m for m in ("human_optimal", "bound", "bound_unrestricted") if m in chosen]
    for i, name in enumerate(todo):
        report(
            progress,
            "optimal_control",
            i,
            len(todo),
            fraction=optimal_share + (1 - optimal_share) * i / len(todo),
            message=f"optimal control: {name}",
        )
        human = name == "human_optimal"
        # Every bound starts from the best of the other methods (the task's bound too, for the
        # unrestricted one, whose rules it obeys) and is improved until none beats it.
        made = out.attempt(name, lambda name=name, human=human: (
            run_optimal(
                robot, task, name=name, duration=duration, objective=objective,
                spec=optimal.spec, warm=out.results.get("paper"),
                n_intervals=optimal.n_intervals, no_reversal=optimal.no_reversal,
                report_samples=report_samples,
            ) if human else run_bound(
                robot, task, name=name, duration=duration, objective=objective,
                candidates=dict(out.results), n_intervals=optimal.n_intervals,
                no_reversal=optimal.no_reversal and name == "bound",
                report_samples=report_samples,
                stricter="bound" if name == "bound_unrestricted" and optimal.no_reversal
                and "bound" in out.results else None,
            )
        ))  # fmt: skip
        if made is not None and optimal.converge:
            out.attempt(name, lambda name=name, human=human, made=made: refine_to_convergence(
                robot, task, made, duration=duration, objective=objective,
                spec=optimal.spec if human else HumanSpec("none", robot.elbow_joint),
                no_reversal=optimal.no_reversal and name in ("human_optimal", "bound"),
                report_samples=report_samples, keep_lowest=not human,
            ))  # fmt: skip
    out.results = {m: out.results[m] for m in chosen if m in out.results}
    return out


def _require_enough(outcome: _Outcome, chosen: tuple[str, ...]) -> None:
    """A plan needs the quintic (every saving's reference) and, when others were asked for, at
    least one of them; otherwise the clearest failure is raised: the only one itself (its own
    type, e.g. ``SolverError``), else :class:`PlanFailed` led by an infeasibility that names a
    duration, then any infeasibility, then the first failure, with the others after it."""
    failures = outcome.failures
    if "quintic" in failures:
        raise failures["quintic"].exception
    if len(outcome.results) > 1 or len(chosen) == 1:
        return
    if len(failures) == 1:
        raise next(iter(failures.values())).exception

    def rank(f: MethodFailure) -> tuple[int, float]:
        # The smallest verified duration first: planning at it makes the plan succeed.
        shortest = getattr(f.exception, "shortest_duration", None)
        if f.kind == "infeasible" and shortest is not None:
            return 0, float(shortest)
        if f.kind == "infeasible" and "expected a duration" in f.error:
            return 1, math.inf
        return (2 if f.kind == "infeasible" else 3), math.inf

    ordered = sorted(failures.values(), key=rank)
    lead, rest = ordered[0], ordered[1:]
    raise PlanFailed(
        f"no method but the quintic succeeded: {lead.name}: {lead.error} (also failed: "
        + "; ".join(f"{f.name}: {f.error}" for f in rest)
        + ")",
        failures,
    )


def _check_feasible_at_all(
    robot: Robot, task: PlanTask, duration: float, chosen: tuple[str, ...]
) -> None:
    """Refuse, before any method runs, what no method can do: a stroke faster than a speed
    limit allows (naming the joint, the limit and a duration verified by planning at it), and,
    when a method that keeps the torque limits is asked for, a load no joint can hold still at
    the start or the goal (no duration helps)."""
    mean_speed = np.abs(np.asarray(task.goal) - np.asarray(task.start)) / duration
    slow = np.flatnonzero(mean_speed > np.asarray(robot.qd_max))
    if slow.size:
        j = int(slow[np.argmax(mean_speed[slow] / np.asarray(robot.qd_max)[slow])])
        found = shortest_verified_duration(robot, task.start, task.goal)
        raise PlanningError(
            f"infeasible: joint {j + 1} ({robot.joint_names[j]}) must average "
            f"{mean_speed[j]:.2f} rad/s over {duration:g} s but its speed limit is "
            f"{robot.qd_max[j]:.3g} rad/s: {found.describe()}"
        )
    if set(chosen) & {"paper", "human_optimal", "bound", "bound_unrestricted"}:
        why = rest_overload(robot, task.start, task.goal)
        if why:
            raise PlanningError(why)


@dataclass(frozen=True)
class _Prepared:
    """What :func:`plan` derives from the checked task before planning: the template used, the
    elbow's peak-velocity angle on the stroke ``q_via`` [rad] and as human flexion
    ``target_deg`` [deg], and the human constraint with its phase shares."""

    template: HumanTemplate
    q_via: float
    target_deg: float
    spec: HumanSpec
    shares: PhaseShares | None


def _prepare(
    robot: Robot,
    task: PlanTask,
    template: HumanTemplate,
    opts: PlanOptions,
    chosen: tuple[str, ...],
) -> _Prepared:
    """Check the task (reachable at all in ``opts.duration`` by the ``chosen`` methods, then
    within the limits), place the template's peak and build the human constraint."""
    duration, human_constraint = opts.duration, opts.human_constraint
    if np.shape(task.start) == np.shape(task.goal) == (robot.n_joints,) and duration > 0:
        _check_feasible_at_all(robot, task, duration, chosen)
    validate_task(robot, task, duration)
    q_via, target_deg = _peak_target(robot, task, template, opts.peak_angle_deg)
    if "human_optimal" in chosen:
        spec, shares = human_spec(human_constraint, robot, task, template, q_via)
    else:  # still refuse an unknown constraint name
        human_spec(
            human_constraint if human_constraint not in ("phases", "shape") else "none",
            robot,
            task,
            template,
            q_via,
        )
        spec, shares = HumanSpec("none", robot.elbow_joint), None
    return _Prepared(template, q_via, target_deg, spec, shares)


def _plan_result(
    robot: Robot,
    opts: PlanOptions,
    task: PlanTask,
    given_template: HumanTemplate | None,
    prepared: _Prepared,
    outcome: _Outcome,
    fl: Floors,
    chosen: tuple[str, ...],
) -> PlanResult:
    """The comparison of the planned methods: objective values, warnings (template, bounds,
    failed methods, actuators), actuator and safety checks, with the options they came from
    (``given_template`` is the caller's, None for the paper's; ``chosen`` the methods asked
    for; ``fl`` the task's physical floors)."""
    results, objective, template = outcome.results, opts.objective, prepared.template
    paper = results.get("paper")
    values = {n: objective_value(robot, m.evaluated, objective) for n, m in results.items()}
    warnings = [
        *_plan_warnings(given_template, results),
        *_bound_warnings(objective, results, values),
        *(f"{f.name} failed: {f.error}" for f in outcome.failures.values()),
    ]
    actuators, actuator_warnings = plan_actuators(robot, results)
    warnings += actuator_warnings
    return PlanResult(
        robot=robot.name,
        objective=objective,
        duration=opts.duration,
        payload_mass=float(robot.payload.mass),
        task=task,
        template=template,
        target_peak_angle_deg=float(prepared.target_deg),
        standard=results["quintic"].evaluated,
        optimized=None if paper is None else paper.evaluated,
        floors=fl,
        optimizer=outcome.pso,
        via_time=outcome.via_time,
        elbow_joint=robot.elbow_joint,
        phase_bounds_deg=(float(template.phase_bounds_deg[0]), float(template.phase_bounds_deg[1])),
        warnings=tuple(warnings),
        methods=results,
        objective_values=values,
        human_constraint=opts.human_constraint,
        no_reversal=opts.no_reversal,
        phase_shares=prepared.shares,
        joint_names=tuple(robot.joint_names),
        human_rule=prepared.spec.rules() if "human_optimal" in chosen else "",
        method_errors=dict(outcome.failures),
        actuators=actuators,
        safety=(
            check_safety(robot, {n: m.trajectory for n, m in results.items()})
            if opts.safety
            else not_checked(SKIPPED)
        ),
    )


def plan(
    robot: Robot,
    options: PlanOptions | None = None,
    *,
    task: PlanTask | None = None,
    template: HumanTemplate | None = None,
    progress: ProgressFn | None = None,
    **overrides: Any,
) -> PlanResult:
    """Plan a task with the chosen methods and compare them.

    Args:
        robot: the robot, with its payload (``load_robot(name, payload=kg)``).
        options: every option (``PlanOptions``: duration [s], objective, PSO seed and budget,
            methods, human constraint, transcription...); its fields hold the defaults,
            ranges and units. None: the defaults.
        task: start and goal configurations; defaults to the robot's curl task.
        template: the human template; defaults to the paper's (velocity peak at 62 deg).
        progress: called with a ``Progress`` (stages ``pso``, ``optimal_control``, ``done``).
        **overrides: options by name over ``options`` (``plan(robot, duration=2.0,
            methods=ALL_METHODS)``); an unknown name is a PlanningError naming it.

    Returns:
        The comparison; ``to_dict()`` gives the CLI's JSON.

    Raises:
        PlanningError: bad task or options, or no trajectory satisfies the limits.
        SolverError: IPOPT did not solve an optimal-control problem.
        JerkLimitedError: the jerk-limited move needs more time than ``duration``.
    """
    opts = _options_of(options, overrides)
    chosen = check_methods(opts.methods)
    logging.getLogger("bioplan.planning").info(
        "plan of %s: %s over %g s, %s", robot.name, ", ".join(chosen), opts.duration, opts.objective
    )
    task = task or PlanTask.default(robot)
    prepared = _prepare(robot, task, template or HumanTemplate(), opts, chosen)
    outcome = _run_methods(
        robot,
        task,
        chosen,
        duration=opts.duration,
        objective=opts.objective,
        paper_args={
            "q_via": prepared.q_via,
            "target_deg": prepared.target_deg,
            "seed": opts.seed,
            "particles": opts.particles,
            "iterations": opts.iterations,
            "n_samples": opts.n_samples,
        },
        optimal=_Optimal(
            prepared.spec, prepared.shares, opts.n_intervals, opts.no_reversal, opts.converge
        ),
        report_samples=opts.report_samples,
        progress=progress,
    )
    _require_enough(outcome, chosen)
    fl = task_floors_of(robot, task, opts.duration)
    for name, m in outcome.results.items():
        check_floors(m.evaluated, fl, name)
    report(progress, "done", 1, 1, message="planned")
    return _plan_result(robot, opts, task, template, prepared, outcome, fl, chosen)
