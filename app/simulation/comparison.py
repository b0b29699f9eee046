"""Plan, then simulate: every planned method tracked in MuJoCo with the same controller.

:func:`simulate_comparison` plans a task (``app.planning.planner.plan``, the methods asked for),
simulates every method's trajectory in one MuJoCo rollout with the same controller
(:mod:`app.simulation.tracking`) and reports the metrics *measured in the simulation*, the
tracking error, the changes against the standard quintic, the physical floors, the planner's own
metrics beside them (for the agreement check) and where the peaks of power and torque fall
relative to the human template's A/B/C phases.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app import names
from app.jsonsafe import json_safe
from app.options import OptionsError
from app.planning.energy import EnergyMetrics, Floors, improvement_pct
from app.progress import ProgressFn, report, within
from app.simulation.options import SimulationOptions
from app.simulation.tracking import (
    INTEGRATOR,
    SimulationError,
    TrackingResult,
    simulate_batch,
)

if TYPE_CHECKING:
    from app.planning.human_template import HumanTemplate
    from app.planning.planner import PlanResult, PlanTask
    from app.planning.robots import Robot

logger = logging.getLogger("bioplan.simulation")

__all__ = [
    "AGREEMENT_PCT",
    "FLOOR_SLACK",
    "METRICS",
    "SimulationResult",
    "peaks_and_phases",
    "scalar_metrics",
    "simulate_comparison",
]

FloatArray = NDArray[np.float64]

#: Scalar metrics compared everywhere (``peak_torque`` = the largest joint peak torque [Nm]).
METRICS: tuple[str, ...] = names.OBJECTIVES
#: Planned and simulated metrics should agree this well when tracking is good [%].
AGREEMENT_PCT = 2.0
#: Relative slack below the physical floors tolerated in simulated metrics [-].
FLOOR_SLACK = 0.005
#: A planned value below this fraction of its metric's scale (:func:`metric_scale`) is near
#: zero: a percentage of it means nothing, so its difference is stated in the metric's unit and
#: judged against AGREEMENT_PCT of the scale instead [-].
NEAR_ZERO_FRACTION = 0.01


def _phase(flexion_deg: float, bounds_deg: tuple[float, float]) -> str:
    """Phase A/B/C of an elbow flexion [deg] given the A/B and B/C bounds [deg]."""
    if flexion_deg < bounds_deg[0]:
        return names.PHASES[0].name
    if flexion_deg < bounds_deg[1]:
        return names.PHASES[1].name
    return names.PHASES[2].name


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


def scalar_metrics(metrics: EnergyMetrics) -> dict[str, float]:
    """The scalar metrics of ``METRICS``; ``peak_torque`` = the largest joint's [Nm]."""
    m = metrics.to_dict()
    out: dict[str, float] = {}
    for k in METRICS:
        value = m[k]
        if isinstance(value, list):
            out[k] = float(max(value))
        else:
            out[k] = math.nan if value is None else float(value)
    return out


def pct_change(standard: float, optimized: float) -> float:
    """100 (standard - optimized) / standard; NaN when the standard is 0 (no basis)."""
    if standard == 0.0 or not (math.isfinite(standard) and math.isfinite(optimized)):
        return math.nan
    return 100.0 * (standard - optimized) / abs(standard)


