"""Sweeps: plan and simulate every cell of a grid of durations x payloads x objectives.

:func:`run_sweep` runs :func:`app.simulation.comparison.simulate_comparison` for every cell in a
process pool, with every requested method, and classifies each cell per metric: the paper's plan
"saves", makes "no difference" (|change| < 1 %) or "costs more" than the quintic (every other
method's change and its share of the achievable saving are reported beside it); cells where the
standard quintic already sits on the ``abs_work`` floor (within 1 % of |ΔPE|) are marked, and
infeasible cells are reported as such.

A verdict must not hang on the PSO's luck: each cell plans the paper's method with ``seeds``
seeds at the stated budget (the cell's seed, then ``check_seed``, ``check_seed + 1``, ...); a
metric's verdict is certain only when every seed gives the same one (:func:`certify_verdicts`),
otherwise it is marked uncertain (``unconverged``; shown as ``?``) with its spread, the min-max
of the planned change and of the paper's share of the achievable saving over the seeds. A cell
where the paper's family is infeasible still reports every other method (``method_status``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app import names
from app.jsonsafe import json_safe
from app.options import OptionsError
from app.planning.options import LIBRARY_METHODS
from app.progress import ProgressFn, report
from app.simulation.comparison import (
    METRICS,
    SimulationResult,
    _check_mjcf,
    pct_change,
    scalar_metrics,
    simulate_comparison,
)
from app.simulation.options import SweepGrid
from app.simulation.tracking import (
    INTEGRATOR,
    POOR_TRACKING_RAD,
    SimulationError,
)

if TYPE_CHECKING:
    from app.planning.robots import Robot

logger = logging.getLogger("bioplan.simulation")

__all__ = [
    "SweepCell",
    "SweepResult",
    "Verdict",
    "certify_verdicts",
    "classify",
    "run_sweep",
]

FloatArray = NDArray[np.float64]

#: |change| below this is "no difference" [%].
NO_DIFFERENCE_PCT = 1.0
#: The standard trajectory is "on the floor" when abs_work <= (1 + this) * delta_potential.
AT_FLOOR_FRACTION = 0.01
#: Seeds of the paper's PSO per cell (the cell's and the check seeds): a verdict is certain only
#: when all agree.
SWEEP_SEEDS = names.SWEEP_SEEDS
#: Uncertain verdicts listed in the text summary (all of them are in the JSON).
MAX_UNCERTAIN_LINES = 12


def classify(change_pct: float) -> str:
    """``"saves"``, ``"no difference"`` (|change| < 1 %), ``"costs more"`` or ``"n/a"``."""
    if not math.isfinite(change_pct):
        return "n/a"
    if abs(change_pct) < NO_DIFFERENCE_PCT:
        return "no difference"
    return "saves" if change_pct > 0.0 else "costs more"


@dataclass(frozen=True)
class Verdict:
    """One metric's verdict over the seeds of the paper's PSO.

    Attributes:
        verdict: the cell's verdict (its first seed's, :func:`classify`).
        certain: every seed gives the same verdict.
        by_seed: each seed's verdict, in seed order.
        low_pct, high_pct: the spread: min and max of the planned change over the seeds [%]
            (NaN when no seed has a finite change).
    """

    verdict: str
    certain: bool
    by_seed: tuple[str, ...]
    low_pct: float
    high_pct: float


def _spread(values: Sequence[float]) -> tuple[float, float]:
    finite = [v for v in values if math.isfinite(v)]
    return (min(finite), max(finite)) if finite else (math.nan, math.nan)


def certify_verdicts(changes_by_seed: Sequence[dict[str, float]]) -> dict[str, Verdict]:
    """Certify each metric's verdict over the PSO seeds of one cell.

    Args:
        changes_by_seed: per seed (the cell's first), the planned change per metric [%]
            (NaN where that seed found no plan).

    Returns:
        Per metric (every key of any seed): certain only when every seed's :func:`classify`
        agrees, a seed without a plan ("n/a") agreeing with no finite change.
    """
    if not changes_by_seed:
        raise ValueError("certify_verdicts needs at least one seed's changes")
    keys = list(dict.fromkeys(k for run in changes_by_seed for k in run))
    out: dict[str, Verdict] = {}
    for k in keys:
        values = [run.get(k, math.nan) for run in changes_by_seed]
        labels = tuple(classify(v) for v in values)
        low, high = _spread(values)
        out[k] = Verdict(labels[0], len(set(labels)) == 1, labels, low, high)
    return out


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
        methods_change_pct: per simulated method, its change against the quintic per metric.
        share_of_achievable_pct: per method, its share of the achievable saving of the
            objective, (quintic − method) / (quintic − bound), simulated [%].
        method_status: per requested method, ``ok`` or why it has no result (e.g. the
            jerk-limited move needs more time than the cell's duration).
        unconverged: metrics whose planned verdict is not the same for every seed of the
            paper's PSO (the verdict depends on the PSO's budget or luck).
        check_planned_change_pct: the first check seed's planned change per metric.
        seeds: the seeds the paper's PSO ran with (the cell's first).
        verdicts: per metric, the certified verdict over the seeds (:class:`Verdict`).
        paper_share_by_seed: per seed, the paper's planned share of the achievable saving of
            the objective [%] (NaN without a bound or a plan).
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
    methods_change_pct: dict[str, dict[str, float]] = field(default_factory=dict)
    share_of_achievable_pct: dict[str, float] = field(default_factory=dict)
    method_status: dict[str, str] = field(default_factory=dict)
    unconverged: tuple[str, ...] = ()
    check_planned_change_pct: dict[str, float] = field(default_factory=dict)
    seeds: tuple[int, ...] = ()
    verdicts: dict[str, Verdict] = field(default_factory=dict)
    paper_share_by_seed: tuple[float, ...] = ()

    @property
    def paper_infeasible(self) -> bool:
        """The paper's family had no plan within the limits (the other methods still ran)."""
        return self.method_status.get("paper", "ok") != "ok"

    @property
    def classification(self) -> dict[str, str]:
        """Per metric: "saves", "no difference", "costs more" (or the status when not ok;
        "infeasible" when only the paper's family is)."""
        if self.status != "ok":
            return {k: self.status for k in METRICS}
        if self.paper_infeasible:
            return {k: "infeasible" for k in METRICS}
        return {k: classify(self.change_pct.get(k, math.nan)) for k in METRICS}

    @property
    def paper_share_range_pct(self) -> tuple[float, float]:
        """Min and max of the paper's planned share over the seeds [%] (NaN: none)."""
        return _spread(self.paper_share_by_seed)

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["warnings"] = list(self.warnings)
        d["classification"] = self.classification
        d["paper_share_range_pct"] = list(self.paper_share_range_pct)
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
            f"{c['particles']} particles x {c['iterations']} iterations x "
            f"{len(c.get('seeds') or [c['seed']])} seed(s) per cell, MuJoCo step "
            f"{1000 * c['timestep']:g} ms, {c['workers']} worker(s), {c['seconds']:.1f} s",
            "cells: change in % of the standard (positive = the bio-inspired plan saves);",
            f"  '+' saves, '=' no difference (|change| < {NO_DIFFERENCE_PCT:g}%), '-' costs "
            "more, '*' standard already on the abs_work floor, '!' the cell has warnings (e.g. "
            "the standard quintic exceeds a limit), '?' uncertain: the seeds of the paper's PSO "
            "disagree (spread below), 'infeasible'/'unstable' as said",
        ]
        for o in self.objectives:
            for m in metrics or METRICS:
                lines.append("")
                lines.append(f"objective {o}, metric {m} [{names.METRICS[m].unit}]:")
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
        lines.extend(self._uncertain_lines(metrics or METRICS))
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
        for cell in [c for c in self.cells if c.status == "ok" and c.paper_infeasible][:5]:
            lines.append(
                f"paper infeasible: T={cell.duration:g} s, m={cell.payload:g} kg, "
                f"{cell.objective} (the other methods are reported): {cell.method_status['paper']}"
            )
        return "\n".join(lines)

    def _uncertain_lines(self, metrics: Sequence[str]) -> list[str]:
        """One line per uncertain verdict: the seeds' verdicts and the spread."""
        lines: list[str] = []
        for cell in self.cells:
            for m in metrics:
                v = cell.verdicts.get(m)
                if v is None or v.certain:
                    continue
                share = ""
                lo, hi = cell.paper_share_range_pct
                if math.isfinite(lo):
                    share = f"; paper's share {lo:.1f}..{hi:.1f} %"
                lines.append(
                    f"uncertain: T={cell.duration:g} s, m={cell.payload:g} kg, {cell.objective}, "
                    f"{m}: {' / '.join(v.by_seed)} over seeds {list(cell.seeds)}, planned "
                    f"change {v.low_pct:+.1f}..{v.high_pct:+.1f} %{share}"
                )
        if len(lines) > MAX_UNCERTAIN_LINES:
            more = len(lines) - MAX_UNCERTAIN_LINES
            lines = [*lines[:MAX_UNCERTAIN_LINES], f"... and {more} more uncertain (see --json)"]
        if lines:
            lines.insert(0, "")
        return lines


