"""Classical point-to-point profiles and the minimum-torque-change baseline on one task.

The minimum-torque-change trajectory (Uno, Kawato & Suzuki 1989), J = ∫ Σ τ̇² dt, is solved
with the optimal-control machinery (:mod:`app.planning.optimal`) under the joint position,
velocity and torque limits, with the quintic's boundary conditions; joints may reverse, as
free human movements do.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from app.planning.energy import Floors
from app.planning.evaluation import (
    EvaluatedTrajectory,
    PlanTask,
    check_floors,
    evaluate_trajectory,
    task_floors_of,
    validate_task,
)
from app.planning.optimal import HumanSpec, SolverInfo, solve_optimal
from app.planning.profiles import CLASSICAL_PROFILES
from app.planning.robots import Robot

#: Intervals of the minimum-torque-change solve: piecewise-constant jerk converges to the smooth
#: optimum from above (human arm, 1 s: 7804 at 40, 7728 at 60, 7685 at 100 N²m²/s).
MTC_INTERVALS = 100


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
    min_torque_change: SolverInfo | None = None

    def to_dict(self) -> dict[str, Any]:
        mtc = self.min_torque_change
        return {
            "min_torque_change_solver": None if mtc is None else mtc.to_dict(),
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
    mtc_intervals: int = MTC_INTERVALS,
) -> ProfilesComparison:
    """Evaluate trapezoidal, S-curve, triangular, cubic, quintic, minimum-jerk and
    minimum-torque-change trajectories with equal duration and boundary conditions.

    Args:
        robot: the robot with its payload.
        task: start and goal; defaults to the robot's curl task.
        duration: motion time [s].
        n_samples: time samples per trajectory.
        mtc_intervals: constant-jerk intervals of the minimum-torque-change solve.
        include_min_torque_change: also solve the Uno-Kawato-Suzuki baseline (IPOPT, within
            the joint limits).
    """
    task = task or PlanTask.default(robot)
    validate_task(robot, task, duration)
    out: dict[str, EvaluatedTrajectory] = {}
    for name, make in CLASSICAL_PROFILES.items():
        traj = make(task.start, task.goal, duration, n_samples=n_samples)
        out[name] = evaluate_trajectory(robot, traj, task)
    solver = None
    if include_min_torque_change:
        mtc = solve_optimal(
            robot,
            task.start,
            task.goal,
            duration,
            objective="torque_change",
            human=HumanSpec("none", robot.elbow_joint),
            no_reversal=False,
            n_intervals=mtc_intervals,
            report_samples=n_samples,
            name="min_torque_change",
        )
        out["min_torque_change"] = evaluate_trajectory(robot, mtc.trajectory, task)
        solver = mtc.solver
    fl = task_floors_of(robot, task, duration)
    for name, ev in out.items():
        check_floors(ev, fl, name)
    return ProfilesComparison(
        robot=robot.name,
        duration=duration,
        payload_mass=float(robot.payload.mass),
        task=task,
        profiles=out,
        floors=fl,
        min_torque_change=solver,
    )
