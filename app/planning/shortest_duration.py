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

The same search (:func:`bracket_shortest`) finds the paper's method's own shortest duration
(:func:`shortest_paper_duration`) with the paper's PSO as the test: its family scales exactly
with the duration, so the same argument holds for the family (the PSO may still miss a feasible
member: the duration reported is one at which it found one), and each duration tried is a whole
millisecond, so the one reported is the one solved.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from app.planning.evaluation import PlanTask, evaluate_trajectory
from app.planning.optimal import FloatArray, HumanSpec, OptimalResult, SolverError, solve_optimal
from app.planning.paper import PlanProblem
from app.planning.profiles import Trajectory, piecewise_quintic, stretched
from app.planning.pso import PSOResult
from app.planning.robots import Robot

__all__ = [
    "Bracket",
    "PaperDuration",
    "ShortestDuration",
    "VerifiedDuration",
    "binding_limit",
    "bracket_shortest",
    "feasibility_probe",
    "paper_breach",
    "paper_trajectory",
    "probe_warm_name",
    "rest_overload",
    "shortest_feasible_duration",
    "shortest_paper_duration",
    "shortest_verified_duration",
]

#: Relative width of the final bracket [lo, hi]: hi is reported, a solved duration.
REL_TOL = 0.01
#: The search gives up beyond this multiple of the asked duration.
MAX_FACTOR = 16.0
#: IPOPT iterations a feasibility probe may take. Feasible probes converge in 20-35 (cold) on
#: the built-in robots; proving a near-boundary duration infeasible took 100-120 iterations and
#: up to 30 s (IPOPT's restoration phase on an ill-conditioned system), most of a failed plan's
#: time. A capped probe counts as "none found": the search then reports from above, still a
#: duration it solved.
PROBE_ITERATIONS = 60


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
            f"expected a duration of at least {self.duration:.3f} s (the shortest solved; none "
            f"found at {self.infeasible_below:.3f} s; {self.binding} binds)"
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

    def solve(duration: float, warm: Trajectory | None) -> OptimalResult:
        return solve_optimal(
            robot, start, goal, duration, objective="tau_sq", human=human,
            n_intervals=n_intervals, no_reversal=no_reversal, report_samples=501,
            explain=False, warm_start=warm, warm_start_name=probe_warm_name(warm),
            max_iterations=PROBE_ITERATIONS,
        )  # fmt: skip

    feasible, solved = feasibility_probe(solve)
    found = bracket_shortest(feasible, infeasible, rel_tol=rel_tol, max_factor=max_factor)
    if found.feasible is None:
        why = _static_overload(robot, start, goal)
        return ShortestDuration(None, found.infeasible, why, found.searched, found.solves)
    binding = binding_limit(robot, PlanTask(start, goal), solved[found.feasible].trajectory)
    return ShortestDuration(found.feasible, found.infeasible, binding, found.feasible, found.solves)


def probe_warm_name(warm: Trajectory | None) -> str:
    """What a probe's warm start is, for its solver report."""
    return "quintic" if warm is None else "longer probe"


def feasibility_probe(
    solve: Callable[[float, Trajectory | None], OptimalResult],
) -> tuple[Callable[[float], bool], dict[float, OptimalResult]]:
    """A feasibility test for a duration search, and the motions it solved (duration [s] ->
    result).

    ``solve(duration, warm)`` solves the probe problem (best with ``max_iterations =``
    :data:`PROBE_ITERATIONS`); a :class:`SolverError` means "none found". Each probe starts from
    the nearest longer solved motion sped up to its duration (the same path: at most a little
    over the limits when the two durations are close, which is where bisection probes), which
    IPOPT refines in fewer iterations than the quintic.
    """
    solved: dict[float, OptimalResult] = {}

    def feasible(duration: float) -> bool:
        longer = [d for d in solved if d > duration]
        warm = stretched(solved[min(longer)].trajectory, duration) if longer else None
        try:
            solved[duration] = solve(duration, warm)
        except SolverError:
            return False
        return True

    return feasible, solved


@dataclass(frozen=True)
class Bracket:
    """Where :func:`bracket_shortest` left the shortest feasible duration.

    Attributes:
        feasible: the shortest duration found feasible [s] (it was solved; None: none up to
            ``searched``).
        infeasible: the longest duration found infeasible [s].
        searched: the longest duration tried [s].
        solves: calls of the feasibility test.
    """

    feasible: float | None
    infeasible: float
    searched: float
    solves: int


