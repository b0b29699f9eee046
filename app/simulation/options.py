"""The options of ``simulate_comparison`` and ``run_sweep``, defined once.

``SimulationOptions`` is the planning options ``simulate`` shares with ``plan``
(:class:`~app.planning.options.MethodOptions`) and the simulation's own; ``SweepGrid`` is a
sweep's grid (durations x payloads x objectives) and the options every cell runs with. Each
field holds its default, range or choices, unit and help; ``bioplan simulate``/``sweep`` and the
API's requests are built from them, and a job payload is ``to_dict()``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import get_args

from app.names import (
    DEFAULT_OBJECTIVE,
    MAX_DURATION,
    OBJECTIVES,
    PSO_DEFAULTS,
    SWEEP_SEEDS,
)
from app.options import Options, option
from app.planning.options import MAX_SEED, MethodOptions, methods_option
from app.simulation.tracking import (
    DEFAULT_DAMPING_RATIO,
    DEFAULT_NATURAL_FREQUENCY_HZ,
    DEFAULT_TIMESTEP,
    MAX_TIMESTEP,
    Feedforward,
)

__all__ = ["SWEEP_ITERATIONS", "SWEEP_PARTICLES", "SimulationOptions", "SweepGrid"]

#: PSO budget per sweep cell (modest, so a 10 x 10 grid fits in a minute on two cores).
SWEEP_PARTICLES = 24
SWEEP_ITERATIONS = 40
#: Most values on one axis of a sweep's grid.
MAX_GRID_VALUES = 50


@dataclass(frozen=True)
class SimulationOptions(MethodOptions):
    """Every option of :func:`app.simulation.simulate_comparison`: the planning ones (see
    :class:`~app.planning.options.MethodOptions`) and:

    Attributes:
        timestep: MuJoCo time step [s]; every trajectory is planned on its grid.
        feedforward: the controller's feed-forward: ``pinocchio``, ``mujoco`` or ``none``.
        natural_frequency_hz: closed-loop natural frequency of the PD feedback [Hz].
        damping_ratio: damping ratio of the PD feedback [-].
    """

    timestep: float = option(
        DEFAULT_TIMESTEP,
        help="MuJoCo time step",
        unit="s",
        gt=0,
        le=MAX_TIMESTEP,
        flag="--timestep-ms",
        cli_scale=1000.0,
        cli_unit="ms",
        api=False,  # the API simulates at the default step
    )
    feedforward: str = option(
        "pinocchio",
        help="the controller's feed-forward torque",
        choices=get_args(Feedforward),
        cli=False,  # library only: the CLI and the API use Pinocchio's
        api=False,
    )
    natural_frequency_hz: float = option(
        DEFAULT_NATURAL_FREQUENCY_HZ,
        help="closed-loop natural frequency of the PD feedback",
        unit="Hz",
        gt=0,
        cli=False,
        api=False,
    )
    damping_ratio: float = option(
        DEFAULT_DAMPING_RATIO,
        help="damping ratio of the PD feedback",
        gt=0,
        cli=False,
        api=False,
    )


@dataclass(frozen=True)
class SweepGrid(Options):
    """A sweep's grid and the options every cell runs with (:func:`app.simulation.run_sweep`).

    Attributes:
        durations: motion times [s].
        payloads: payload masses [kg].
        objectives: the planners' objectives.
        seed: PSO seed of every cell.
        particles, iterations: PSO budget per cell (modest; stated in the output).
        methods: methods per cell (the quintic always).
        check_seed: first check seed of the paper's PSO (-1: ``seed + 1``).
        no_check: skip the convergence check (one seed per cell).
        seeds: seeds the paper's PSO runs with per cell; a verdict is certain only when all
            agree.
        converge: refine every optimal-control result until its objective changes by less
            than 0.1 %.
        timestep: simulation step [s].
    """

    durations: tuple[float, ...] = option(
        (0.5, 0.75, 1.0, 1.5, 2.0),
        help="motion times",
        unit="s",
        gt=0,
        le=MAX_DURATION,
        min_items=1,
        max_items=MAX_GRID_VALUES,
    )
    payloads: tuple[float, ...] = option(
        (0.0, 4.0, 8.0, 12.0, 20.0),
        help="payload masses",
        unit="kg",
        ge=0,
        le=10000,
        min_items=1,
        max_items=MAX_GRID_VALUES,
    )
    objectives: tuple[str, ...] = option(
        (DEFAULT_OBJECTIVE,),
        help="planner objectives",
        choices=OBJECTIVES,
        min_items=1,
        max_items=len(OBJECTIVES),
    )
    seed: int = option(PSO_DEFAULTS.seed, help="PSO seed of every cell", ge=0, le=MAX_SEED)
    particles: int = option(SWEEP_PARTICLES, help="PSO swarm per cell", ge=2, le=1000)
    iterations: int = option(SWEEP_ITERATIONS, help="PSO iterations per cell", ge=1, le=10000)
    methods: tuple[str, ...] = methods_option("methods per cell")
    check_seed: int = option(
        -1,
        help="first check seed of the paper's PSO (-1: seed + 1; the others follow it)",
        ge=-1,
        le=MAX_SEED,
    )
    no_check: bool = option(False, help="skip the convergence check (one seed)")
    seeds: int = option(
        SWEEP_SEEDS,
        help="seeds the paper's PSO runs with per cell (the cell's seed and the check seeds); a "
        "verdict is certain only when all agree, otherwise marked '?' with its spread",
        ge=1,
        le=20,
    )
    converge: bool = option(
        False,
        help="refine every optimal-control result until its objective changes by less than "
        "0.1 % (several times slower; docs/planning.md)",
    )
    timestep: float = option(
        DEFAULT_TIMESTEP,
        help="simulation time step",
        unit="s",
        gt=0,
        le=MAX_TIMESTEP,
        cli=False,  # library only, as before
        api=False,
    )
