"""What every planning method shares: the task, the evaluation of a trajectory, the checks.

A method's trajectory is evaluated the same way whatever made it: inverse dynamics with
Pinocchio on the fine report grid, every metric of :mod:`app.planning.energy`, where the elbow is
fastest, and every limit violation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.errors import BioPlanError
from app.planning.energy import EnergyMetrics, Floors, energy_metrics
from app.planning.human_template import flexion_on_stroke
from app.planning.profiles import Trajectory, check_limits
from app.planning.robots import Robot

FloatArray = NDArray[np.float64]

#: Relative slack on limits and floors for round-off [-].
_TOL = 1e-9
#: Samples within this fraction of the elbow's top speed count as its peak [-] (an optimum
#: may hold the top speed over a stretch: the peak is where it is first reached).
PEAK_SPEED_TOLERANCE = 1e-6


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
        peak_velocity_span_deg: first and last elbow angle [deg] at which the elbow moves at its
            top speed (an optimum may hold it over a stretch; equal for a sharp peak).
    """

    trajectory: Trajectory
    tau: FloatArray
    metrics: EnergyMetrics
    peak_velocity_angle_deg: float
    peak_velocity_time: float
    violations: tuple[str, ...]
    peak_velocity_span_deg: tuple[float, float] = (math.nan, math.nan)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = dict(self.metrics.to_dict())
        out["peak_velocity_angle_deg"] = self.peak_velocity_angle_deg
        out["peak_velocity_span_deg"] = list(self.peak_velocity_span_deg)
        out["peak_velocity_time"] = self.peak_velocity_time
        out["violations"] = list(self.violations)
        return out


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
    speed = np.abs(traj.qd[:, elbow])
    top = np.flatnonzero(speed >= speed.max() * (1.0 - PEAK_SPEED_TOLERANCE))
    i_peak = int(top[0])
    span = elbow_flexion_deg(traj.q[[int(top[0]), int(top[-1])], elbow], task, elbow)
    peak_angle = float(span[0])
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
        peak_velocity_span_deg=(float(span[0]), float(span[1])),
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


def check_floors(ev: EvaluatedTrajectory, fl: Floors, label: str) -> None:
    """A metric below its physical floor means a bug in dynamics or integration: fail loudly.

    The discrete net work ∫Στ·q̇ dt (trapezoid) differs from ΔPE only by integration error, and
    abs_work >= pos_work >= net work holds exactly on the grid; so the floors are checked with that
    integration error as slack, and an integration error above 0.1 % is itself reported as a bug.
    The electrical floor gets the same slack plus 0.1 % of the friction floor (the trapezoidal
    friction work of a sampled motion differs from its integral by that order).
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
        ("abs_work", ev.metrics.abs_work, fl.abs_work, slack),
        ("pos_work", ev.metrics.pos_work, fl.pos_work, slack),
        ("peak_power", ev.metrics.peak_power, fl.peak_power, slack / tr.duration),
        (
            "electrical_energy",
            ev.metrics.electrical_energy,
            fl.electrical_energy,
            slack + 1e-3 * fl.friction_energy,
        ),
    )
    for name, value, floor, tol in checks:
        if value is not None and value < floor - tol:
            raise RuntimeError(
                f"{label} {name} = {value:.6g} is below its physical floor {floor:.6g}: "
                "dynamics or integration is wrong"
            )


def task_floors_of(robot: Robot, task: PlanTask, duration: float) -> Floors:
    """The floors of a task on a robot (potential energy from its dynamics, friction from its
    motors)."""
    from app.planning.energy import task_floors

    pe = robot.dynamics().potential_energy(np.stack([task.start, task.goal]))
    return task_floors((float(pe[0]), float(pe[1])), task.goal - task.start, duration, robot.motors)
