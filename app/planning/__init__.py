"""Robot trajectory planning: dynamics, profiles, energy metrics, PSO and the bio-inspired planner.

Public API (imported lazily, so ``import app.planning`` stays cheap for the CLI)::

    from app.planning import load_robot, plan, HumanTemplate
    robot = load_robot("curtain_wall_6dof", payload=4.0)
    result = plan(robot, duration=1.0, objective="peak_power", seed=0, methods=ALL_METHODS)
    result.to_dict(); result.methods["bound"].trajectory
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from app.planning.comparison import ProfilesComparison, compare_profiles
    from app.planning.dynamics import Dynamics, PinocchioDynamics, PlanarArm2DOF
    from app.planning.energy import (
        OBJECTIVES,
        EnergyMetrics,
        Floors,
        MotorModel,
        energy_metrics,
        floors,
        improvement_pct,
        objective_values,
    )
    from app.planning.human_constraints import PhaseShares, phase_shares
    from app.planning.human_template import HumanTemplate
    from app.planning.jerk_limited import JerkLimitedError, jerk_limited
    from app.planning.methods import ALL_METHODS, DEFAULT_METHODS, MethodResult
    from app.planning.min_torque_change import MinTorqueChangeResult, minimum_torque_change
    from app.planning.optimal import OptimalResult, SolverError, SolverInfo, solve_optimal
    from app.planning.planner import PlanningError, PlanResult, PlanTask, plan
    from app.planning.profiles import CLASSICAL_PROFILES, Trajectory, piecewise_quintic, quintic
    from app.planning.pso import PSOResult, pso_minimize
    from app.planning.robots import BUILTIN_ROBOTS, Payload, Robot, RobotError, load_robot
    from app.planning.symbolic import SymbolicChain, symbolic_chain

_EXPORTS = {
    "compare_profiles": "comparison",
    "ProfilesComparison": "comparison",
    "Dynamics": "dynamics",
    "PinocchioDynamics": "dynamics",
    "PlanarArm2DOF": "dynamics",
    "OBJECTIVES": "energy",
    "EnergyMetrics": "energy",
    "Floors": "energy",
    "MotorModel": "energy",
    "energy_metrics": "energy",
    "floors": "energy",
    "improvement_pct": "energy",
    "objective_values": "energy",
    "HumanTemplate": "human_template",
    "PhaseShares": "human_constraints",
    "phase_shares": "human_constraints",
    "JerkLimitedError": "jerk_limited",
    "jerk_limited": "jerk_limited",
    "ALL_METHODS": "methods",
    "DEFAULT_METHODS": "methods",
    "MethodResult": "methods",
    "OptimalResult": "optimal",
    "SolverError": "optimal",
    "SolverInfo": "optimal",
    "solve_optimal": "optimal",
    "SymbolicChain": "symbolic",
    "symbolic_chain": "symbolic",
    "MinTorqueChangeResult": "min_torque_change",
    "minimum_torque_change": "min_torque_change",
    "PlanningError": "planner",
    "PlanResult": "planner",
    "PlanTask": "planner",
    "plan": "planner",
    "CLASSICAL_PROFILES": "profiles",
    "Trajectory": "profiles",
    "piecewise_quintic": "profiles",
    "quintic": "profiles",
    "PSOResult": "pso",
    "pso_minimize": "pso",
    "BUILTIN_ROBOTS": "robots",
    "Payload": "robots",
    "Robot": "robots",
    "RobotError": "robots",
    "load_robot": "robots",
}

__all__ = [
    "ALL_METHODS",
    "BUILTIN_ROBOTS",
    "CLASSICAL_PROFILES",
    "DEFAULT_METHODS",
    "OBJECTIVES",
    "Dynamics",
    "EnergyMetrics",
    "Floors",
    "HumanTemplate",
    "JerkLimitedError",
    "MethodResult",
    "MinTorqueChangeResult",
    "MotorModel",
    "OptimalResult",
    "PSOResult",
    "Payload",
    "PhaseShares",
    "PinocchioDynamics",
    "PlanResult",
    "PlanTask",
    "PlanarArm2DOF",
    "PlanningError",
    "ProfilesComparison",
    "Robot",
    "RobotError",
    "SolverError",
    "SolverInfo",
    "SymbolicChain",
    "Trajectory",
    "compare_profiles",
    "energy_metrics",
    "floors",
    "improvement_pct",
    "jerk_limited",
    "load_robot",
    "minimum_torque_change",
    "objective_values",
    "phase_shares",
    "piecewise_quintic",
    "plan",
    "pso_minimize",
    "quintic",
    "solve_optimal",
    "symbolic_chain",
]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'app.planning' has no attribute {name!r}")
    return getattr(importlib.import_module(f"app.planning.{module}"), name)
