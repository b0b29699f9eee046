"""The bio-inspired planner: quintic segments shaped like a human lift, tuned by PSO.

The paper's method, generalised to any robot whose task moves an "elbow" joint:

* The standard trajectory is one quintic per joint (zero velocity and acceleration at both ends).
* The optimised trajectory is two quintic segments per joint, joined at a via point. At the via
  point the elbow passes the human template's peak-velocity angle (62 deg by default, the middle of
  phase B) with zero acceleration, i.e. at a stationary point of its velocity. A constraint makes
  that stationary point the velocity's global peak, so the elbow really is fastest there, as in a
  human curl: accelerate through phase A, carry momentum through the weak phase B, let gravity
  decelerate phase C.
* PSO chooses the via time and the elbow's via speed, and for every other moving joint (the
  shoulder in the default task) its position and speed at the via time. Constraints (Deb's
  feasibility rules in ``pso_minimize``): joint position, velocity and torque limits, the elbow's
  velocity peak at the via point, and no reversal of any joint.

Metrics are reported on a fine grid (``report_samples``), not on the optimiser's coarse grid, so a
peak between two coarse samples is not missed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.errors import BioPlanError
from app.planning.energy import (
    OBJECTIVES,
    EnergyMetrics,
    Floors,
    cumulative_energy,
    energy_metrics,
    floors,
    improvement_pct,
    objective_values,
    power_curve,
)
from app.planning.human_template import HumanTemplate, flexion_on_stroke, joint_on_stroke
from app.planning.jsonsafe import json_safe
from app.planning.profiles import (
    Trajectory,
    check_limits,
    piecewise_quintic,
    piecewise_quintic_batch,
    quintic,
    time_grid,
)
from app.planning.pso import PSOResult, pso_minimize
from app.planning.robots import Robot
from app.progress import ProgressFn, report

FloatArray = NDArray[np.float64]

#: Relative slack on limits and floors for round-off [-].
_TOL = 1e-9


class PlanningError(BioPlanError):
    """The task cannot be planned as asked (one-line message: what and what was expected)."""


@dataclass(frozen=True)
class PlanTask:
    """A rest-to-rest joint-space task.

    Attributes:
        start: (n,) start configuration [rad].
        goal: (n,) goal configuration [rad].
    """

    start: FloatArray
    goal: FloatArray

    @classmethod
    def default(cls, robot: Robot) -> PlanTask:
        """The robot's default curl task (for the built-ins: J2 0->20 deg, J3 0->150 deg)."""
        return cls(
            np.array(robot.default_start, dtype=float), np.array(robot.default_goal, dtype=float)
        )

    @classmethod
    def from_degrees(cls, start_deg: Any, goal_deg: Any) -> PlanTask:
        return cls(
            np.radians(np.asarray(start_deg, float)), np.radians(np.asarray(goal_deg, float))
        )


@dataclass(frozen=True)
class EvaluatedTrajectory:
    """A trajectory with its inverse dynamics and metrics.

    Attributes:
        trajectory: the sampled trajectory (fine report grid).
        tau: (T, n) joint torques from inverse dynamics [Nm] (rigid body + armature).
        metrics: the energy metrics of DESIGN.md.
        peak_velocity_angle_deg: elbow angle where the elbow's speed peaks [deg].
        peak_velocity_time: time of that peak [s].
        violations: human-readable limit violations (empty when feasible).
    """

    trajectory: Trajectory
    tau: FloatArray
    metrics: EnergyMetrics
    peak_velocity_angle_deg: float
    peak_velocity_time: float
    violations: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = dict(self.metrics.to_dict())
        out["peak_velocity_angle_deg"] = self.peak_velocity_angle_deg
        out["peak_velocity_time"] = self.peak_velocity_time
        out["violations"] = list(self.violations)
        return out


