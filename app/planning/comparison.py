"""Classical point-to-point profiles and the minimum-torque-change baseline on one task."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from app.planning.energy import Floors, floors
from app.planning.min_torque_change import minimum_torque_change
from app.planning.planner import EvaluatedTrajectory, PlanTask, evaluate_trajectory, validate_task
from app.planning.profiles import CLASSICAL_PROFILES
from app.planning.robots import Robot


@dataclass(frozen=True)
class ProfilesComparison:
    """Every profile evaluated on the same robot, task and duration.

    Attributes:
        robot: robot name.
        duration: motion time [s].
        payload_mass: payload [kg].
        task: the task.
        profiles: name -> evaluated trajectory, classical profiles first, then
            ``min_torque_change``.
        floors: the physical floors of the task.
    """

    robot: str
    duration: float
    payload_mass: float
    task: PlanTask
    profiles: dict[str, EvaluatedTrajectory]
    floors: Floors

    def to_dict(self) -> dict[str, Any]:
        return {
            "robot": self.robot,
            "duration": self.duration,
            "payload": self.payload_mass,
            "start_deg": np.degrees(self.task.start).tolist(),
            "goal_deg": np.degrees(self.task.goal).tolist(),
            "profiles": {name: ev.to_dict() for name, ev in self.profiles.items()},
            "floors": self.floors.to_dict(),
        }


def compare_profiles(
    robot: Robot,
    *,
    task: PlanTask | None = None,
    duration: float = 1.0,
    n_samples: int = 1000,
    include_min_torque_change: bool = True,
) -> ProfilesComparison:
    """Evaluate trapezoidal, S-curve, triangular, cubic, quintic, minimum-jerk and
    minimum-torque-change trajectories with equal duration and boundary conditions.

    Args:
        robot: the robot with its payload.
        task: start and goal; defaults to the robot's curl task.
        duration: motion time [s].
        n_samples: time samples per trajectory.
        include_min_torque_change: also solve the Uno-Kawato-Suzuki baseline.
    """
    task = task or PlanTask.default(robot)
    validate_task(robot, task, duration)
    out: dict[str, EvaluatedTrajectory] = {}
    for name, make in CLASSICAL_PROFILES.items():
        traj = make(task.start, task.goal, duration, n_samples=n_samples)
        out[name] = evaluate_trajectory(robot, traj, task)
    if include_min_torque_change:
        mtc = minimum_torque_change(
            robot.dynamics(), task.start, task.goal, duration, n_samples=n_samples
        )
        out["min_torque_change"] = evaluate_trajectory(robot, mtc.trajectory, task)
    pe = robot.dynamics().potential_energy(np.stack([task.start, task.goal]))
    return ProfilesComparison(
        robot=robot.name,
        duration=duration,
        payload_mass=float(robot.payload.mass),
        task=task,
        profiles=out,
        floors=floors(float(pe[1] - pe[0]), duration),
    )
