"""Plan, then simulate: the standard vs the bio-inspired trajectory, one task or a whole grid.

:func:`simulate_comparison` plans a task (``app.planning.planner.plan``), simulates both
trajectories in MuJoCo with the same controller (:mod:`app.simulation.tracking`) and reports the
metrics *measured in the simulation*, the tracking error, the changes, the physical floors, the
planner's own metrics beside them (for the agreement check) and where the peaks of power and
torque fall relative to the human template's A/B/C phases.

:func:`run_sweep` does that for every cell of a grid of durations x payloads x objectives in a
process pool and classifies each cell per metric: the bio-inspired plan "saves", makes
"no difference" (|change| < 1 %) or "costs more"; cells where the standard quintic already sits
on the ``abs_work`` floor (within 1 % of the potential-energy rise) are marked, and infeasible
cells are reported as such.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app import names
from app.planning.energy import Floors, improvement_pct
from app.planning.jsonsafe import json_safe
from app.progress import ProgressFn, report, within
from app.simulation.tracking import (
    DEFAULT_DAMPING_RATIO,
    DEFAULT_NATURAL_FREQUENCY_HZ,
    DEFAULT_TIMESTEP,
    INTEGRATOR,
    POOR_TRACKING_RAD,
    Feedforward,
    SimulationError,
    TrackingResult,
    simulate_batch,
)

if TYPE_CHECKING:
    from app.planning.human_template import HumanTemplate
    from app.planning.planner import PlanResult, PlanTask
    from app.planning.robots import Robot

FloatArray = NDArray[np.float64]

#: Scalar metrics compared everywhere (``peak_torque`` = the largest joint peak torque [Nm]).
METRICS: tuple[str, ...] = names.OBJECTIVES
#: |change| below this is "no difference" [%].
NO_DIFFERENCE_PCT = 1.0
#: The standard trajectory is "on the floor" when abs_work <= (1 + this) * delta_potential.
AT_FLOOR_FRACTION = 0.01
#: Planned and simulated metrics should agree this well when tracking is good [%].
AGREEMENT_PCT = 2.0
#: Relative slack below the physical floors tolerated in simulated metrics [-].
FLOOR_SLACK = 0.005
#: PSO budget per sweep cell (modest, so a 10 x 10 grid fits in a minute on two cores).
SWEEP_PARTICLES = 24
SWEEP_ITERATIONS = 40


def _phase(flexion_deg: float, bounds_deg: tuple[float, float]) -> str:
    """Phase A/B/C of an elbow flexion [deg] given the A/B and B/C bounds [deg]."""
    if flexion_deg < bounds_deg[0]:
        return "A"
    if flexion_deg < bounds_deg[1]:
        return "B"
    return "C"


def _peak(t: FloatArray, flex: FloatArray, values: FloatArray, bounds: tuple[float, float]) -> Any:
    k = int(np.argmax(np.abs(values)))
    return {
        "value": float(values[k]),
        "time": float(t[k]),
        "elbow_deg": float(flex[k]),
        "phase": _phase(float(flex[k]), bounds),
    }


def peaks_and_phases(
    run: TrackingResult,
    *,
    task: PlanTask,
    elbow_joint: int,
    phase_bounds_deg: tuple[float, float],
    joint_names: Sequence[str],
) -> dict[str, Any]:
    """Where the peaks of power and of each joint's torque fall in time, elbow angle and phase.

    Args:
        run: a simulated run.
        task: the planned task (maps the elbow joint angle to human elbow flexion).
        elbow_joint: index of the robot's elbow joint.
        phase_bounds_deg: A/B and B/C bounds of the human template [deg].
        joint_names: (n,) names.

    Returns:
        ``{"power": peak, "electrical_power": peak, "torque": [peak per joint]}``, each peak
        ``{"value", "time" [s], "elbow_deg" [deg, human-equivalent flexion], "phase"}``
        (torque peaks also name their ``joint``).
    """
    from app.planning.planner import elbow_flexion_deg

    flex = elbow_flexion_deg(run.q[:, elbow_joint], task, elbow_joint)
    torque = []
    for j, name in enumerate(joint_names):
        p = _peak(run.t, flex, run.tau[:, j], phase_bounds_deg)
        p["joint"] = name
        torque.append(p)
    return {
        "power": _peak(run.t, flex, run.power, phase_bounds_deg),
        "electrical_power": _peak(run.t, flex, run.electrical_power, phase_bounds_deg),
        "torque": torque,
    }


def _scalar_metrics(m: dict[str, Any]) -> dict[str, float]:
    out = {k: float(m[k]) for k in METRICS if k != "peak_torque"}
    out["peak_torque"] = float(max(m["peak_torque"]))
    return out


def _pct_change(standard: float, optimized: float) -> float:
    """100 (standard - optimized) / standard; NaN when the standard is 0 (no basis)."""
    if standard == 0.0 or not (math.isfinite(standard) and math.isfinite(optimized)):
        return math.nan
    return 100.0 * (standard - optimized) / abs(standard)


def classify(change_pct: float) -> str:
    """``"saves"``, ``"no difference"`` (|change| < 1 %), ``"costs more"`` or ``"n/a"``."""
    if not math.isfinite(change_pct):
        return "n/a"
    if abs(change_pct) < NO_DIFFERENCE_PCT:
        return "no difference"
    return "saves" if change_pct > 0.0 else "costs more"


@dataclass(frozen=True)
class SimulationResult:
    """The planned and simulated comparison of the standard and the bio-inspired trajectory.

    ``to_dict()`` is the JSON of ``bioplan simulate --json``.

    Attributes:
        plan: the planner's result (its metrics are on the same time grid).
        standard, optimized: the simulated runs.
        floors: physical floors of the task.
        conditions: robot, payload, duration, objective, seed, controller, time step, ...
        warnings: planner and simulator warnings, and any planned/simulated disagreement.
    """

    plan: PlanResult
    standard: TrackingResult
    optimized: TrackingResult
    floors: Floors
    conditions: dict[str, Any]
    warnings: tuple[str, ...] = field(default=())

    @property
    def improvement_pct(self) -> dict[str, Any]:
        """100 (standard - optimised) / standard per metric, from the simulation."""
        return improvement_pct(self.standard.metrics, self.optimized.metrics)

    def peaks(self, label: str) -> dict[str, Any]:
        """Peaks of power and torque of ``"standard"`` or ``"optimized"`` with their phases."""
        run = self.optimized if label == "optimized" else self.standard
        return peaks_and_phases(
            run,
            task=self.plan.task,
            elbow_joint=self.plan.elbow_joint,
            phase_bounds_deg=self.plan.phase_bounds_deg,
            joint_names=self.conditions["joint_names"],
        )

    def agreement_pct(self) -> dict[str, dict[str, float]]:
        """100 (simulated - planned) / planned per scalar metric, for both trajectories."""
        out: dict[str, dict[str, float]] = {}
        for label, run, planned in (
            ("standard", self.standard, self.plan.standard),
            ("optimized", self.optimized, self.plan.optimized),
        ):
            sim = _scalar_metrics(run.metrics.to_dict())
            ref = _scalar_metrics(planned.metrics.to_dict())
            out[label] = {
                k: (100.0 * (sim[k] - ref[k]) / abs(ref[k]) if ref[k] != 0.0 else math.nan)
                for k in METRICS
            }
        return out

    def phase_times(self, label: str = "optimized") -> tuple[float, float]:
        """Times [s] at which the commanded elbow crosses the A/B and B/C bounds."""
        return self.plan.phase_times(label)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (NaN as None): metrics from the simulation, tracking, floors, changes, ..."""
        runs = (("standard", self.standard), ("optimized", self.optimized))
        sides: dict[str, Any] = {}
        for label, run in runs:
            d: dict[str, Any] = dict(run.metrics.to_dict())
            d["peaks"] = self.peaks(label)
            d["saturation"] = [float(v) for v in run.saturation]
            d["peak_velocity_angle_deg"] = getattr(self.plan, label).peak_velocity_angle_deg
            sides[label] = d
        out = {
            **sides,
            "tracking": {
                label: {
                    "rms": [float(v) for v in run.tracking_rms],
                    "max": [float(v) for v in run.tracking_max],
                }
                for label, run in runs
            },
            "floors": self.floors.to_dict(),
            "improvement_pct": self.improvement_pct,
            "planned": {
                "standard": self.plan.standard.metrics.to_dict(),
                "optimized": self.plan.optimized.metrics.to_dict(),
                "improvement_pct": self.plan.improvement_pct,
                "simulated_minus_planned_pct": self.agreement_pct(),
            },
            "conditions": dict(self.conditions),
            "warnings": list(self.warnings),
        }
        return dict(json_safe(out))

    def arrays(self) -> dict[str, FloatArray]:
        """Curves for plots: ``t`` and ``<standard|optimized>_<name>`` for every recorded array."""
        out: dict[str, FloatArray] = {"t": self.standard.t}
        for label, run in (("standard", self.standard), ("optimized", self.optimized)):
            for name, arr in run.arrays().items():
                if name != "t":
                    out[f"{label}_{name}"] = arr
        return out

    def summary(self) -> str:
        """A human-readable report of the comparison."""
        c = self.conditions
        std = _scalar_metrics(self.standard.metrics.to_dict())
        opt = _scalar_metrics(self.optimized.metrics.to_dict())
        pstd = _scalar_metrics(self.plan.standard.metrics.to_dict())
        popt = _scalar_metrics(self.plan.optimized.metrics.to_dict())
        units = {
            "tau_sq": "N²m²s",
            "abs_work": "J",
            "pos_work": "J",
            "electrical_energy": "J",
            "peak_power": "W",
            "peak_torque": "Nm",
        }
        lines = [
            f"robot {c['robot']}, payload {c['payload']:g} kg, duration {c['duration']:g} s, "
            f"objective {c['objective']}, seed {c['seed']}",
            f"MuJoCo {c['integrator']}, step {1000 * c['timestep']:g} ms, feed-forward "
            f"{c['feedforward']}, PD {c['natural_frequency_hz']:g} Hz / zeta "
            f"{c['damping_ratio']:g}, backend {c['backend']}",
            "",
            f"{'metric (simulated)':<24}{'standard':>12}{'optimized':>12}{'change':>10}"
            f"{'  (planned: standard, optimized)':>34}",
        ]
        for k in METRICS:
            if math.isnan(std[k]) and k == "electrical_energy":  # the robot has no motor model
                lines.append(f"{k + ' [' + units[k] + ']':<24}{'not modelled':>24}")
                continue
            change = _pct_change(std[k], opt[k])
            ch = f"{change:+.1f}%" if math.isfinite(change) else "-"
            lines.append(
                f"{k + ' [' + units[k] + ']':<24}{std[k]:>12.4g}{opt[k]:>12.4g}{ch:>10}"
                f"      ({pstd[k]:.4g}, {popt[k]:.4g})"
            )
        lines.append(
            f"floors: delta_potential = {self.floors.delta_potential:.4g} J, "
            f"min_peak_power = {self.floors.min_peak_power:.4g} W"
        )
        lines.append("change: positive = the bio-inspired plan saves")
        for label, run in (("standard", self.standard), ("optimized", self.optimized)):
            lines.append(
                f"tracking {label}: max error "
                + ", ".join(f"{math.degrees(v):.3f}" for v in run.tracking_max)
                + " deg per joint"
            )
        for label in ("standard", "optimized"):
            p = self.peaks(label)
            pw = p["power"]
            tq = max(p["torque"], key=lambda d: abs(d["value"]))
            lines.append(
                f"{label}: power peak {pw['value']:.4g} W at t={pw['time']:.3f} s, elbow "
                f"{pw['elbow_deg']:.1f} deg (phase {pw['phase']}); largest torque peak "
                f"{abs(tq['value']):.4g} Nm ({tq['joint']}) at elbow {tq['elbow_deg']:.1f} deg "
                f"(phase {tq['phase']})"
            )
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _check_mjcf(robot: Robot) -> None:
    """Fail fast, before planning, when the robot cannot be simulated."""
    if robot.mjcf_path is None:
        robot.mujoco_model()  # raises RobotError with the robot's own message


