"""MuJoCo validation of planned trajectories: tracking, comparison, sweep and the demo report.

A plain library (numpy, mujoco, and the planning package); the service layer wraps it.
"""

from app.simulation.tracking import (
    DEFAULT_TIMESTEP,
    SimulationError,
    TrackingResult,
    default_gains,
    resample,
    simulate_batch,
    simulate_tracking,
    simulation_grid,
)

__all__ = [
    "DEFAULT_TIMESTEP",
    "SimulationError",
    "TrackingResult",
    "default_gains",
    "resample",
    "simulate_batch",
    "simulate_tracking",
    "simulation_grid",
]
