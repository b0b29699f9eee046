"""MuJoCo validation of planned trajectories: tracking, comparison, sweep and the demo report.

A plain library (numpy, mujoco, and the planning package); the service layer wraps it.
"""

from app.simulation.comparison import (
    METRICS,
    SimulationResult,
    peaks_and_phases,
    simulate_comparison,
)
from app.simulation.sweep import SweepCell, SweepResult, classify, run_sweep
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
    "METRICS",
    "SimulationError",
    "SimulationResult",
    "SweepCell",
    "SweepResult",
    "TrackingResult",
    "classify",
    "default_gains",
    "peaks_and_phases",
    "resample",
    "run_sweep",
    "simulate_batch",
    "simulate_comparison",
    "simulate_tracking",
    "simulation_grid",
]