def simulate_comparison(
    robot: Robot,
    *,
    duration: float = 1.0,
    objective: str = "abs_work",
    seed: int = 0,
    task: PlanTask | None = None,
    template: HumanTemplate | None = None,
    particles: int = 40,
    iterations: int = 100,
    peak_angle_deg: float | None = None,
    timestep: float = DEFAULT_TIMESTEP,
    feedforward: Feedforward = "pinocchio",
    natural_frequency_hz: float = DEFAULT_NATURAL_FREQUENCY_HZ,
    damping_ratio: float = DEFAULT_DAMPING_RATIO,
    progress: ProgressFn | None = None,
) -> SimulationResult:
    """Plan a task, then simulate the standard and the bio-inspired trajectory in MuJoCo.

    Both trajectories are planned on the simulation grid (``k * timestep``), so planned and
    simulated metrics use the same samples; both are simulated in one rollout with the same
    controller.

    Args:
        robot: the robot with its payload (``load_robot(name, payload=kg)``); needs an MJCF.
        duration: motion time [s].
        objective: the metric the planner minimises.
        seed: PSO seed.
        task: start/goal; defaults to the robot's curl task.
        template: the human template (default: the paper's).
        particles: PSO swarm size.
        iterations: PSO iterations.
        peak_angle_deg: overrides the template's elbow peak-velocity angle [deg].
        timestep: simulation step [s].
        feedforward: ``"pinocchio"``, ``"mujoco"`` or ``"none"``.
        natural_frequency_hz: PD bandwidth [Hz].
        damping_ratio: PD damping ratio [-].
        progress: called with a ``Progress`` (stages ``pso`` then ``simulate``).

    Returns:
        The comparison.

    Raises:
        RobotError: the robot has no MJCF.
        PlanningError: the task cannot be planned.
        SimulationError: the simulation ran away or the input is bad.
    """
    from app.planning.planner import plan

    _check_mjcf(robot)
    if not (math.isfinite(duration) and duration > 0):
        raise SimulationError(f"duration must be a positive number of seconds, got {duration}")
    n_steps = duration / timestep
    on_grid = abs(n_steps - round(n_steps)) < 1e-9 * max(n_steps, 1.0)
    report_samples = round(n_steps) + 1 if on_grid else math.ceil(n_steps) + 1

    result = plan(
        robot,
        task=task,
        duration=duration,
        objective=objective,
        template=template,
        seed=seed,
        particles=particles,
        iterations=iterations,
        report_samples=max(report_samples, 10),
        peak_angle_deg=peak_angle_deg,
        progress=within(progress, 0.0, 0.85),
    )
    report(progress, "simulate", 0, 1, fraction=0.85, message="simulating in MuJoCo")
    standard, optimized = simulate_batch(
        robot,
        [result.standard.trajectory, result.optimized.trajectory],
        timestep=timestep,
        feedforward=feedforward,
        natural_frequency_hz=natural_frequency_hz,
        damping_ratio=damping_ratio,
    )
    conditions = {
        "robot": robot.name,
        "joint_names": list(robot.joint_names),
        "payload": float(robot.payload.mass),
        "payload_size": [float(v) for v in robot.payload.size],
        "duration": float(duration),
        "objective": objective,
        "seed": int(seed),
        "particles": int(particles),
        "iterations": int(iterations),
        "start_deg": np.degrees(result.task.start).tolist(),
        "goal_deg": np.degrees(result.task.goal).tolist(),
        "phase_bounds_deg": list(result.phase_bounds_deg),
        "elbow_joint": robot.joint_names[result.elbow_joint],
        "shoulder_joint": robot.joint_names[robot.shoulder_joint],
        "peak_velocity_angle_deg": result.optimized.peak_velocity_angle_deg,
        "target_peak_velocity_angle_deg": result.target_peak_angle_deg,
        "timestep": float(timestep),
        "integrator": INTEGRATOR,
        "feedforward": feedforward,
        "natural_frequency_hz": float(natural_frequency_hz),
        "damping_ratio": float(damping_ratio),
        "kp": [float(v) for v in standard.kp],
        "kd": [float(v) for v in standard.kd],
        "backend": standard.backend,
        "friction": "in the drive (electrical model), not in the MuJoCo joints",
    }
    warnings = [*result.warnings]
    for label, run in (("standard", standard), ("optimized", optimized)):
        warnings += [f"{label}: {w}" for w in run.warnings]
    out = SimulationResult(
        plan=result,
        standard=standard,
        optimized=optimized,
        floors=result.floors,
        conditions=conditions,
    )
    floor = float(result.floors.delta_potential)
    for label, run in (("standard", standard), ("optimized", optimized)):
        # A discrete simulation may dip below a continuous-time floor by its integration error
        # (~0.01 % at 1 ms); more than the stated slack means the simulation is not to be trusted.
        for k in ("abs_work", "pos_work"):
            value = float(getattr(run.metrics, k))
            if floor > 0 and value < floor * (1.0 - FLOOR_SLACK):
                warnings.append(
                    f"{label}: simulated {k} = {value:.4g} J is below the floor delta_potential "
                    f"= {floor:.4g} J by more than {100 * FLOOR_SLACK:g}%: the simulation is "
                    "not accurate enough (expected a smaller time step)"
                )
        if not run.tracking_ok:
            continue
        for k, v in out.agreement_pct()[label].items():
            if math.isfinite(v) and abs(v) > AGREEMENT_PCT:
                warnings.append(
                    f"{label}: simulated {k} differs from the planned value by {v:+.1f}% "
                    f"(> {AGREEMENT_PCT:g}%) although tracking is good"
                )
    report(progress, "simulate", 1, 1, message="simulation done")
    return dataclasses.replace(out, warnings=tuple(warnings))


