"""The paper's method: two quintic segments joined at the template's angle, tuned by PSO.

The paper's method, generalised to any robot whose task moves an "elbow" joint:

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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from app.planning.energy import objective_values
from app.planning.evaluation import PlanTask
from app.planning.profiles import piecewise_quintic_batch, quintic, time_grid
from app.planning.robots import Robot

FloatArray = NDArray[np.float64]


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
        # An unbounded side (a continuous joint) has no violation: inf / inf would be NaN.
        span = np.where(np.isfinite(span), span, 1.0)
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
