"""The options of ``plan`` (and the part ``simulate_comparison`` shares), defined once.

Each field holds the option's default, range or choices, unit and help; ``bioplan plan``
builds its flags from them, ``POST /api/plans`` its request fields, and a plan job's payload is
``PlanOptions.to_dict()`` (read back with ``PlanOptions.from_dict(payload, ignore_unknown=True)``).
Importing this module is cheap (no NumPy, CasADi or Pinocchio): ``bioplan --help`` reads it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from app.names import (
    DEFAULT_OBJECTIVE,
    HUMAN_CONSTRAINTS,
    MAX_DURATION,
    METHODS,
    OBJECTIVES,
    OPTIMAL_INTERVALS,
    PSO_DEFAULTS,
    STANDARD_METHODS,
)
from app.options import Options, option

__all__ = ["LIBRARY_METHODS", "MethodOptions", "PlanOptions", "methods_option"]

#: What the library plans when not told (``planning.methods.DEFAULT_METHODS``): the quick pair.
#: The CLI and the API plan every standard method (the field's ``interface_default``).
LIBRARY_METHODS: tuple[str, ...] = ("quintic", "paper")
#: Largest PSO seed (NumPy's ``SeedSequence`` takes any, JSON clients 32 bits).
MAX_SEED = 2**32 - 1


def methods_option(help: str) -> Any:
    """A ``methods`` field: some of :data:`app.names.METHODS` (``--method`` on the CLI); the
    library's default :data:`LIBRARY_METHODS`, the CLI's and the API's every standard method.

    Args:
        help: the field's help line.
    """
    return option(
        LIBRARY_METHODS,
        help=help,
        choices=tuple(METHODS),
        min_items=1,
        max_items=len(METHODS),
        interface_default=STANDARD_METHODS,
        flag="--method",
    )


@dataclass(frozen=True)
class MethodOptions(Options):
    """The options ``plan`` and ``simulate_comparison`` share: the task's timing, the objective,
    the paper's PSO budget and the methods with their optimal-control settings.

    Attributes:
        duration: motion time [s], the same for every method.
        objective: the metric the paper's PSO and the optimal control minimise.
        seed: PSO seed; the same inputs and seed give the same result bit for bit.
        particles: PSO swarm size.
        iterations: PSO iterations (at most; it stops early on stagnation).
        peak_angle_deg: the elbow's peak-velocity angle [deg]; None: the template's.
        methods: methods to plan (the quintic always: it is every saving's reference).
        human_constraint: ``human_optimal``'s constraint (``app.names.HUMAN_CONSTRAINTS``).
        no_reversal: the optimal-control methods never move a joint against its stroke.
        n_intervals: constant-jerk intervals of the optimal-control transcription.
        converge: refine every optimal-control result on meshes of 2N, 4N, ... intervals
            until its objective changes by less than 0.1 %.
    """

    duration: float = option(
        1.0, help="motion time, the same for every method", unit="s", gt=0, le=MAX_DURATION,
        cli=False,  # the CLI's --duration is the robot task's (add_robot_args), same range
    )  # fmt: skip
    objective: str = option(
        DEFAULT_OBJECTIVE,
        help="the metric the paper's PSO and the optimal control minimise",
        choices=OBJECTIVES,
    )
    seed: int = option(
        PSO_DEFAULTS.seed,
        help="PSO seed (the same inputs and seed give the same result bit for bit)",
        ge=0,
        le=MAX_SEED,
    )
    particles: int = option(PSO_DEFAULTS.particles, help="PSO swarm size", ge=2, le=1000)
    iterations: int = option(
        PSO_DEFAULTS.iterations, help="PSO iterations (at most)", ge=1, le=10000
    )
    peak_angle_deg: float | None = option(
        None,
        help="elbow velocity-peak angle",
        unit="deg",
        none_means="the template's",
        gt=0,
        lt=180,
    )
    methods: tuple[str, ...] = methods_option(
        "methods to plan (the quintic always runs: it is every saving's reference)"
    )
    human_constraint: str = option(
        "peak",
        help="human_optimal's constraint: the elbow fastest at the template's angle (peak), the "
        "A/B/C phase shares within the template's spread (phases), the elbow's speed inside the "
        "recorded lifts' band (shape; a template from recorded lifts only), or none",
        choices=HUMAN_CONSTRAINTS,
    )
    no_reversal: bool = option(
        True,
        help="let the optimal-control methods move joints against their stroke (default: no "
        "joint reverses)",
        flag="--allow-reversal",
        negated=True,
    )
    n_intervals: int = option(
        OPTIMAL_INTERVALS,
        help="constant-jerk intervals of the optimal-control transcription",
        ge=8,
        le=400,
        flag="--intervals",
    )
    converge: bool = option(
        False,
        help="refine every optimal-control result on meshes of 2N, 4N, ... intervals until its "
        "objective changes by less than 0.1 % (the evidence in solver.convergence); off by "
        "default: it makes a peak-power plan about 5x slower (docs/planning.md)",
    )


@dataclass(frozen=True)
class PlanOptions(MethodOptions):
    """Every option of :func:`app.planning.planner.plan` (see :class:`MethodOptions`), and:

    Attributes:
        n_samples: time samples per trajectory inside the PSO.
        report_samples: time samples of the reported trajectories and metrics.
        safety: check every method's trajectory for collisions (False: "not checked").
    """

    n_samples: int = option(
        PSO_DEFAULTS.n_samples, help="optimiser grid points", ge=10, le=100000, cli=False
    )
    report_samples: int = option(
        1000,
        help="time samples of the reported trajectories and metrics",
        ge=10,
        le=100000,
        cli=False,  # library only: the service reports on its fixed grid
        api=False,
    )
    safety: bool = option(
        True,
        help="check every method's trajectory for collisions with the robot itself, the "
        "mounting plane and the sidecar's obstacles (False: reported 'not checked')",
        cli=False,  # library only: the CLI and the API always check
        api=False,
    )