# ----------------------------------------------------------------------------------------------
# Sweep
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SweepCell:
    """One grid cell: a task duration, a payload and an objective.

    Attributes:
        duration: motion time [s]; payload: [kg]; objective: the planner's objective.
        status: ``"ok"``, ``"infeasible"`` (the planner found no feasible trajectory),
            ``"unstable"`` (the simulation ran away) or ``"error"``.
        message: why, when the status is not ``"ok"``.
        change_pct: per metric of ``METRICS``, 100 (standard - optimised) / standard from the
            simulation (positive = saves).
        planned_change_pct: the same from the planner.
        standard, optimized: simulated scalar metrics.
        floors: the task's floors.
        at_floor: the standard's abs_work is within 1 % of delta_potential.
        tracking_max: largest tracking error of both runs [rad].
        warnings: warnings of the cell's plan and simulation.
        seconds: wall time of the cell [s].
    """

    duration: float
    payload: float
    objective: str
    status: str
    message: str = ""
    change_pct: dict[str, float] = field(default_factory=dict)
    planned_change_pct: dict[str, float] = field(default_factory=dict)
    standard: dict[str, float] = field(default_factory=dict)
    optimized: dict[str, float] = field(default_factory=dict)
    floors: dict[str, float] = field(default_factory=dict)
    at_floor: bool = False
    tracking_max: float = math.nan
    warnings: tuple[str, ...] = ()
    seconds: float = 0.0

    @property
    def classification(self) -> dict[str, str]:
        """Per metric: "saves", "no difference", "costs more" (or the status when not ok)."""
        if self.status != "ok":
            return {k: self.status for k in METRICS}
        return {k: classify(self.change_pct.get(k, math.nan)) for k in METRICS}

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["warnings"] = list(self.warnings)
        d["classification"] = self.classification
        return dict(json_safe(d))