@dataclass(frozen=True)
class PlanResult:
    """Standard and optimised trajectories on the same task, with metrics and floors.

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
    optimized: EvaluatedTrajectory
    floors: Floors
    optimizer: PSOResult
    via_time: float
    elbow_joint: int
    phase_bounds_deg: tuple[float, float]
    warnings: tuple[str, ...] = field(default=())
    joint_names: tuple[str, ...] = field(default=())

    @property
    def improvement_pct(self) -> dict[str, Any]:
        """100 (standard - optimised) / standard per metric: positive means the plan saves."""
        return improvement_pct(self.standard.metrics, self.optimized.metrics)

    def to_dict(self) -> dict[str, Any]:
        return {
            "joint_names": list(self.joint_names),
            "duration": self.duration,
            "task": {
                "start_deg": np.degrees(self.task.start).tolist(),
                "goal_deg": np.degrees(self.task.goal).tolist(),
            },
            "standard": self.standard.to_dict(),
            "optimized": self.optimized.to_dict(),
            "floors": self.floors.to_dict(),
            "improvement_pct": json_safe(self.improvement_pct),
            "peak_velocity_angle_deg": self.optimized.peak_velocity_angle_deg,
            "target_peak_velocity_angle_deg": self.target_peak_angle_deg,
            "optimizer": {
                "iterations": self.optimizer.iterations,
                "evaluations": self.optimizer.evaluations,
                "seconds": self.optimizer.seconds,
                "seed": self.optimizer.seed,
                "best_cost": self.optimizer.best_cost,
                "stopped_early": self.optimizer.stopped_early,
                "history": [float(c) for c in self.optimizer.history],
            },
            "conditions": {
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
            },
            "warnings": list(self.warnings),
        }

    def arrays(self) -> dict[str, FloatArray]:
        """Arrays for plots: time grid and, per trajectory, q, qd, qdd, tau, power, energy.

        Keys are ``t`` (T,) [s] and ``<standard|optimized>_<q|qd|qdd|tau>`` (T, n) in SI units,
        ``<...>_power`` (T,) [W] (sum over joints of |tau * qd|) and ``<...>_energy`` (T,) [J]
        (its running integral).
        """
        out: dict[str, FloatArray] = {"t": self.standard.trajectory.t}
        for label, ev in (("standard", self.standard), ("optimized", self.optimized)):
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
        """Times [s] at which the elbow crosses the A/B and B/C phase bounds."""
        ev = self.optimized if label == "optimized" else self.standard
        return phase_boundary_times(
            ev.trajectory, self.elbow_joint, self.task, self.phase_bounds_deg
        )


def elbow_flexion_deg(q_elbow: FloatArray, task: PlanTask, elbow_joint: int) -> FloatArray:
    """Human-equivalent elbow flexion [deg] along the task's elbow stroke (see
    :func:`app.planning.human_template.flexion_on_stroke`)."""
    q0, q1 = float(task.start[elbow_joint]), float(task.goal[elbow_joint])
    return flexion_on_stroke(q_elbow, q0, q1)


def phase_boundary_times(
    traj: Trajectory, elbow_joint: int, task: PlanTask, bounds_deg: tuple[float, float]
) -> tuple[float, float]:
    """Times [s] at which the elbow first reaches each phase bound (NaN if it never does)."""
    flex = elbow_flexion_deg(traj.q[:, elbow_joint], task, elbow_joint)
    out = []
    for bound in bounds_deg:
        idx = np.flatnonzero(flex >= bound)
        if idx.size == 0:
            out.append(math.nan)
        elif idx[0] == 0:
            out.append(float(traj.t[0]))
        else:
            i = int(idx[0])
            f0, f1 = flex[i - 1], flex[i]
            w = (bound - f0) / (f1 - f0) if f1 != f0 else 0.0
            out.append(float(traj.t[i - 1] + w * (traj.t[i] - traj.t[i - 1])))
    return out[0], out[1]


def evaluate_trajectory(
    robot: Robot, traj: Trajectory, task: PlanTask, *, elbow_joint: int | None = None
) -> EvaluatedTrajectory:
    """Inverse dynamics, metrics, peak-velocity angle and limit check of one trajectory."""
    elbow = robot.elbow_joint if elbow_joint is None else elbow_joint
    tau = robot.dynamics().inverse_dynamics(traj.q, traj.qd, traj.qdd)
    metrics = energy_metrics(traj.t, traj.qd, tau, motors=robot.motors)
    i_peak = int(np.argmax(np.abs(traj.qd[:, elbow])))
    peak_angle = float(elbow_flexion_deg(traj.q[i_peak : i_peak + 1, elbow], task, elbow)[0])
    violations = list(check_limits(traj, q_min=robot.q_min, q_max=robot.q_max, qd_max=robot.qd_max))
    over = np.abs(tau) > np.asarray(robot.tau_max) * (1 + _TOL)
    for j in np.flatnonzero(over.any(axis=0)):
        k = int(np.argmax(np.abs(tau[:, j])))
        violations.append(
            f"joint {j + 1} ({robot.joint_names[j]}) torque {abs(tau[k, j]):.1f} Nm exceeds "
            f"{robot.tau_max[j]:.1f} Nm at t={traj.t[k]:.3f} s"
        )
    return EvaluatedTrajectory(
        trajectory=traj,
        tau=tau,
        metrics=metrics,
        peak_velocity_angle_deg=peak_angle,
        peak_velocity_time=float(traj.t[i_peak]),
        violations=tuple(violations),
    )


def validate_task(robot: Robot, task: PlanTask, duration: float) -> None:
    """Refuse tasks that cannot be planned, with a one-line reason."""
    n = len(robot.joint_names)
    start, goal = np.asarray(task.start, float), np.asarray(task.goal, float)
    if start.shape != (n,) or goal.shape != (n,):
        raise PlanningError(
            f"task has {start.size} start and {goal.size} goal angles; robot {robot.name!r} "
            f"has {n} joints"
        )
    if not (math.isfinite(duration) and duration > 0):
        raise PlanningError(f"duration must be a positive number of seconds, got {duration}")
    if np.allclose(start, goal):
        raise PlanningError("start equals goal: nothing to plan (expected a task that moves)")
    for name, q in (("start", start), ("goal", goal)):
        bad = np.flatnonzero((q < robot.q_min - 1e-12) | (q > robot.q_max + 1e-12))
        if bad.size:
            j = int(bad[0])
            raise PlanningError(
                f"{name} angle of joint {j + 1} ({robot.joint_names[j]}) is "
                f"{math.degrees(q[j]):.1f} deg, outside its limits "
                f"[{math.degrees(robot.q_min[j]):.1f}, {math.degrees(robot.q_max[j]):.1f}] deg"
            )
    # No rest-to-rest motion of this duration has a lower peak speed than the mean speed.
    mean_speed = np.abs(goal - start) / duration
    slow = np.flatnonzero(mean_speed > robot.qd_max)
    if slow.size:
        j = int(slow[0])
        shortest = abs(goal[j] - start[j]) / robot.qd_max[j]
        raise PlanningError(
            f"infeasible: joint {j + 1} ({robot.joint_names[j]}) must average "
            f"{mean_speed[j]:.2f} rad/s over {duration} s but its limit is {robot.qd_max[j]:.2f} "
            f"rad/s (expected a duration of at least {shortest:.2f} s)"
        )
    if abs(goal[robot.elbow_joint] - start[robot.elbow_joint]) < 1e-9:
        raise PlanningError(
            f"the task does not move the elbow joint ({robot.joint_names[robot.elbow_joint]}), "
            "which the human template shapes"
        )


@dataclass(frozen=True)
class _Design:
    """Maps PSO decision vectors to via-point knots."""

    start: FloatArray
    goal: FloatArray
    duration: float
    elbow: int
    q_via_elbow: float
    others: tuple[int, ...]  # moving non-elbow joints

    @property
    def dim(self) -> int:
        return 2 + 2 * len(self.others)

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        lower = [0.15, 1.0] + [0.0, 0.0] * len(self.others)
        upper = [0.85, 3.0] + [1.0, 3.0] * len(self.others)
        return np.array(lower), np.array(upper)

    def knots(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Decision vectors (B, D) -> knot times (B, 3), positions, velocities, accels (B, 3, n)."""
        b = x.shape[0]
        n = self.start.size
        delta = self.goal - self.start
        mean_speed = delta / self.duration
        t_knots = np.empty((b, 3))
        t_knots[:, 0] = 0.0
        t_knots[:, 1] = x[:, 0] * self.duration
        t_knots[:, 2] = self.duration
        q_knots = np.empty((b, 3, n))
        q_knots[:, 0] = self.start
        q_knots[:, 2] = self.goal
        # Joints that do not move stay put; the elbow passes the template angle.
        q_knots[:, 1] = np.where(np.abs(delta) > 0, np.nan, self.start)
        q_knots[:, 1, self.elbow] = self.q_via_elbow
        qd_knots = np.zeros((b, 3, n))
        qd_knots[:, 1, self.elbow] = x[:, 1] * mean_speed[self.elbow]
        for k, j in enumerate(self.others):
            q_knots[:, 1, j] = self.start[j] + x[:, 2 + 2 * k] * delta[j]
            qd_knots[:, 1, j] = x[:, 3 + 2 * k] * mean_speed[j]
        qdd_knots = np.zeros((b, 3, n))
        return t_knots, q_knots, qd_knots, qdd_knots

    def initial_guess(self, q_std: FloatArray, qd_std: FloatArray, t: FloatArray) -> FloatArray:
        """The decision vector closest to the standard quintic (seeds one particle)."""
        qe = q_std[:, self.elbow]
        if self.goal[self.elbow] < self.start[self.elbow]:
            qe = -qe
            target = -self.q_via_elbow
        else:
            target = self.q_via_elbow
        t_via = float(np.interp(target, qe, t))
        frac = float(np.clip(t_via / self.duration, 0.15, 0.85))
        delta = self.goal - self.start
        mean_speed = delta / self.duration
        x = [frac, float(np.interp(t_via, t, qd_std[:, self.elbow]) / mean_speed[self.elbow])]
        for j in self.others:
            x.append(float((np.interp(t_via, t, q_std[:, j]) - self.start[j]) / delta[j]))
            x.append(float(np.interp(t_via, t, qd_std[:, j]) / mean_speed[j]))
        lo, hi = self.bounds()
        return np.asarray(np.clip(np.array(x), lo, hi), dtype=np.float64)