@dataclass(frozen=True)
class SimulationResult:
    """Every planned method, simulated in MuJoCo, beside the planner's numbers.

    ``to_dict()`` is the JSON of ``bioplan simulate --json``.

    Attributes:
        plan: the planner's result (its metrics are on the same time grid).
        standard: the quintic's run; optimized: the paper's run (None when not planned).
        floors: physical floors of the task.
        conditions: robot, payload, duration, objective, seed, controller, time step, ...
        warnings: planner and simulator warnings, and any planned/simulated disagreement.
        runs: every method's run by name (``runs["bound"]``).
    """

    plan: PlanResult
    standard: TrackingResult
    optimized: TrackingResult | None
    floors: Floors
    conditions: dict[str, Any]
    warnings: tuple[str, ...] = field(default=())
    runs: dict[str, TrackingResult] = field(default_factory=dict)
    motors: tuple[Any, ...] = ()
    tau_max: tuple[float, ...] = ()

    @property
    def improvement_pct(self) -> dict[str, Any]:
        """100 (standard - paper) / standard per metric, from the simulation ({} without it)."""
        if self.optimized is None:
            return {}
        return improvement_pct(self.standard.metrics, self.optimized.metrics)

    def run(self, label: str) -> TrackingResult:
        """A run by method name, or ``standard`` / ``optimized`` (the quintic / the paper)."""
        key = {"standard": "quintic", "optimized": "paper"}.get(label, label)
        if key not in self.runs:
            raise SimulationError(
                f"method {label!r} was not simulated: expected one of {', '.join(self.runs)}"
            )
        return self.runs[key]

    def peaks(self, label: str) -> dict[str, Any]:
        """Peaks of power and torque of one run (see :meth:`run`) with their phases."""
        return peaks_and_phases(
            self.run(label),
            task=self.plan.task,
            elbow_joint=self.plan.elbow_joint,
            phase_bounds_deg=self.plan.phase_bounds_deg,
            joint_names=self.conditions["joint_names"],
        )

    def agreement_pct(self) -> dict[str, dict[str, float]]:
        """100 (simulated - planned) / planned per scalar metric, per run.

        Keys: ``standard``, ``optimized`` (when the paper ran) and every method name.
        """
        out: dict[str, dict[str, float]] = {}
        for name, run in self.runs.items():
            sim = scalar_metrics(run.metrics)
            ref = scalar_metrics(self.plan.methods[name].evaluated.metrics)
            out[name] = {
                k: (100.0 * (sim[k] - ref[k]) / abs(ref[k]) if ref[k] != 0.0 else math.nan)
                for k in METRICS
            }
        out["standard"] = out["quintic"]
        if "paper" in out:
            out["optimized"] = out["paper"]
        return out

    def share_of_achievable_pct(self) -> dict[str, float]:
        """Per method, 100 (quintic − method) / (quintic − bound) of the objective, simulated."""
        from app.planning.methods import simulated_share_of_achievable_pct as share

        if "bound" not in self.runs:
            return {}
        obj = self.plan.objective
        values = {name: _simulated_objective(self, name, obj) for name in self.runs}
        q, b = values["quintic"], values["bound"]
        return {
            name: math.nan if name == "bound_unrestricted" else share(q, v, b)
            for name, v in values.items()
        }

    def phase_times(self, label: str = "optimized") -> tuple[float, float]:
        """Times [s] at which the commanded elbow crosses the A/B and B/C bounds."""
        return self.plan.phase_times(label)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (NaN as None): metrics from the simulation, tracking, floors, changes, ..."""
        return dict(json_safe(_to_dict(self)))

    def arrays(self) -> dict[str, FloatArray]:
        """Curves for plots on one grid: ``t`` and ``<method>_<name>`` for every recorded array
        of every run (``standard_*`` / ``optimized_*`` repeat the quintic's and the paper's)."""
        out: dict[str, FloatArray] = {"t": self.standard.t}
        labels = [*self.runs.items(), ("standard", self.standard)]
        if self.optimized is not None:
            labels.append(("optimized", self.optimized))
        for label, run in labels:
            for name, arr in run.arrays().items():
                if name != "t":
                    out[f"{label}_{name}"] = arr
        return out

    def summary(self) -> str:
        """A human-readable report of the comparison."""
        return _summary(self)


def _simulated_objective(sim: SimulationResult, name: str, objective: str) -> float:
    from app.planning.energy import objective_values

    run = sim.runs[name]
    tau_max = np.asarray(sim.tau_max, dtype=np.float64)
    motors = sim.motors or None
    return float(
        objective_values(objective, run.t, run.qd, run.tau, motors=motors, tau_max=tau_max)
    )


def _side(sim: SimulationResult, name: str) -> dict[str, Any]:
    run = sim.runs[name]
    d: dict[str, Any] = dict(run.metrics.to_dict())
    d["peaks"] = sim.peaks(name)
    d["saturation"] = [float(v) for v in run.saturation]
    d["peak_velocity_angle_deg"] = sim.plan.methods[name].evaluated.peak_velocity_angle_deg
    return d


def _to_dict(sim: SimulationResult) -> dict[str, Any]:
    shares = sim.share_of_achievable_pct()
    methods: dict[str, Any] = {}
    for name, run in sim.runs.items():
        d = _side(sim, name)
        d["label"] = names.METHODS[name].label
        d["tracking"] = {
            "rms": [float(v) for v in run.tracking_rms],
            "max": [float(v) for v in run.tracking_max],
        }
        d["improvement_pct"] = improvement_pct(sim.standard.metrics, run.metrics)
        d["share_of_achievable_pct"] = shares.get(name)
        # How the plan was made (PSO, IPOPT with its mesh-refinement evidence, ruckig).
        d["solver"] = sim.plan.methods[name].solver
        methods[name] = d
    pairs = [("standard", "quintic")] + ([("optimized", "paper")] if "paper" in sim.runs else [])
    planned: dict[str, Any] = {
        label: sim.plan.methods[name].evaluated.metrics.to_dict() for label, name in pairs
    }
    planned["improvement_pct"] = sim.plan.improvement_pct
    # the methods that failed to plan (their own errors), so not simulated
    planned["method_errors"] = {n: f.to_dict() for n, f in sim.plan.method_errors.items()}
    planned["simulated_minus_planned_pct"] = sim.agreement_pct()
    conditions = dict(sim.conditions)
    return {
        **{label: _side(sim, name) for label, name in pairs},
        "tracking": {
            label: {
                "rms": [float(v) for v in sim.runs[name].tracking_rms],
                "max": [float(v) for v in sim.runs[name].tracking_max],
            }
            for label, name in pairs
        },
        "floors": sim.floors.to_dict(),
        "improvement_pct": sim.improvement_pct,
        "planned": planned,
        "methods": methods,
        "share_of_achievable_pct": shares,
        "conditions": conditions,
        "warnings": list(sim.warnings),
    }


def _summary(sim: SimulationResult) -> str:
    c = sim.conditions
    runs = list(sim.runs)
    std = scalar_metrics(sim.standard.metrics)
    lines = [
        f"robot {c['robot']}, payload {c['payload']:g} kg, duration {c['duration']:g} s, "
        f"objective {c['objective']}, seed {c['seed']}, human constraint "
        f"{c['human_constraint']}",
        f"MuJoCo {c['integrator']}, step {1000 * c['timestep']:g} ms, feed-forward "
        f"{c['feedforward']}, PD {c['natural_frequency_hz']:g} Hz / zeta "
        f"{c['damping_ratio']:g}, backend {c['backend']}",
        "",
        f"{'metric (simulated)':<26}" + "".join(f"{name:>16}" for name in runs),
    ]
    for k in METRICS:
        unit = names.METRICS[k].unit
        row = f"{k + ' [' + unit + ']':<26}"
        if k == "electrical_energy" and math.isnan(std[k]):  # the robot has no motor model
            lines.append(row + f"{'not modelled':>16}")
            continue
        for name in runs:
            value = scalar_metrics(sim.runs[name].metrics)[k]
            change = pct_change(std[k], value)
            text = (
                f"{value:.4g}"
                if name == "quintic" or not math.isfinite(change)
                else (f"{value:.4g} ({change:+.0f}%)")
            )
            row += f"{text:>16}"
        lines.append(row)
    fl = sim.floors
    lines.append(
        f"floors: |ΔPE| = {fl.abs_work:.4g} J (ΔPE {fl.delta_potential:+.4g} J), positive work "
        f"{fl.pos_work:.4g} J, peak power {fl.peak_power:.4g} W, electrical "
        f"{fl.electrical_energy:.4g} J (friction {fl.friction_energy:.4g} J)"
    )
    shares = sim.share_of_achievable_pct()
    if shares:
        lines.append(
            f"share of the achievable {c['objective']} saving (quintic -> bound): "
            + ", ".join(f"{n} {v:.0f}%" for n, v in shares.items() if math.isfinite(v))
        )
    lines.append("(change) = saving against the quintic: positive = saves")
    for name in runs:
        run = sim.runs[name]
        p = sim.peaks(name)
        pw = p["power"]
        lines.append(
            f"{name}: max tracking error "
            + ", ".join(f"{math.degrees(v):.3f}" for v in run.tracking_max)
            + f" deg; power peak {pw['value']:.4g} W at t={pw['time']:.3f} s, elbow "
            f"{pw['elbow_deg']:.1f} deg (phase {pw['phase']})"
        )
    lines += [f"warning: {w}" for w in sim.warnings]
    return "\n".join(lines)


def _check_mjcf(robot: Robot) -> None:
    """Fail fast, before planning, when the robot cannot be simulated."""
    if robot.mjcf_path is None:
        robot.mujoco_model()  # raises RobotError with the robot's own message


def _report_samples(duration: float, timestep: float) -> int:
    """Samples putting the planned trajectories on the simulation grid ``k * timestep``."""
    n_steps = duration / timestep
    on_grid = abs(n_steps - round(n_steps)) < 1e-9 * max(n_steps, 1.0)
    return max(round(n_steps) + 1 if on_grid else math.ceil(n_steps) + 1, 10)


def simulate_comparison(
    robot: Robot,
    options: SimulationOptions | None = None,
    *,
    task: PlanTask | None = None,
    template: HumanTemplate | None = None,
    progress: ProgressFn | None = None,
    **overrides: Any,
) -> SimulationResult:
    """Plan a task with the chosen methods, then simulate every trajectory in MuJoCo.

    Every trajectory is planned on the simulation grid (``k * timestep``), so planned and
    simulated metrics use the same samples; all are simulated in one rollout with the same
    controller.

    Args:
        robot: the robot with its payload (``load_robot(name, payload=kg)``); needs an MJCF.
        options: every option (``SimulationOptions``: the planning ones as ``plan``'s, the
            time step [s], feed-forward and PD gains); None: the defaults.
        task: start/goal; defaults to the robot's curl task.
        template: the human template (default: the paper's).
        progress: called with a ``Progress`` (stages ``pso``, ``optimal_control``, ``simulate``).
        **overrides: options by name over ``options`` (``duration=2.0``); an unknown name or
            a value out of range is a SimulationError naming it.

    Returns:
        The comparison.

    Raises:
        RobotError: the robot has no MJCF.
        PlanningError: the task cannot be planned.
        SimulationError: the simulation ran away or the input is bad.
    """
    from app.planning.options import MethodOptions, PlanOptions
    from app.planning.planner import plan

    _check_mjcf(robot)
    opts = _simulation_options(options, overrides)
    duration, timestep = opts.duration, opts.timestep
    shared = {k: v for k, v in opts.to_dict().items() if k in MethodOptions.names()}
    result = plan(
        robot,
        PlanOptions(**shared, report_samples=_report_samples(duration, timestep)),
        task=task,
        template=template,
        progress=within(progress, 0.0, 0.85),
    )
    report(progress, "simulate", 0, 1, fraction=0.85, message="simulating in MuJoCo")
    names_ = list(result.methods)
    runs = simulate_batch(
        robot,
        [result.methods[n].trajectory for n in names_],
        timestep=timestep,
        feedforward=opts.feedforward,  # type: ignore[arg-type]  # checked by its choices
        natural_frequency_hz=opts.natural_frequency_hz,
        damping_ratio=opts.damping_ratio,
    )
    by_name = dict(zip(names_, runs, strict=True))
    for name, run in by_name.items():
        logger.info(
            "%s: simulated at %g ms steps (%s feed-forward): abs_work %.4g J, tracking error "
            "up to %.3g deg%s", name, 1000 * run.timestep, run.feedforward,
            run.metrics.abs_work, math.degrees(float(np.max(run.tracking_max))),
            "" if run.tracking_ok else " (poor tracking)",
        )  # fmt: skip
    conditions = _conditions(robot, result, by_name["quintic"], opts.to_dict())
    out = SimulationResult(
        plan=result,
        standard=by_name["quintic"],
        optimized=by_name.get("paper"),
        floors=result.floors,
        conditions=conditions,
        runs=by_name,
        motors=tuple(robot.motors),
        tau_max=tuple(float(v) for v in robot.tau_max),
    )
    warnings = [*result.warnings, *_run_warnings(out)]
    report(progress, "simulate", 1, 1, message="simulation done")
    return dataclasses.replace(out, warnings=tuple(warnings))


def _simulation_options(
    options: SimulationOptions | None, overrides: dict[str, Any]
) -> SimulationOptions:
    """``options`` (default: ``SimulationOptions()``) with ``overrides`` by name; ``None`` for
    ``methods`` or ``n_intervals`` keeps the default (as before the options existed)."""
    changes = {k: v for k, v in overrides.items() if not (v is None and k in _NONE_IS_DEFAULT)}
    try:
        base = SimulationOptions() if options is None else options
        return base.replace(**changes) if changes else base
    except OptionsError as exc:
        raise SimulationError(str(exc)) from None


#: Overrides whose None meant "the default" in the keyword signature.
_NONE_IS_DEFAULT = frozenset({"methods", "n_intervals"})


def _conditions(
    robot: Robot, result: PlanResult, standard: TrackingResult, args: dict[str, Any]
) -> dict[str, Any]:
    paper = result.methods.get("paper")
    return {
        "robot": robot.name,
        "joint_names": list(robot.joint_names),
        "payload": float(robot.payload.mass),
        "payload_size": [float(v) for v in robot.payload.size],
        "duration": float(args["duration"]),
        "objective": args["objective"],
        "seed": int(args["seed"]),
        "particles": int(args["particles"]),
        "iterations": int(args["iterations"]),
        "methods": list(result.methods),
        "human_constraint": result.human_constraint,
        "start_deg": np.degrees(result.task.start).tolist(),
        "goal_deg": np.degrees(result.task.goal).tolist(),
        "phase_bounds_deg": list(result.phase_bounds_deg),
        "elbow_joint": robot.joint_names[result.elbow_joint],
        "shoulder_joint": robot.joint_names[robot.shoulder_joint],
        "peak_velocity_angle_deg": None
        if paper is None
        else paper.evaluated.peak_velocity_angle_deg,
        "target_peak_velocity_angle_deg": result.target_peak_angle_deg,
        "timestep": float(args["timestep"]),
        "integrator": INTEGRATOR,
        "feedforward": args["feedforward"],
        "natural_frequency_hz": float(args["natural_frequency_hz"]),
        "damping_ratio": float(args["damping_ratio"]),
        "kp": [float(v) for v in standard.kp],
        "kd": [float(v) for v in standard.kd],
        "backend": standard.backend,
        "friction": "in the drive (electrical model), not in the MuJoCo joints",
    }


def metric_scale(metric: str, quintic: dict[str, float]) -> float:
    """The size of ``metric`` in this task: the quintic's planned value of it, and for the
    energies [J] at least the quintic's planned absolute work (positive work and, without
    regeneration, the electrical energy are of its order; positive work is near zero on a
    lowering task while the motion still moves joules)."""
    keys = [metric, "abs_work"] if names.METRICS[metric].unit == "J" else [metric]
    values = [abs(quintic.get(k, math.nan)) for k in keys]
    finite = [v for v in values if math.isfinite(v)]  # electrical energy: NaN = not modelled
    return max(finite) if finite else math.nan


def agreement_warning(
    label: str, metric: str, planned: float, simulated: float, scale: float
) -> str | None:
    """The warning when simulated and planned ``metric`` disagree although tracking is good.

    Relative (``+3.1%``) when the planned value is at least NEAR_ZERO_FRACTION of ``scale``;
    otherwise absolute, in the metric's unit, and only when the difference exceeds
    AGREEMENT_PCT of ``scale`` (two near-zero values differ by a large percentage of each
    other and by nothing that matters). None when they agree.
    """
    if not (math.isfinite(planned) and math.isfinite(simulated)):
        return None
    diff = simulated - planned
    if math.isfinite(scale) and scale > 0 and abs(planned) < NEAR_ZERO_FRACTION * scale:
        if abs(diff) <= AGREEMENT_PCT / 100.0 * scale:
            return None
        unit = names.METRICS[metric].unit
        return (
            f"{label}: simulated {metric} differs from the planned value by {diff:+.4g} {unit} "
            f"(planned {planned:.4g} {unit}, near zero next to the task's scale {scale:.4g} "
            f"{unit}; > {AGREEMENT_PCT:g}% of it) although tracking is good"
        )
    if planned == 0.0:
        return None
    pct = 100.0 * diff / abs(planned)
    if abs(pct) <= AGREEMENT_PCT:
        return None
    return (
        f"{label}: simulated {metric} differs from the planned value by {pct:+.1f}% "
        f"(> {AGREEMENT_PCT:g}%) although tracking is good"
    )


def _run_warnings(sim: SimulationResult) -> list[str]:
    """Simulator warnings, simulated metrics below a floor, planned/simulated disagreement."""
    warnings: list[str] = []
    fl = sim.floors
    labels = {"quintic": "standard", "paper": "optimized"}
    quintic = scalar_metrics(sim.plan.methods["quintic"].evaluated.metrics)
    for name, run in sim.runs.items():
        label = labels.get(name, name)
        warnings += [f"{label}: {w}" for w in run.warnings]
        # A discrete simulation may dip below a continuous-time floor by its integration error
        # (~0.01 % at 1 ms); more than the stated slack means the simulation is not to be trusted.
        for k, floor in (("abs_work", fl.abs_work), ("pos_work", fl.pos_work)):
            value = float(getattr(run.metrics, k))
            if floor > 0 and value < floor * (1.0 - FLOOR_SLACK):
                warnings.append(
                    f"{label}: simulated {k} = {value:.4g} J is below its floor {floor:.4g} J by "
                    f"more than {100 * FLOOR_SLACK:g}%: the simulation is not accurate enough "
                    "(expected a smaller time step)"
                )
        if not run.tracking_ok:
            continue
        simulated = scalar_metrics(run.metrics)
        planned = scalar_metrics(sim.plan.methods[name].evaluated.metrics)
        for k in METRICS:
            text = agreement_warning(label, k, planned[k], simulated[k], metric_scale(k, quintic))
            if text is not None:
                warnings.append(text)
    return warnings