@dataclass(frozen=True)
class SweepResult:
    """All cells of a sweep, with the conditions (PSO budget, controller, workers)."""

    robot: str
    durations: tuple[float, ...]
    payloads: tuple[float, ...]
    objectives: tuple[str, ...]
    cells: tuple[SweepCell, ...]
    conditions: dict[str, Any]

    def cell(self, duration: float, payload: float, objective: str) -> SweepCell:
        for c in self.cells:
            if c.duration == duration and c.payload == payload and c.objective == objective:
                return c
        raise KeyError((duration, payload, objective))

    def table(self, objective: str, metric: str) -> FloatArray:
        """(durations, payloads) simulated change of ``metric`` [%] (NaN where not ok)."""
        out = np.full((len(self.durations), len(self.payloads)), np.nan)
        for i, d in enumerate(self.durations):
            for j, p in enumerate(self.payloads):
                c = self.cell(d, p, objective)
                if c.status == "ok":
                    out[i, j] = c.change_pct.get(metric, math.nan)
        return out

    def counts(self, objective: str, metric: str) -> dict[str, int]:
        """How many cells save, make no difference, cost more, or are not ok."""
        out: dict[str, int] = {}
        for c in self.cells:
            if c.objective == objective:
                label = c.classification[metric]
                out[label] = out.get(label, 0) + 1
        return out

    def to_dict(self) -> dict[str, Any]:
        """Plain data (NaN as None): conditions, every cell, and per metric a table."""
        tables: dict[str, Any] = {}
        for o in self.objectives:
            tables[o] = {}
            for m in METRICS:
                grid = self.table(o, m)
                tables[o][m] = {
                    "change_pct": [[_none_if_nan(v) for v in row] for row in grid],
                    "classification": [
                        [self.cell(d, p, o).classification[m] for p in self.payloads]
                        for d in self.durations
                    ],
                    "counts": self.counts(o, m),
                }
        return {
            "robot": self.robot,
            "durations": list(self.durations),
            "payloads": list(self.payloads),
            "objectives": list(self.objectives),
            "metrics": list(METRICS),
            "conditions": dict(self.conditions),
            "tables": tables,
            "cells": [c.to_dict() for c in self.cells],
        }

    def summary(self, metrics: Sequence[str] | None = None) -> str:
        """Plain-text grids of the % change (rows: durations, columns: payloads)."""
        c = self.conditions
        lines = [
            f"sweep of {self.robot}: {len(self.durations)} durations x {len(self.payloads)} "
            f"payloads x {len(self.objectives)} objective(s), seed {c['seed']}, PSO "
            f"{c['particles']} particles x {c['iterations']} iterations per cell, MuJoCo step "
            f"{1000 * c['timestep']:g} ms, {c['workers']} worker(s), {c['seconds']:.1f} s",
            "cells: change in % of the standard (positive = the bio-inspired plan saves);",
            f"  '+' saves, '=' no difference (|change| < {NO_DIFFERENCE_PCT:g}%), '-' costs "
            "more, '*' standard already on the abs_work floor, '!' the cell has warnings (e.g. "
            "the standard quintic exceeds a limit), 'infeasible'/'unstable' as said",
        ]
        for o in self.objectives:
            for m in metrics or METRICS:
                lines.append("")
                lines.append(f"objective {o}, metric {m}:")
                corner = "T [s] / m [kg]"
                header = f"{corner:>16}" + "".join(f"{p:>14g}" for p in self.payloads)
                lines.append(header)
                for d in self.durations:
                    cells = []
                    for p in self.payloads:
                        cell = self.cell(d, p, o)
                        cells.append(f"{_cell_text(cell, m):>14}")
                    lines.append(f"{d:>16g}" + "".join(cells))
                counts = self.counts(o, m)
                lines.append("  " + ", ".join(f"{k}: {v}" for k, v in sorted(counts.items())))
        if c.get("pool_note"):
            lines.append(f"note: {c['pool_note']}")
        bad = [c for c in self.cells if c.status != "ok"]
        for cell in bad[:5]:
            lines.append(
                f"{cell.status}: T={cell.duration:g} s, m={cell.payload:g} kg, "
                f"{cell.objective}: {cell.message}"
            )
        if len(bad) > 5:
            lines.append(f"... and {len(bad) - 5} more cells not ok (see --json for each)")
        return "\n".join(lines)


