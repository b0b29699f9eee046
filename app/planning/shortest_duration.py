"""The smallest feasible duration of an optimal-control request IPOPT found infeasible.

When the limits cannot be met in the asked duration, a user needs the number that can: "expected
a duration of at least 0.74 s". The search solves the cheapest problem of the same structure
(``tau_sq``, same human constraint, same limits) at longer durations, doubling until one is
feasible, then bisects to a relative tolerance.

Why bisection is sound: slowing a feasible motion down, q(t T / T'), scales velocities by
s = T / T' < 1 and accelerations by s², so every torque becomes s² τ + (1 - s²) g(q), a convex
combination of a feasible torque and the static one; position, velocity and human constraints
(the peak's place, the phases' shares) do not depend on the time scale. Feasibility is therefore
monotone in the duration whenever holding the path still is feasible, which the doubling
phase checks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from app.planning.evaluation import PlanTask, evaluate_trajectory
from app.planning.optimal import FloatArray, HumanSpec, OptimalResult, SolverError, solve_optimal
from app.planning.robots import Robot

__all__ = [
    "ShortestDuration",
    "VerifiedDuration",
    "rest_overload",
    "shortest_feasible_duration",
    "shortest_verified_duration",
]

#: Relative width of the final bracket [lo, hi]: hi is reported, a solved duration.
REL_TOL = 0.01
#: The search gives up beyond this multiple of the asked duration.
MAX_FACTOR = 16.0


@dataclass(frozen=True)
class ShortestDuration:
    """The outcome of the search.

    Attributes:
        duration: the shortest duration found feasible [s] (None: none up to ``searched``).
        infeasible_below: the longest duration found infeasible [s].
        binding: the limit closest to active at ``duration``, e.g. "the torque limit of joint
            elbow (1 Nm)" ("" when none was found).
        searched: the longest duration tried [s].
        solves: IPOPT solves spent.
    """

    duration: float | None
    infeasible_below: float
    binding: str
    searched: float
    solves: int

    def describe(self) -> str:
        """The part of the one-line error that says what is feasible."""
        if self.duration is None:
            why = f" ({self.binding})" if self.binding else ""
            return (
                f"no duration up to {self.searched:.3g} s is feasible either{why}: expected a "
                "lighter payload or wider torque limits"
            )
        return (
            f"expected a duration of at least {self.duration:.3f} s (the shortest feasible, "
            f"{self.infeasible_below:.3f} s is not; {self.binding} binds)"
        )


def shortest_feasible_duration(
    robot: Robot,
    start: FloatArray,
    goal: FloatArray,
    infeasible: float,
    *,
    human: HumanSpec,
    n_intervals: int,
    no_reversal: bool,
    rel_tol: float = REL_TOL,
    max_factor: float = MAX_FACTOR,
) -> ShortestDuration:
    """Search the shortest duration in which the request is feasible.

    Args:
        robot: the robot with its payload.
        start, goal: (n,) rest configurations [rad].
        infeasible: a duration [s] already found infeasible.
        human: the human-likeness constraint of the failed request.
        n_intervals: constant-jerk intervals of the failed request.
        no_reversal: the failed request's no-reversal option.
        rel_tol: relative width of the final bracket.
        max_factor: give up beyond ``max_factor * infeasible``.

    Returns:
        The shortest feasible duration (to ``rel_tol``, reported from above: it was solved),
        the binding limit there, and the search's cost.
    """
    solves = 0
    solved: dict[float, OptimalResult] = {}

    def feasible(duration: float) -> bool:
        nonlocal solves
        solves += 1
        try:
            solved[duration] = solve_optimal(
                robot, start, goal, duration, objective="tau_sq", human=human,
                n_intervals=n_intervals, no_reversal=no_reversal, report_samples=501,
                explain=False,
            )  # fmt: skip
        except SolverError:
            return False
        return True

    lo, hi = float(infeasible), 2.0 * float(infeasible)
    while not feasible(hi):
        lo, hi = hi, 2.0 * hi
        if hi > max_factor * infeasible:
            return ShortestDuration(None, lo, _static_overload(robot, start, goal), lo, solves)
    while hi > lo * (1.0 + rel_tol):
        mid = math.sqrt(lo * hi)
        if feasible(mid):
            hi = mid
        else:
            lo = mid
    binding = _binding_limit(robot, PlanTask(start, goal), solved[hi])
    return ShortestDuration(hi, lo, binding, hi, solves)


def _binding_limit(robot: Robot, task: PlanTask, solution: OptimalResult) -> str:
    """The speed or torque limit the feasible motion uses the most."""
    ev = evaluate_trajectory(robot, solution.trajectory, task)
    torque = np.abs(ev.tau).max(axis=0) / np.asarray(robot.tau_max)
    speed = np.abs(solution.trajectory.qd).max(axis=0) / np.asarray(robot.qd_max)
    j_tau, j_speed = int(np.argmax(torque)), int(np.argmax(speed))
    if torque[j_tau] >= speed[j_speed]:
        name, limit = robot.joint_names[j_tau], float(robot.tau_max[j_tau])
        return f"the torque limit of joint {name} ({limit:g} Nm)"
    name, limit = robot.joint_names[j_speed], float(robot.qd_max[j_speed])
    return f"the speed limit of joint {name} ({limit:g} rad/s)"


def _static_overload(robot: Robot, start: FloatArray, goal: FloatArray) -> str:
    """Which joint cannot hold the load still somewhere on the straight joint path ("" if none).

    Slowing down cannot lower a static torque, so a path point whose gravity torque exceeds a
    limit explains why no duration was feasible (for this path; a detour may still avoid it).
    """
    s = np.linspace(0.0, 1.0, 101)[:, None]
    path = start + s * (goal - start)
    rest = np.zeros_like(path)
    ratio = np.abs(robot.dynamics().inverse_dynamics(path, rest, rest)) / np.asarray(robot.tau_max)
    k, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    if ratio[k, j] <= 1.0:
        return ""
    tau = ratio[k, j] * robot.tau_max[j]
    return (
        f"holding still {s[k, 0]:.0%} of the way along the straight joint path needs "
        f"{tau:.1f} Nm at joint {robot.joint_names[j]}, above its {robot.tau_max[j]:g} Nm limit"
    )


#: A verified duration is rounded up to this step [s] (the number the user types back).
_DURATION_STEP = 1e-3
#: The verified duration grows by this factor while the checked move still breaks a limit.
_GROWTH = 1.05
#: A rest-to-rest quintic's peak speed over its mean speed (15/8).
QUINTIC_PEAK_RATIO = 1.875


@dataclass(frozen=True)
class VerifiedDuration:
    """The shortest duration of a speed-limited task, and one that was checked to work.

    Attributes:
        lower: no rest-to-rest move is faster: the largest stroke over its speed limit [s].
        joint: the joint that sets ``lower`` (its name).
        speed_limit: that joint's speed limit [rad/s].
        duration: a duration [s] at which ``method``'s move was planned and evaluated within
            every joint's position, speed and torque limits (None: none up to the search's end).
        method: ``jerk_limited`` (ruckig's time-optimal move, within the acceleration and jerk
            limits too) or ``quintic`` (when ruckig cannot plan the robot).
    """

    lower: float
    joint: str
    speed_limit: float
    duration: float | None
    method: str

    def describe(self) -> str:
        """The part of the one-line error that says what is feasible."""
        bound = (
            f"no rest-to-rest move is faster than {self.lower:.3f} s (joint {self.joint}'s "
            f"stroke at its {self.speed_limit:.3g} rad/s limit)"
        )
        if self.duration is None:
            return (
                f"{bound}, and no {self.method} move up to {MAX_FACTOR:g} times that keeps "
                "every limit: expected a lighter payload or wider limits"
            )
        return (
            f"expected a duration of at least {self.duration:.3f} s (verified: the "
            f"{self.method} move of {self.duration:.3f} s keeps every joint's position, speed "
            f"and torque limits; {bound})"
        )


def shortest_verified_duration(
    robot: Robot, start: FloatArray, goal: FloatArray, *, max_factor: float = MAX_FACTOR
) -> VerifiedDuration:
    """The shortest duration the speed limits allow, and one checked by planning at it.

    ``lower`` (stroke over speed limit) is only necessary; the returned ``duration`` is
    ruckig's time-optimal jerk-limited move (the ``jerk_limited`` method, which then succeeds at
    it), rounded up to 1 ms and lengthened by 5 % steps until Pinocchio's evaluation of the move
    breaks no limit. Without finite acceleration and jerk limits it is the quintic's (peak speed
    15/8 of the mean), checked the same way.
    """
    from app.planning.jerk_limited import JerkLimitedError, _calculate, jerk_limited
    from app.planning.profiles import quintic

    start, goal = np.asarray(start, float), np.asarray(goal, float)
    times = np.abs(goal - start) / np.asarray(robot.qd_max, float)
    j = int(np.argmax(times))
    lower = float(times[j])
    task = PlanTask(start, goal)
    try:
        first = float(_calculate(robot, start, goal, None).duration)  # type: ignore[attr-defined]
        method = "jerk_limited"
    except JerkLimitedError:
        first, method = QUINTIC_PEAK_RATIO * lower, "quintic"
    duration = math.ceil(max(first, lower) / _DURATION_STEP) * _DURATION_STEP
    while duration <= max_factor * max(lower, _DURATION_STEP):
        if method == "jerk_limited":
            traj = jerk_limited(robot, start, goal, duration, n_samples=501)
        else:
            traj = quintic(start, goal, duration, n_samples=501)
        if not evaluate_trajectory(robot, traj, task).violations:
            return VerifiedDuration(
                lower, robot.joint_names[j], float(robot.qd_max[j]), duration, method
            )
        duration = math.ceil(duration * _GROWTH / _DURATION_STEP) * _DURATION_STEP
    return VerifiedDuration(lower, robot.joint_names[j], float(robot.qd_max[j]), None, method)


def rest_overload(robot: Robot, start: FloatArray, goal: FloatArray) -> str:
    """Why no duration helps, or "": a joint cannot hold the robot and payload still at the
    start or the goal, where every motion begins and ends at rest.

    The static torque there is the gravity torque g(q), which no duration changes. It is affine
    in the payload's mass, g0 + m s (s from a second evaluation with 1 kg more), so the message
    also names the heaviest payload every joint holds at both ends.
    """
    rest = np.stack([np.asarray(start, float), np.asarray(goal, float)])
    zero = np.zeros_like(rest)
    limit = np.asarray(robot.tau_max, float)
    g = robot.dynamics().inverse_dynamics(rest, zero, zero)
    ratio = np.abs(g) / limit
    k, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    if ratio[k, j] <= 1.0:
        return ""
    mass = float(robot.payload.mass)
    heavier = robot.with_payload(mass + 1.0).dynamics().inverse_dynamics(rest, zero, zero)
    slope = heavier - g
    g0 = g - mass * slope  # without the payload
    where = ("start", "goal")[k]
    head = (
        f"infeasible: holding the {mass:g} kg payload still at the {where} needs "
        f"{abs(g[k, j]):.1f} Nm at joint {robot.joint_names[j]}, above its {limit[j]:g} Nm "
        "limit: no duration helps (every motion starts and ends at rest there)"
    )
    if np.any(np.abs(g0) > limit * (1.0 + 1e-9)):
        return head + ": expected stronger joints (the arm cannot hold itself still there)"
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(
            slope > 0, (limit - g0) / slope, np.where(slope < 0, (limit + g0) / -slope, np.inf)
        )
    heaviest = float(np.min(room))
    return head + f": expected a payload of at most {heaviest:.3g} kg or stronger joints"