def _none_if_nan(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _cell_text(cell: SweepCell, metric: str) -> str:
    if cell.status != "ok":
        return cell.status
    if cell.paper_infeasible:
        return "infeasible"
    v = cell.change_pct.get(metric, math.nan)
    if not math.isfinite(v):
        return "n/a"
    mark = {"saves": "+", "no difference": "=", "costs more": "-"}[classify(v)]
    floor = "*" if cell.at_floor else ""
    warn = "!" if cell.warnings else ""
    unsure = "?" if metric in cell.unconverged else ""
    return f"{v:+.1f}% {mark}{floor}{warn}{unsure}"


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


@dataclass(frozen=True)
class _CellJob:
    duration: float
    payload: float
    objective: str
    seed: int
    particles: int
    iterations: int
    timestep: float
    methods: tuple[str, ...]
    check_seeds: tuple[int, ...]
    converge: bool = False


def _failed(job: _CellJob, status: str, exc: Exception, started: float) -> SweepCell:
    return SweepCell(
        duration=job.duration,
        payload=job.payload,
        objective=job.objective,
        status=status,
        message=str(exc),
        seconds=time.perf_counter() - started,
    )


def _simulate_cell(job: _CellJob) -> tuple[SimulationResult, dict[str, str]]:
    """The cell's comparison; a method that cannot run (e.g. jerk-limited too slow) is left
    out with its reason, the others still run."""
    from app.errors import BioPlanError

    status: dict[str, str] = {}
    methods = list(job.methods)
    while True:
        try:
            res = simulate_comparison(
                _robot_with(job.payload),
                duration=job.duration,
                objective=job.objective,
                seed=job.seed,
                particles=job.particles,
                iterations=job.iterations,
                timestep=job.timestep,
                methods=methods,
                converge=job.converge,
            )
            status.update({m: "ok" for m in res.runs})
            # A method that failed inside the plan (its own error) while the others ran.
            status.update({m: f.error for m, f in res.plan.method_errors.items()})
            return res, status
        except BioPlanError as exc:
            culprit = _failed_method(exc, methods)
            if culprit is None:
                raise
            status[culprit] = str(exc)
            methods.remove(culprit)


def _failed_method(exc: Exception, methods: list[str]) -> str | None:
    """The optional method whose own error ``exc`` is (None: the task itself failed)."""
    from app.planning.jerk_limited import JerkLimitedError
    from app.planning.methods import PaperInfeasible
    from app.planning.optimal import SolverError

    if isinstance(exc, JerkLimitedError) and "jerk_limited" in methods:
        return "jerk_limited"
    if isinstance(exc, PaperInfeasible) and "paper" in methods:
        # Only the paper's family is infeasible: the others still run, unless nothing but the
        # quintic (the reference) would be left.
        return "paper" if set(methods) - {"quintic", "paper"} else None
    if isinstance(exc, SolverError):
        for name in ("human_optimal", "bound"):
            if name in methods:
                return name
    return None


def _replan_paper(
    job: _CellJob, seed: int, report_samples: int, bound: float | None
) -> tuple[dict[str, float], float]:
    """The paper's method planned again with ``seed`` on the cell's grid: its planned change per
    metric [%] and its share of the achievable saving [%] against the cell's ``bound`` value
    (NaN without a bound or a plan)."""
    from app.planning.methods import BoundViolation, share_of_achievable_pct
    from app.planning.planner import PlanningError, plan

    try:
        again = plan(
            _robot_with(job.payload),
            duration=job.duration,
            objective=job.objective,
            seed=seed,
            particles=job.particles,
            iterations=job.iterations,
            report_samples=report_samples,
            methods=("quintic", "paper"),
            safety=False,  # only its metrics are used; the cell's own plan is checked
        )
    except PlanningError:
        # This seed's swarm found no feasible plan: its verdict is "n/a".
        return {k: math.nan for k in METRICS}, math.nan
    std = scalar_metrics(again.standard.metrics)
    opt = scalar_metrics(again.methods["paper"].evaluated.metrics)
    share = math.nan
    if bound is not None:
        values = again.objective_values
        # A seed below the cell's certified bound: its share is not given.
        with contextlib.suppress(BoundViolation):
            share = share_of_achievable_pct(values["quintic"], values["paper"], bound)
    return {k: pct_change(std[k], opt[k]) for k in METRICS}, share


def _seed_runs(
    job: _CellJob, planned: dict[str, float], share: float, report_samples: int,
    bound: float | None,
) -> tuple[list[dict[str, float]], list[float]]:  # fmt: skip
    """Per seed (the cell's first, then the check seeds): planned changes and paper share."""
    changes, shares = [planned], [share]
    for seed in job.check_seeds:
        c, s = _replan_paper(job, seed, report_samples, bound)
        changes.append(c)
        shares.append(s)
    return changes, shares


def _run_cell(job: _CellJob) -> SweepCell:
    """Plan and simulate one cell (in a worker process); never raises for bad cells."""
    from app.planning.planner import PlanningError

    started = time.perf_counter()
    try:
        res, status = _simulate_cell(job)
    except PlanningError as exc:
        return _failed(job, "infeasible", exc, started)
    except SimulationError as exc:
        return _failed(job, "unstable", exc, started)
    std = scalar_metrics(res.standard.metrics)
    changes = {
        name: {k: pct_change(std[k], v) for k, v in scalar_metrics(run.metrics).items()}
        for name, run in res.runs.items()
    }
    pstd = scalar_metrics(res.plan.standard.metrics)
    paper = res.plan.methods.get("paper")
    popt = scalar_metrics(paper.evaluated.metrics) if paper is not None else {}
    planned = {k: pct_change(pstd[k], popt.get(k, math.nan)) for k in METRICS}
    shares = res.plan.share_of_achievable_pct
    bound = res.plan.objective_values.get("bound")
    if "paper" in job.methods:
        by_seed, share_by_seed = _seed_runs(
            job, planned, shares.get("paper", math.nan), res.plan.standard.trajectory.t.size,
            bound,
        )  # fmt: skip
        seeds = (job.seed, *job.check_seeds)
    else:
        by_seed, share_by_seed, seeds = [planned], [], ()
    verdicts = certify_verdicts(by_seed) if seeds else {}
    optimized = scalar_metrics(res.optimized.metrics) if res.optimized is not None else {}
    return SweepCell(
        duration=job.duration,
        payload=job.payload,
        objective=job.objective,
        status="ok",
        change_pct=changes.get("paper", {k: math.nan for k in METRICS}),
        planned_change_pct=planned,
        standard=std,
        optimized=optimized,
        floors={k: float(v) for k, v in res.floors.to_dict().items() if v is not None},
        at_floor=bool(std["abs_work"] <= (1.0 + AT_FLOOR_FRACTION) * res.floors.abs_work),
        tracking_max=float(max(run.tracking_max.max() for run in res.runs.values())),
        warnings=res.warnings,
        seconds=time.perf_counter() - started,
        methods_change_pct=changes,
        share_of_achievable_pct=res.share_of_achievable_pct(),
        method_status=status,
        unconverged=tuple(k for k in METRICS if k in verdicts and not verdicts[k].certain),
        check_planned_change_pct=by_seed[1] if len(by_seed) > 1 else {},
        seeds=seeds,
        verdicts=verdicts,
        paper_share_by_seed=tuple(share_by_seed),
    )


def _cell_job(job: _CellJob) -> SweepCell:
    return _run_cell(job)


def _cell_on_worker(robot: Robot, job: _CellJob) -> tuple[SweepCell, str]:
    """One cell as a Dask task: the cell and the worker that ran it (its address).

    The robot arrives pickled; when its files are not on this machine (a remote worker) it is
    rebuilt from its spec (built-in robots are regenerated; a user robot's files must be
    reachable at the same path).
    """
    from pathlib import Path

    from app.planning.robots import load_robot_spec

    if not Path(robot.urdf_path).exists() and robot.spec:
        robot = load_robot_spec(robot.spec)
    _init_worker(robot)
    try:
        cell = _cell_job(job)
    finally:
        _WORKER.clear()
    try:
        where = str(_distributed().get_worker().address)
    except (ImportError, ValueError):
        where = ""
    return cell, where


#: ``run_sweep``'s executors: a local process pool, or a Dask scheduler (``dask://HOST:PORT``
#: or a ``distributed.Client``) that runs one task per cell.
LOCAL_EXECUTOR = "local"


def _distributed() -> Any:
    """The ``distributed`` module (untyped, hence ``Any``), imported when a sweep uses Dask."""
    import distributed

    return distributed


def _dask_client(executor: Any) -> tuple[Any, bool]:
    """A ``distributed.Client`` for ``dask://HOST:PORT`` (owned: closed after the sweep), or
    the client given."""
    if not isinstance(executor, str):
        return executor, False
    if not executor.startswith("dask://") or len(executor) <= len("dask://"):
        raise SimulationError(
            f"executor {executor!r}: expected 'local' or 'dask://HOST:PORT' (a Dask scheduler)"
        )
    distributed = _distributed()
    address = executor.replace("dask://", "tcp://", 1)
    try:
        return distributed.Client(address, timeout=10, set_as_default=False), True
    except OSError as exc:
        raise SimulationError(
            f"executor {executor}: cannot reach the Dask scheduler ({exc})"
        ) from None


def _run_on_dask(
    clean: Robot, jobs: list[_CellJob], executor: Any, on_cell: Any
) -> tuple[int, str, dict[str, int]]:
    """One Dask task per cell; (workers on the cluster, note, cells per worker address)."""
    distributed = _distributed()
    client, owned = _dask_client(executor)
    try:
        [robot] = client.scatter([clean], broadcast=True, hash=False)
        futures = [
            client.submit(_cell_on_worker, robot, job, pure=False, key=f"bioplan-cell-{i}")
            for i, job in enumerate(jobs)
        ]
        used: dict[str, int] = {}
        for fut in distributed.as_completed(futures, loop=client.loop):
            cell, where = fut.result()
            used[where] = used.get(where, 0) + 1
            on_cell(cell)
        n_workers = len(client.scheduler_info(n_workers=-1)["workers"])
        return n_workers, "", used
    finally:
        if owned:
            client.close()


def _sweep_grid(grid: SweepGrid | None, overrides: dict[str, Any]) -> SweepGrid:
    """``grid`` (default: ``SweepGrid()``) with ``overrides`` by name, checked in the sweep's
    words: an empty, repeated or out-of-range grid is a SimulationError, an unknown objective
    or method the planner's PlanningError."""
    values = {**(SweepGrid() if grid is None else grid).to_dict(), **overrides}
    if "check_seed" in overrides and overrides["check_seed"] is None:
        values.update(check_seed=-1, no_check=True)  # the keyword signature's "no check"
    if values.get("methods") is None:
        values.pop("methods")
    try:
        durs = tuple(float(d) for d in values["durations"])
        pays = tuple(float(p) for p in values["payloads"])
    except (TypeError, ValueError):
        raise SimulationError("durations and payloads must be lists of numbers") from None
    _check_grid(durs, pays, tuple(values["objectives"]), values.get("methods", LIBRARY_METHODS))
    seeds = values.get("seeds")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise SimulationError(f"seeds must be an integer >= 1, got {seeds!r}")
    try:
        return SweepGrid.from_dict(values)
    except OptionsError as exc:
        raise SimulationError(str(exc)) from None


def _check_grid(
    durs: tuple[float, ...], pays: tuple[float, ...], objs: tuple[str, ...], methods: Sequence[str]
) -> tuple[str, ...]:
    """Refuse an empty, repeated or out-of-range grid; the checked methods."""
    from app.planning.energy import OBJECTIVES
    from app.planning.methods import check_methods
    from app.planning.planner import PlanningError

    if not durs or not pays or not objs:
        raise SimulationError("the sweep grid is empty: expected durations, payloads, objectives")
    if any(not (math.isfinite(d) and d > 0) for d in durs):
        raise SimulationError(f"durations must be positive seconds, got {list(durs)}")
    if any(not (math.isfinite(p) and p >= 0) for p in pays):
        raise SimulationError(f"payloads must be masses >= 0 kg, got {list(pays)}")
    unknown = [o for o in objs if o not in OBJECTIVES]
    if unknown:
        # The planner's own error for this (what ``plan`` raises for an unknown objective).
        raise PlanningError(
            f"unknown objective(s) {', '.join(unknown)}: expected some of {', '.join(OBJECTIVES)}"
        )
    if len(set(durs)) != len(durs) or len(set(pays)) != len(pays) or len(set(objs)) != len(objs):
        raise SimulationError("durations, payloads and objectives must not repeat")
    return check_methods(methods)


def _run_jobs(clean: Robot, jobs: list[_CellJob], n_workers: int, on_cell: Any) -> tuple[int, str]:
    """Run the cells in a spawned process pool (or here); the workers used and a pool note."""

    def run_here(todo: Sequence[_CellJob]) -> None:
        _init_worker(clean)
        try:
            for job in todo:
                on_cell(_cell_job(job))
        finally:
            _WORKER.clear()

    if n_workers == 1 or len(jobs) == 1:
        run_here(jobs)
        return n_workers, ""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    finished: set[tuple[float, float, str]] = set()
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
                cell = fut.result()
                finished.add((cell.duration, cell.payload, cell.objective))
                on_cell(cell)
    except BrokenProcessPool as exc:
        # Spawned workers re-import the caller's __main__; a script without the
        # ``if __name__ == "__main__":`` guard (or code piped to stdin) cannot be
        # re-imported. Finish in this process rather than fail.
        todo = [j for j in jobs if (j.duration, j.payload, j.objective) not in finished]
        logger.warning("the process pool failed (%s): %d cell(s) run in this process", exc,
                       len(todo))  # fmt: skip
        run_here(todo)
        return 1, (
            f"the process pool failed ({exc}); {len(todo)} cells ran in this process "
            "(a script needs the `if __name__ == '__main__':` guard for worker processes)"
        )
    return n_workers, ""


def _cell_jobs(g: SweepGrid) -> list[_CellJob]:
    """One job per cell of the checked grid, objective-major, then duration, then payload; the
    paper's check seeds are the grid's ``seeds - 1`` seeds after ``check_seed`` (none with
    ``no_check``)."""
    from app.planning.methods import check_methods

    chosen = check_methods(g.methods)
    check = None if g.no_check else (int(g.seed) + 1 if g.check_seed == -1 else int(g.check_seed))
    n_seeds = 1 if check is None else int(g.seeds)
    checks = () if check is None else tuple(check + i for i in range(n_seeds - 1))
    job = _CellJob(
        duration=0.0,
        payload=0.0,
        objective="",
        seed=int(g.seed),
        particles=int(g.particles),
        iterations=int(g.iterations),
        timestep=float(g.timestep),
        methods=chosen,
        check_seeds=checks,
        converge=bool(g.converge),
    )
    return [
        dataclasses.replace(job, duration=d, payload=p, objective=o)
        for o in g.objectives
        for d in g.durations
        for p in g.payloads
    ]


def _log_start(robot: Robot, g: SweepGrid, jobs: list[_CellJob], where: str) -> None:
    """Log what the sweep is about to run (cells, methods, PSO budget, seeds) and ``where``."""
    job = jobs[0]
    logger.info(
        "sweep of %s: %d cell(s) (%d durations x %d payloads x %d objectives), methods %s, PSO "
        "%d particles x %d iterations, seeds %s, on %s",
        robot.name, len(jobs), len(g.durations), len(g.payloads), len(g.objectives),
        ", ".join(job.methods), job.particles, job.iterations,
        ", ".join(str(s) for s in (job.seed, *job.check_seeds)), where,
    )  # fmt: skip


def _collector(
    n_cells: int, progress: ProgressFn | None
) -> tuple[list[SweepCell], Callable[[SweepCell], None]]:
    """The list the finished cells go to and the callback that appends one, logs it and
    reports the progress (stage ``sweep``: cells done of ``n_cells``)."""
    results: list[SweepCell] = []

    def on_cell(cell: SweepCell) -> None:
        results.append(cell)
        log = logger.info if cell.status == "ok" else logger.warning
        log(
            "sweep cell %d/%d: T=%g s, m=%g kg, %s: %s in %.2f s%s",
            len(results), n_cells, cell.duration, cell.payload, cell.objective, cell.status,
            cell.seconds, f" ({cell.message})" if cell.message else "",
        )  # fmt: skip
        report(
            progress,
            "sweep",
            len(results),
            n_cells,
            message=f"cell {len(results)}/{n_cells}: T={cell.duration:g} s, "
            f"m={cell.payload:g} kg, {cell.objective}: {cell.status}",
        )

    return results, on_cell


def _conditions(
    robot: Robot,
    job: _CellJob,
    n_workers: int,
    where: str,
    used: dict[str, int],
    pool_note: str,
) -> dict[str, Any]:
    """``SweepResult.conditions`` but ``seconds``: the budget and seeds every cell ran with
    (``job``, any cell's), the thresholds of the verdicts and where the cells ran."""
    checks = job.check_seeds
    paper = "paper" in job.methods
    return {
        "seed": job.seed,
        "check_seed": checks[0] if checks else None,
        "seeds": [job.seed, *checks] if paper else [],
        "pso_budget": {
            "particles": job.particles,
            "iterations": job.iterations,
            "seeds": 1 + len(checks) if paper else 0,
            "certain_when": "every seed gives the same verdict",
        },
        "converge": job.converge,
        "particles": job.particles,
        "iterations": job.iterations,
        "methods": list(job.methods),
        "timestep": job.timestep,
        "integrator": INTEGRATOR,
        "workers": n_workers,
        "executor": where,
        "cells_per_worker": used,
        "seconds": 0.0,  # set by run_sweep when the last cell is in
        "no_difference_pct": NO_DIFFERENCE_PCT,
        "at_floor_fraction": AT_FLOOR_FRACTION,
        "poor_tracking_rad": POOR_TRACKING_RAD,
        "payload_shape": [float(v) for v in robot.payload.size],
        "pool_note": pool_note,
    }


def run_sweep(
    *,
    robot: Robot,
    grid: SweepGrid | None = None,
    workers: int | None = None,
    executor: Any = LOCAL_EXECUTOR,
    progress: ProgressFn | None = None,
    **overrides: Any,
) -> SweepResult:
    """Plan and simulate every (duration, payload, objective) cell; classify the changes.

    Cells run in a process pool (``workers`` processes, default ``min(2, cpu_count)``; 1 runs
    them in this process). Workers are spawned (fresh interpreters), so a calling script needs
    the usual ``if __name__ == "__main__":`` guard; without it the pool breaks and the cells run
    in this process instead (said in ``conditions["pool_note"]``). Every cell uses the same
    seed, so the result does not depend on the order in which cells finish.

    Args:
        robot: the robot (its payload shape is kept; the mass is set per cell); needs an MJCF.
        grid: the grid and the cells' options (``SweepGrid``: durations [s], payloads [kg],
            objectives, PSO seed and budget per cell, methods, the seeds' check, converge,
            time step [s]); None: its defaults. Every cell uses the same seed; the paper's PSO
            runs with ``seeds`` seeds per cell (the cell's, then ``check_seed``,
            ``check_seed + 1``...; ``no_check``: one), and a verdict is certain only when all
            agree (:func:`certify_verdicts`).
        workers: processes in the pool.
        executor: ``"local"`` (a process pool of ``workers`` processes), ``"dask://HOST:PORT"``
            (one task per cell on that Dask scheduler's workers; ``workers`` is ignored) or a
            ``distributed.Client`` (e.g. from inside a Dask task). ``conditions["executor"]``
            and ``conditions["cells_per_worker"]`` say where the cells ran.
        progress: called with a ``Progress`` (stage ``sweep``: cells done) as cells finish.
        **overrides: grid options by name over ``grid`` (``durations=[1.0]``, ``seeds=2``;
            ``check_seed=None`` is ``no_check=True``); an unknown name is an error naming it.

    Returns:
        The sweep; ``to_dict()`` for JSON, ``summary()`` for text.

    Raises:
        RobotError: the robot has no MJCF.
        SimulationError: an empty grid, a bad duration or payload.
        PlanningError: an unknown objective or method.
    """
    _check_mjcf(robot)
    g = _sweep_grid(grid, overrides)
    n_workers = min(2, os.cpu_count() or 1) if workers is None else int(workers)
    if n_workers < 1:
        raise SimulationError(f"workers must be >= 1, got {workers}")
    jobs = _cell_jobs(g)
    started = time.perf_counter()
    local = isinstance(executor, str) and executor == LOCAL_EXECUTOR
    results, on_cell = _collector(len(jobs), progress)
    report(progress, "sweep", 0, len(jobs), message=f"{len(jobs)} cells on {n_workers} worker(s)")
    _log_start(robot, g, jobs, f"{n_workers} local worker(s)" if local else "Dask")
    # A copy without cached Pinocchio/MuJoCo objects, so it pickles to the workers.
    clean = dataclasses.replace(robot)
    used: dict[str, int] = {}
    if local:
        n_workers, pool_note = _run_jobs(clean, jobs, n_workers, on_cell)
        where = LOCAL_EXECUTOR
    else:
        n_workers, pool_note, used = _run_on_dask(clean, jobs, executor, on_cell)
        where = executor if isinstance(executor, str) else "dask"
    order = {(j.duration, j.payload, j.objective): i for i, j in enumerate(jobs)}
    cells = tuple(sorted(results, key=lambda c: order[(c.duration, c.payload, c.objective)]))
    conditions = _conditions(robot, jobs[0], n_workers, where, used, pool_note)
    conditions["seconds"] = time.perf_counter() - started
    return SweepResult(
        robot=robot.name,
        durations=g.durations,
        payloads=g.payloads,
        objectives=g.objectives,
        cells=cells,
        conditions=conditions,
    )