def _none_if_nan(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _cell_text(cell: SweepCell, metric: str) -> str:
    if cell.status != "ok":
        return cell.status
    v = cell.change_pct.get(metric, math.nan)
    if not math.isfinite(v):
        return "n/a"
    mark = {"saves": "+", "no difference": "=", "costs more": "-"}[classify(v)]
    floor = "*" if cell.at_floor else ""
    warn = "!" if cell.warnings else ""
    return f"{v:+.1f}% {mark}{floor}{warn}"


# Worker state: the robot (without its caches) and robots per payload, built once per process.
_WORKER: dict[str, Any] = {}


def _init_worker(robot: Robot) -> None:
    _WORKER.clear()
    _WORKER["robot"] = robot
    _WORKER["by_payload"] = {}


def _robot_with(payload: float) -> Robot:
    cache: dict[float, Robot] = _WORKER["by_payload"]
    if payload not in cache:
        cache[payload] = _WORKER["robot"].with_payload(payload)
    return cache[payload]


def _run_cell(
    duration: float,
    payload: float,
    objective: str,
    seed: int,
    particles: int,
    iterations: int,
    timestep: float,
) -> SweepCell:
    """Plan and simulate one cell (in a worker process); never raises for bad cells."""
    from app.planning.planner import PlanningError

    started = time.perf_counter()

    def failed(status: str, exc: Exception) -> SweepCell:
        return SweepCell(
            duration=duration,
            payload=payload,
            objective=objective,
            status=status,
            message=str(exc),
            seconds=time.perf_counter() - started,
        )

    try:
        res = simulate_comparison(
            _robot_with(payload),
            duration=duration,
            objective=objective,
            seed=seed,
            particles=particles,
            iterations=iterations,
            timestep=timestep,
        )
    except PlanningError as exc:
        return failed("infeasible", exc)
    except SimulationError as exc:
        return failed("unstable", exc)
    std = _scalar_metrics(res.standard.metrics.to_dict())
    opt = _scalar_metrics(res.optimized.metrics.to_dict())
    pstd = _scalar_metrics(res.plan.standard.metrics.to_dict())
    popt = _scalar_metrics(res.plan.optimized.metrics.to_dict())
    dpe = res.floors.delta_potential
    return SweepCell(
        duration=duration,
        payload=payload,
        objective=objective,
        status="ok",
        change_pct={k: _pct_change(std[k], opt[k]) for k in METRICS},
        planned_change_pct={k: _pct_change(pstd[k], popt[k]) for k in METRICS},
        standard=std,
        optimized=opt,
        floors={k: float(v) for k, v in res.floors.to_dict().items()},
        at_floor=bool(dpe > 0 and std["abs_work"] <= (1.0 + AT_FLOOR_FRACTION) * dpe),
        tracking_max=float(max(res.standard.tracking_max.max(), res.optimized.tracking_max.max())),
        warnings=res.warnings,
        seconds=time.perf_counter() - started,
    )


def _cell_job(args: tuple[float, float, str, int, int, int, float]) -> SweepCell:
    return _run_cell(*args)


def run_sweep(
    *,
    robot: Robot,
    durations: Sequence[float],
    payloads: Sequence[float],
    objectives: Sequence[str] = ("abs_work",),
    seed: int = 0,
    particles: int = SWEEP_PARTICLES,
    iterations: int = SWEEP_ITERATIONS,
    timestep: float = DEFAULT_TIMESTEP,
    workers: int | None = None,
    progress: ProgressFn | None = None,
) -> SweepResult:
    """Plan and simulate every (duration, payload, objective) cell; classify the changes.

    Cells run in a process pool (``workers`` processes, default ``min(2, cpu_count)``; 1 runs
    them in this process). Workers are spawned (fresh interpreters), so a calling script needs
    the usual ``if __name__ == "__main__":`` guard; without it the pool breaks and the cells run
    in this process instead (said in ``conditions["pool_note"]``). Every cell uses the same
    seed, so the result does not depend on the order in which cells finish.

    Args:
        robot: the robot (its payload shape is kept; the mass is set per cell); needs an MJCF.
        durations: motion times [s], each > 0.
        payloads: payload masses [kg], each >= 0.
        objectives: planner objectives (``app.planning.energy.OBJECTIVES``).
        seed: PSO seed for every cell.
        particles: PSO swarm size per cell (modest by default; stated in the output).
        iterations: PSO iterations per cell.
        timestep: simulation step [s].
        workers: processes in the pool.
        progress: called with a ``Progress`` (stage ``sweep``: cells done) as cells finish.

    Returns:
        The sweep; ``to_dict()`` for JSON, ``summary()`` for text.

    Raises:
        RobotError: the robot has no MJCF.
        SimulationError: an empty grid, a bad duration or payload.
        PlanningError: an unknown objective.
    """
    from app.planning.energy import OBJECTIVES

    _check_mjcf(robot)
    durs = tuple(float(d) for d in durations)
    pays = tuple(float(p) for p in payloads)
    objs = tuple(objectives)
    if not durs or not pays or not objs:
        raise SimulationError("the sweep grid is empty: expected durations, payloads, objectives")
    if any(not (math.isfinite(d) and d > 0) for d in durs):
        raise SimulationError(f"durations must be positive seconds, got {list(durs)}")
    if any(not (math.isfinite(p) and p >= 0) for p in pays):
        raise SimulationError(f"payloads must be masses >= 0 kg, got {list(pays)}")
    unknown = [o for o in objs if o not in OBJECTIVES]
    if unknown:
        # The planner's own error for this (what ``plan`` raises for an unknown objective).
        from app.planning.planner import PlanningError

        raise PlanningError(
            f"unknown objective(s) {', '.join(unknown)}: expected some of {', '.join(OBJECTIVES)}"
        )
    if len(set(durs)) != len(durs) or len(set(pays)) != len(pays) or len(set(objs)) != len(objs):
        raise SimulationError("durations, payloads and objectives must not repeat")
    n_workers = min(2, os.cpu_count() or 1) if workers is None else int(workers)
    if n_workers < 1:
        raise SimulationError(f"workers must be >= 1, got {workers}")
    jobs = [
        (d, p, o, int(seed), int(particles), int(iterations), float(timestep))
        for o in objs
        for d in durs
        for p in pays
    ]
    started = time.perf_counter()
    # A copy without cached Pinocchio/MuJoCo objects, so it pickles to the workers.
    clean = dataclasses.replace(robot)
    results: list[SweepCell] = []

    def on_cell(cell: SweepCell) -> None:
        results.append(cell)
        report(
            progress,
            "sweep",
            len(results),
            len(jobs),
            message=f"cell {len(results)}/{len(jobs)}: T={cell.duration:g} s, "
            f"m={cell.payload:g} kg, {cell.objective}: {cell.status}",
        )

    report(progress, "sweep", 0, len(jobs), message=f"{len(jobs)} cells on {n_workers} worker(s)")

    def run_here(todo: Sequence[tuple[float, float, str, int, int, int, float]]) -> None:
        _init_worker(clean)
        try:
            for job in todo:
                on_cell(_cell_job(job))
        finally:
            _WORKER.clear()

    pool_note = ""
    if n_workers == 1 or len(jobs) == 1:
        run_here(jobs)
    else:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed
        from concurrent.futures.process import BrokenProcessPool

        # "spawn": fresh interpreters, safe even when the caller runs threads (the service).
        ctx = multiprocessing.get_context("spawn")
        try:
            with ProcessPoolExecutor(
                max_workers=min(n_workers, len(jobs)),
                mp_context=ctx,
                initializer=_init_worker,
                initargs=(clean,),
            ) as pool:
                futures = [pool.submit(_cell_job, job) for job in jobs]
                for fut in as_completed(futures):
                    on_cell(fut.result())
        except BrokenProcessPool as exc:
            # Spawned workers re-import the caller's __main__; a script without the
            # ``if __name__ == "__main__":`` guard (or code piped to stdin) cannot be
            # re-imported. Finish in this process rather than fail.
            finished = {(c.duration, c.payload, c.objective) for c in results}
            todo = [job for job in jobs if (job[0], job[1], job[2]) not in finished]
            pool_note = (
                f"the process pool failed ({exc}); {len(todo)} cells ran in this process "
                "(a script needs the `if __name__ == '__main__':` guard for worker processes)"
            )
            n_workers = 1
            run_here(todo)
    order = {(d, p, o): i for i, (d, p, o, *_rest) in enumerate(jobs)}
    cells = tuple(sorted(results, key=lambda c: order[(c.duration, c.payload, c.objective)]))
    return SweepResult(
        robot=robot.name,
        durations=durs,
        payloads=pays,
        objectives=objs,
        cells=cells,
        conditions={
            "seed": int(seed),
            "particles": int(particles),
            "iterations": int(iterations),
            "timestep": float(timestep),
            "integrator": INTEGRATOR,
            "workers": n_workers,
            "seconds": time.perf_counter() - started,
            "no_difference_pct": NO_DIFFERENCE_PCT,
            "at_floor_fraction": AT_FLOOR_FRACTION,
            "poor_tracking_rad": POOR_TRACKING_RAD,
            "payload_shape": [float(v) for v in robot.payload.size],
            "pool_note": pool_note,
        },
    )