def bracket_shortest(
    feasible: Callable[[float], bool],
    infeasible: float,
    *,
    rel_tol: float = REL_TOL,
    max_factor: float = MAX_FACTOR,
    step: float | None = None,
) -> Bracket:
    """The shortest duration ``feasible`` accepts: doubling from ``infeasible`` until one is
    accepted (at most ``max_factor`` times it), then geometric bisection until the bracket is
    narrower than ``rel_tol`` (relative).

    Args:
        feasible: solves the request at a duration [s] and says whether it succeeded.
        infeasible: a duration [s] already found infeasible.
        rel_tol: relative width of the final bracket.
        max_factor: give up beyond ``max_factor * infeasible``.
        step: when given, every duration tried is rounded up to a multiple of it [s] (e.g.
            1e-3), so the reported duration is exactly the one solved and typed back; the
            bisection also stops when the bracket is one step wide.
    """
    per_second = None if step is None else round(1.0 / step)

    def tried(duration: float) -> float:
        if per_second is None:
            return duration
        # an integer over an integer is the double nearest the decimal the user types
        return math.ceil(duration * per_second - 1e-9) / per_second

    solves = 0

    def accepts(duration: float) -> bool:
        nonlocal solves
        solves += 1
        return feasible(duration)

    lo, hi = float(infeasible), tried(2.0 * float(infeasible))
    while not accepts(hi):
        lo, hi = hi, tried(2.0 * hi)
        if hi > max_factor * infeasible:
            return Bracket(None, lo, lo, solves)
    while hi > lo * (1.0 + rel_tol):
        mid = tried(math.sqrt(lo * hi))
        if not lo < mid < hi:
            break  # one step wide
        if accepts(mid):
            hi = mid
        else:
            lo = mid
    return Bracket(hi, lo, hi, solves)


def binding_limit(robot: Robot, task: PlanTask, trajectory: Trajectory) -> str:
    """The speed or torque limit a feasible motion uses the most, e.g. "the speed limit of
    joint elbow (3.15 rad/s)"."""
    ev = evaluate_trajectory(robot, trajectory, task)
    torque = np.abs(ev.tau).max(axis=0) / np.asarray(robot.tau_max)
    speed = np.abs(trajectory.qd).max(axis=0) / np.asarray(robot.qd_max)
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


@dataclass(frozen=True)
class PaperDuration:
    """Why the paper's method failed, and the shortest duration at which it does not.

    The paper's family scales exactly with the duration (the via time is a share of it and the
    via speeds multiples of the mean speeds), so a longer duration only slows the same shapes
    down: speeds scale by s = T / T' and torques become s² τ + (1 - s²) g(q), while the
    position, peak and no-reversal constraints do not change. The search is
    :func:`bracket_shortest` with the paper's PSO (same seed and budget) as the test.

    Attributes:
        breach: what the best trajectory breaks at the asked duration, e.g. "joint elbow's
            speed limit (3.15 rad/s): 3.4 rad/s at 0.41 s".
        duration: the shortest duration [s] (a multiple of 1 ms) at which the paper's PSO found
            a trajectory within every limit on the report grid (None: none up to ``searched``).
        infeasible_below: the longest duration found infeasible [s].
        binding: the limit the verified trajectory uses the most ("" when none was found).
        searched: the longest duration tried [s].
        last_breach: what the best trajectory still breaks at ``searched`` (when none was
            found).
        solves: PSO runs spent by the search.
    """

    breach: str
    duration: float | None
    infeasible_below: float
    binding: str
    searched: float
    last_breach: str
    solves: int

    def describe(self) -> str:
        """The part of the one-line error that says what is feasible."""
        if self.duration is None:
            return (
                f"no duration helps: none up to {self.searched:.3g} s is feasible for the "
                f"paper's family (a longer one only slows the same shapes down; at "
                f"{self.searched:.3g} s the best still breaks {self.last_breach}): expected "
                "another peak angle, a lighter payload or wider limits"
            )
        return (
            f"expected a duration of at least {self.duration:.3f} s (verified: the paper's PSO "
            f"with the same seed and budget finds a trajectory within every limit at "
            f"{self.duration:.3f} s, {self.infeasible_below:.3f} s is not; {self.binding} "
            "binds there)"
        )


def paper_trajectory(problem: PlanProblem, x: FloatArray, n_samples: int) -> Trajectory:
    """The paper's trajectory of the decision vector ``x`` (D,) on ``n_samples`` samples."""
    tk, qk, qdk, qddk = problem.design.knots(np.asarray(x, float)[None, :])
    return piecewise_quintic(
        tk[0], qk[0], qdk[0], qddk[0], n_samples=n_samples, name="bio_optimized"
    )


