"""The industrial baseline: a time-synchronised jerk-limited profile from ruckig.

What a robot controller runs for a point-to-point move: every joint starts and stops at rest
(zero velocity and acceleration, as the quintic), respects the joint's velocity, acceleration
and jerk limits (``Robot.qd_max``, ``qdd_max``, ``jerk_max``), and all joints arrive together.
ruckig's ``minimum_duration`` stretches the time-optimal profile to the task's duration.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from app.errors import BioPlanError
from app.planning.profiles import Trajectory, time_grid

if TYPE_CHECKING:
    from app.planning.robots import Robot

__all__ = ["JerkLimitedError", "jerk_limited"]

FloatArray = NDArray[np.float64]


class JerkLimitedError(BioPlanError):
    """The jerk-limited profile cannot reach the goal in the requested duration."""


def _calculate(robot: Robot, start: FloatArray, goal: FloatArray, duration: float | None) -> object:
    import ruckig

    n = start.size
    for what, limits in (("speed", robot.qd_max), ("acceleration", robot.qdd_max),
                         ("jerk", robot.jerk_max)):  # fmt: skip
        unbounded = np.flatnonzero(~np.isfinite(np.asarray(limits, float)))
        if unbounded.size:
            joint = robot.joint_names[int(unbounded[0])]
            raise JerkLimitedError(
                f"jerk_limited needs a finite {what} limit for every joint; {joint} has none "
                "(expected limits in the URDF or a sidecar, docs/robots.md, or --method without "
                "jerk_limited)"
            )
    inp = ruckig.InputParameter(n)
    inp.current_position = start.tolist()
    inp.current_velocity = [0.0] * n
    inp.current_acceleration = [0.0] * n
    inp.target_position = goal.tolist()
    inp.target_velocity = [0.0] * n
    inp.target_acceleration = [0.0] * n
    inp.max_velocity = np.asarray(robot.qd_max, float).tolist()
    inp.max_acceleration = np.asarray(robot.qdd_max, float).tolist()
    inp.max_jerk = np.asarray(robot.jerk_max, float).tolist()
    if duration is not None:
        inp.minimum_duration = float(duration)
    trajectory = ruckig.Trajectory(n)
    try:
        result = ruckig.Ruckig(n).calculate(inp, trajectory)
    except (ValueError, RuntimeError) as exc:
        # ruckig's Python enum lacks some of its C++ results (-101 comes back as "-101 is not a
        # valid Result"), and invalid input raises: both are a refusal, never a bug here.
        raise JerkLimitedError(_refusal(robot, _result_code(exc), duration)) from None
    if result not in (ruckig.Result.Working, ruckig.Result.Finished):
        raise JerkLimitedError(_refusal(robot, int(result), duration))
    return trajectory


#: ruckig's error results (ruckig/result.hpp), by code.
_RUCKIG_ERRORS = {
    -1: "an unclassified error",
    -100: "invalid input",
    -101: "a duration beyond its numerical limits",
    -102: "positions outside the position limits",
    -104: "a zero limit",
    -110: "a failed execution-time calculation",
    -111: "a failed synchronisation",
}


def _result_code(exc: Exception) -> int | None:
    match = re.match(r"\s*(-?\d+) is not a valid", str(exc))
    return int(match.group(1)) if match else None


def _refusal(robot: Robot, code: int | None, duration: float | None) -> str:
    what = _RUCKIG_ERRORS.get(code, f"result {code}") if code is not None else "invalid input"
    if code == -101 and duration is not None:
        return (
            f"ruckig cannot plan {robot.name}'s move in {duration:g} s ({what}): expected a "
            "shorter duration (seconds to minutes)"
        )
    return (
        f"ruckig cannot plan {robot.name}'s move ({what}): expected start and goal within the "
        "limits and positive velocity, acceleration and jerk limits"
    )


def jerk_limited(
    robot: Robot, start: FloatArray, goal: FloatArray, duration: float, *, n_samples: int = 1000
) -> Trajectory:
    """The time-synchronised jerk-limited rest-to-rest move of the given duration.

    Args:
        robot: the robot (its velocity, acceleration and jerk limits).
        start, goal: (n,) configurations [rad].
        duration: motion time [s].
        n_samples: samples of the returned trajectory.

    Returns:
        The trajectory (named ``"jerk_limited"``); its jerk is the profile's piecewise-constant
        jerk, sampled.

    Raises:
        JerkLimitedError: even the time-optimal profile is slower than ``duration`` (the message
            names the smallest feasible duration) or ruckig refuses the input.
    """
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    profile = _calculate(robot, start, goal, duration)
    total = float(profile.duration)  # type: ignore[attr-defined]
    if total > duration * (1.0 + 1e-9):
        raise JerkLimitedError(
            f"infeasible: the jerk-limited profile of {robot.name} needs at least {total:.3f} s "
            f"with its velocity, acceleration and jerk limits (expected a duration >= "
            f"{total:.3f} s, got {duration:g} s)"
        )
    t = time_grid(duration, n_samples)
    states = [profile.at_time(float(ti)) for ti in t]  # type: ignore[attr-defined]
    q = np.array([s[0] for s in states], dtype=np.float64)
    qd = np.array([s[1] for s in states], dtype=np.float64)
    qdd = np.array([s[2] for s in states], dtype=np.float64)
    # Exactly rest at both ends (ruckig's end state is exact up to round-off).
    q[0], q[-1] = start, goal
    qd[0] = qd[-1] = qdd[0] = qdd[-1] = 0.0
    jerk = np.gradient(qdd, t, axis=0)
    return Trajectory(t=t, q=q, qd=qd, qdd=qdd, jerk=jerk, name="jerk_limited")