@dataclass(frozen=True)
class PlanProblem:
    """The PSO problem of one planning task: decision-vector bounds and the batched cost.

    Exposed so benchmarks can hand exactly the planner's problem to another optimiser.
    """

    robot: Robot
    design: _Design
    objective: str
    t: FloatArray
    lower: FloatArray
    upper: FloatArray
    initial: FloatArray

    @classmethod
    def build(
        cls,
        robot: Robot,
        task: PlanTask,
        *,
        duration: float,
        objective: str,
        q_via_elbow: float,
        n_samples: int,
    ) -> PlanProblem:
        start = np.asarray(task.start, float)
        goal = np.asarray(task.goal, float)
        elbow = robot.elbow_joint
        moving = np.flatnonzero(np.abs(goal - start) > 0)
        design = _Design(
            start=start,
            goal=goal,
            duration=duration,
            elbow=elbow,
            q_via_elbow=q_via_elbow,
            others=tuple(int(j) for j in moving if j != elbow),
        )
        t = time_grid(duration, n_samples)
        std = quintic(start, goal, duration, n_samples=n_samples)
        lower, upper = design.bounds()
        initial = design.initial_guess(std.q, std.qd, t)
        return cls(robot, design, objective, t, lower, upper, initial)

    def swarm_cost(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Decision vectors (P, D) -> objective (P,) and constraint violation (P,) >= 0."""
        robot, design, t = self.robot, self.design, self.t
        elbow = design.elbow
        tk, qk, qdk, qddk = design.knots(x)
        q, qd, qdd = piecewise_quintic_batch(tk, qk, qdk, qddk, t)
        tau = robot.dynamics().inverse_dynamics(q, qd, qdd)
        tau_max = np.asarray(robot.tau_max)
        cost = objective_values(self.objective, t, qd, tau, motors=robot.motors, tau_max=tau_max)
        # Violations, each normalised so 1 means "100 % over the limit".
        q_min, q_max = np.asarray(robot.q_min), np.asarray(robot.q_max)
        v = np.zeros(x.shape[0])
        v += np.maximum(np.abs(qd) / np.asarray(robot.qd_max) - 1.0, 0.0).max(axis=(1, 2))
        v += np.maximum(np.abs(tau) / tau_max - 1.0, 0.0).max(axis=(1, 2))
        span = np.maximum(q_max - q_min, 1e-9)
        v += np.maximum((q_min - q) / span, 0.0).max(axis=(1, 2))
        v += np.maximum((q - q_max) / span, 0.0).max(axis=(1, 2))
        # The elbow's speed must peak at the via point (where it equals the via speed).
        v_via = np.abs(qdk[:, 1, elbow])
        v += np.maximum(np.abs(qd[:, :, elbow]).max(axis=1) / v_via - 1.0, 0.0)
        # No joint may reverse: velocity keeps the sign of the stroke.
        delta = design.goal - design.start
        direction = np.sign(delta)
        mean_speed = np.maximum(np.abs(delta) / design.duration, 1e-9)
        reverse = np.maximum(-qd * direction, 0.0) / mean_speed
        v += np.where(direction != 0, reverse, 0.0).max(axis=(1, 2))
        return cost, v


def plan(
    robot: Robot,
    *,
    task: PlanTask | None = None,
    duration: float = 1.0,
    objective: str = "abs_work",
    template: HumanTemplate | None = None,
    seed: int = 0,
    particles: int = 40,
    iterations: int = 100,
    n_samples: int = 100,
    report_samples: int = 1000,
    peak_angle_deg: float | None = None,
    progress: ProgressFn | None = None,
) -> PlanResult:
    """Plan the standard and the bio-inspired trajectory of a task and compare them.

    Args:
        robot: the robot, with its payload (``load_robot(name, payload=kg)``).
        task: start and goal configurations; defaults to the robot's curl task.
        duration: motion time [s], the same for both trajectories.
        objective: the metric PSO minimises (one of ``energy.OBJECTIVES``).
        template: the human template; defaults to the paper's (velocity peak at 62 deg).
        seed: PSO seed; the same inputs and seed give the same result bit for bit.
        particles: swarm size.
        iterations: PSO iterations (at most; it stops early on stagnation).
        n_samples: time samples per trajectory inside the optimiser.
        report_samples: time samples of the reported trajectories and metrics.
        peak_angle_deg: overrides the template's elbow peak-velocity angle [deg].
        progress: called with a ``Progress`` (stage ``pso``: iterations, best cost) while
            optimising.

    Returns:
        The comparison; ``to_dict()`` gives the CLI's JSON.

    Raises:
        PlanningError: bad task, unknown objective, or no trajectory satisfies the limits.
    """
    if objective not in OBJECTIVES:
        raise PlanningError(
            f"unknown objective {objective!r} (expected one of: {', '.join(OBJECTIVES)})"
        )
    if particles < 2 or iterations < 1 or n_samples < 10 or report_samples < 10:
        raise PlanningError(
            "particles must be >= 2, iterations >= 1, n_samples and report_samples >= 10"
        )
    given_template = template
    template = template or HumanTemplate()
    task = task or PlanTask.default(robot)
    validate_task(robot, task, duration)
    start = np.asarray(task.start, float)
    goal = np.asarray(task.goal, float)
    elbow = robot.elbow_joint
    q0_e, q1_e = float(start[elbow]), float(goal[elbow])
    if peak_angle_deg is None:
        q_via = template.peak_joint_angle(q0_e, q1_e)
        target_deg = float(flexion_on_stroke(np.array([q_via]), q0_e, q1_e)[0])
    else:
        target_deg = peak_angle_deg
        q_via = joint_on_stroke(peak_angle_deg, q0_e, q1_e)
    lo_e, hi_e = sorted((start[elbow], goal[elbow]))
    if not lo_e < q_via < hi_e:
        raise PlanningError(
            f"peak-velocity angle {target_deg:.1f} deg lies outside the elbow's stroke "
            f"[{math.degrees(lo_e):.1f}, {math.degrees(hi_e):.1f}] deg"
        )
    problem = PlanProblem.build(
        robot, task, duration=duration, objective=objective, q_via_elbow=q_via, n_samples=n_samples
    )
    design = problem.design
    dyn = robot.dynamics()

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

    tk, qk, qdk, qddk = design.knots(result.best_position[None, :])
    optimized = piecewise_quintic(
        tk[0], qk[0], qdk[0], qddk[0], n_samples=report_samples, name="bio_optimized"
    )
    standard = quintic(start, goal, duration, n_samples=report_samples)
    std_eval = evaluate_trajectory(robot, standard, task)
    opt_eval = evaluate_trajectory(robot, optimized, task)
    pe = dyn.potential_energy(np.stack([start, goal]))
    fl = floors(float(pe[1] - pe[0]), duration)
    _check_floors(std_eval, fl, "standard")
    _check_floors(opt_eval, fl, "optimized")
    warnings: list[str] = []
    if given_template is not None and given_template.is_paper_default:
        warnings.append(
            f"the human template ({given_template.source}) holds the paper's default values: "
            "no recorded lift with kinematics shaped this plan"
        )
    if std_eval.violations:
        warnings.append("the standard quintic violates limits: " + "; ".join(std_eval.violations))
    if opt_eval.violations:
        warnings.append(
            "on the fine report grid the optimised trajectory violates limits: "
            + "; ".join(opt_eval.violations)
        )
    report(progress, "done", 1, 1, message="planned")
    return PlanResult(
        robot=robot.name,
        objective=objective,
        duration=duration,
        payload_mass=float(robot.payload.mass),
        task=task,
        template=template,
        target_peak_angle_deg=float(target_deg),
        standard=std_eval,
        optimized=opt_eval,
        floors=fl,
        optimizer=result,
        via_time=float(tk[0, 1]),
        elbow_joint=elbow,
        phase_bounds_deg=(float(template.phase_bounds_deg[0]), float(template.phase_bounds_deg[1])),
        warnings=tuple(warnings),
        joint_names=tuple(robot.joint_names),
    )


def _check_floors(ev: EvaluatedTrajectory, fl: Floors, label: str) -> None:
    """A metric below its physical floor means a bug in dynamics or integration: fail loudly.

    The discrete net work ∫Στ·q̇ dt (trapezoid) differs from ΔPE only by integration error, and
    abs_work >= pos_work >= net work holds exactly on the grid; so the floors are checked with that
    integration error as slack, and an integration error above 0.1 % is itself reported as a bug.
    """
    tr = ev.trajectory
    net = float(np.trapezoid(np.sum(ev.tau * tr.qd, axis=-1), tr.t))
    integration_error = abs(net - fl.delta_potential)
    scale = max(abs(fl.delta_potential), ev.metrics.abs_work, 1e-9)
    if integration_error > 1e-3 * scale:
        raise RuntimeError(
            f"{label}: net work {net:.6g} J differs from the potential-energy change "
            f"{fl.delta_potential:.6g} J by more than 0.1 %: dynamics or integration is wrong"
        )
    slack = integration_error + 1e-9 * scale
    checks = (
        ("abs_work", ev.metrics.abs_work, fl.delta_potential, slack),
        ("pos_work", ev.metrics.pos_work, fl.delta_potential, slack),
        ("peak_power", ev.metrics.peak_power, fl.min_peak_power, slack / tr.duration),
    )
    for name, value, floor, tol in checks:
        if value < floor - tol:
            raise RuntimeError(
                f"{label} {name} = {value:.6g} is below its physical floor {floor:.6g}: "
                "dynamics or integration is wrong"
            )