def paper_breach(robot: Robot, problem: PlanProblem, x: FloatArray) -> str:
    """What the paper's trajectory ``x`` breaks the most, on the PSO's own grid and with its
    normalisation (1 = 100 % over): a joint's speed, torque or position limit, the elbow's
    speed peak at the via point, or no reversal ("" when it breaks nothing)."""
    design = problem.design
    traj = paper_trajectory(problem, x, problem.t.size)
    q, qd = traj.q, traj.qd
    tau = robot.dynamics().inverse_dynamics(q, qd, traj.qdd)
    qd_max, tau_max = np.asarray(robot.qd_max, float), np.asarray(robot.tau_max, float)
    q_min, q_max = np.asarray(robot.q_min, float), np.asarray(robot.q_max, float)
    span = np.maximum(q_max - q_min, 1e-9)
    span = np.where(np.isfinite(span), span, 1.0)
    delta = design.goal - design.start
    direction = np.sign(delta)
    mean_speed = np.maximum(np.abs(delta) / design.duration, 1e-9)
    v_via = abs(float(design.knots(np.asarray(x, float)[None, :])[2][0, 1, design.elbow]))
    peak = np.zeros_like(qd)
    peak[:, design.elbow] = np.abs(qd[:, design.elbow]) / max(v_via, 1e-12) - 1.0
    with np.errstate(invalid="ignore"):
        terms = {
            "speed": np.abs(qd) / qd_max - 1.0,
            "torque": np.abs(tau) / tau_max - 1.0,
            "position": np.maximum((q_min - q) / span, (q - q_max) / span),
            "peak": peak,
            "reversal": np.where(direction != 0, -qd * direction / mean_speed, 0.0),
        }
    kind, worst = max(terms.items(), key=lambda item: float(np.nanmax(item[1])))
    if not float(np.nanmax(worst)) > 0.0:
        return ""
    k, j = np.unravel_index(int(np.nanargmax(worst)), worst.shape)
    name, at = robot.joint_names[j], f"{traj.t[k]:.2f} s"
    if kind == "speed":
        value = f"{abs(qd[k, j]):.3g} rad/s at {at}"
        return f"joint {name}'s speed limit ({qd_max[j]:.3g} rad/s): {value}"
    if kind == "torque":
        value = f"{abs(tau[k, j]):.3g} Nm at {at}"
        return f"joint {name}'s torque limit ({tau_max[j]:g} Nm): {value}"
    if kind == "position":
        return (
            f"joint {name}'s position limits [{math.degrees(q_min[j]):.1f}, "
            f"{math.degrees(q_max[j]):.1f}] deg: {math.degrees(q[k, j]):.1f} deg at {at}"
        )
    if kind == "peak":
        return (
            f"the elbow's ({name}) speed peak at the via point: {abs(qd[k, j]):.3g} rad/s at "
            f"{at}, above its via speed {v_via:.3g} rad/s"
        )
    return f"no reversal: joint {name} moves against its stroke at {at}"


def shortest_paper_duration(
    robot: Robot,
    task: PlanTask,
    asked: float,
    first: tuple[PlanProblem, PSOResult],
    swarm: Callable[[float], tuple[PlanProblem, PSOResult]],
    *,
    report_samples: int,
    rel_tol: float = REL_TOL,
    max_factor: float = MAX_FACTOR,
) -> PaperDuration:
    """Why the paper's method failed at ``asked`` and its shortest feasible duration.

    Args:
        robot: the robot with its payload.
        task: the task.
        asked: the duration [s] at which the paper's PSO found nothing feasible.
        first: that PSO's problem and result.
        swarm: runs the paper's PSO (same seed and budget) at a duration [s].
        report_samples: the report grid on which a found trajectory must keep every limit too.
        rel_tol, max_factor: as :func:`bracket_shortest` (durations in steps of 1 ms).
    """
    found: dict[float, Trajectory] = {}
    last: list[tuple[PlanProblem, PSOResult]] = [first]

    def feasible(duration: float) -> bool:
        problem, result = swarm(duration)
        if result.best_violation > 0:
            if duration > last[0][0].design.duration:
                last[0] = (problem, result)
            return False
        traj = paper_trajectory(problem, result.best_position, report_samples)
        if evaluate_trajectory(robot, traj, task).violations:
            return False
        found[duration] = traj
        return True

    bracket = bracket_shortest(
        feasible, asked, rel_tol=rel_tol, max_factor=max_factor, step=_DURATION_STEP
    )
    breach = paper_breach(robot, first[0], first[1].best_position)
    if bracket.feasible is None:
        problem, result = last[0]
        return PaperDuration(
            breach, None, bracket.infeasible, "", bracket.searched,
            paper_breach(robot, problem, result.best_position), bracket.solves,
        )  # fmt: skip
    binding = binding_limit(robot, task, found[bracket.feasible])
    return PaperDuration(
        breach, bracket.feasible, bracket.infeasible, binding, bracket.searched, "", bracket.solves
    )
