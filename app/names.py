"""One home for the names the whole project shares.

Metric names, units and formulas; the A/B/C lift phases with their default bounds and colours;
the planning methods; muscle sites; PSO and EMG defaults; job states. The science packages, the
CLI, the reports, the viewer and the dashboard (through ``GET /api/meta``) all read them from
here, so a metric's unit or phase C's colour is written once.

Plain data only: no imports beyond the standard library.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any


@dataclass(frozen=True)
class MetricInfo:
    """A trajectory metric (DESIGN.md, "Energy metrics").

    Attributes:
        name: key in every result (``tau_sq``...).
        unit: SI unit, as printed.
        label: short human name.
        formula: its definition, as printed.
        per_joint: one value per joint (``peak_torque``) instead of one per trajectory.
        floor: the ``Floors`` member that bounds it from below, or None when it has no floor.
    """

    name: str
    unit: str
    label: str
    formula: str
    per_joint: bool = False
    floor: str | None = None


#: Every metric, in the order tables show them.
METRICS: dict[str, MetricInfo] = {
    m.name: m
    for m in (
        MetricInfo("tau_sq", "N²m²s", "torque squared", "∫Σ τ² dt"),
        MetricInfo("abs_work", "J", "absolute work", "∫Σ |τ·ω| dt", floor="abs_work"),
        MetricInfo("pos_work", "J", "positive work", "∫Σ max(τ·ω, 0) dt", floor="pos_work"),
        MetricInfo(
            "electrical_energy",
            "J",
            "electrical energy",
            "motor model: copper losses, friction, regeneration",
            floor="electrical_energy",
        ),
        MetricInfo("peak_power", "W", "peak power", "max_t Σ |τ·ω|", floor="peak_power"),
        MetricInfo("peak_torque", "Nm", "peak torque", "max_t |τ_j| per joint", per_joint=True),
    )
}

#: Metrics a planner can minimise, in table order.
OBJECTIVES: tuple[str, ...] = tuple(METRICS)
#: The metric planning minimises unless told otherwise (``PlanOptions.objective``, sweeps).
DEFAULT_OBJECTIVE = "abs_work"

#: Metrics with one value per trajectory (everything but ``peak_torque``).
SCALAR_METRICS: tuple[str, ...] = tuple(n for n, m in METRICS.items() if not m.per_joint)


@dataclass(frozen=True)
class PhaseInfo:
    """One phase of a curl by elbow flexion (PAPER.md point 4).

    Attributes:
        name: ``A``, ``B`` or ``C``.
        label: what the phase is.
        colour: its colour in every plot, the viewer and the reports (CSS hex).
    """

    name: str
    label: str
    colour: str


#: The lift phases, in order.
PHASES: tuple[PhaseInfo, ...] = (
    PhaseInfo("A", "high-load capacity", "#2f9e44"),
    PhaseInfo("B", "weakest load", "#e8590c"),
    PhaseInfo("C", "deceleration", "#1c7ed6"),
)

#: Default (A/B, B/C) elbow-flexion bounds [deg].
PHASE_BOUNDS_DEG: tuple[float, float] = (40.0, 90.0)

#: Elbow flexion of a human curl, start to top [deg] (DESIGN.md conventions).
HUMAN_CURL_SPAN_DEG: tuple[float, float] = (0.0, 150.0)

#: The paper's elbow peak-velocity angle [deg]: the middle of phase B.
PAPER_PEAK_VELOCITY_ANGLE_DEG = 62.0


@dataclass(frozen=True)
class MethodInfo:
    """A planning method (DESIGN.md, "Planning methods").

    Attributes:
        name: key in results (``quintic``...).
        label: short human name.
        description: one line on what it is.
        colour: its colour in plots and the viewer (CSS hex).
    """

    name: str
    label: str
    description: str
    colour: str


#: Every planning method, in the order results list them.
METHODS: dict[str, MethodInfo] = {
    m.name: m
    for m in (
        MethodInfo("quintic", "standard quintic", "one quintic per joint, rest to rest", "#2563eb"),
        MethodInfo(
            "paper", "paper's method", "two quintics joined at the template angle, PSO", "#ea8c14"
        ),
        MethodInfo(
            "human_optimal",
            "human-like optimum",
            "optimal control with the template's constraints",
            "#9c36b5",
        ),
        MethodInfo(
            "bound",
            "physical bound",
            "optimal control under the task's rules (limits, rest to rest, monotone and held "
            "joints)",
            "#2b8a3e",
        ),
        MethodInfo(
            "bound_unrestricted",
            "unrestricted bound",
            "optimal control, limits only (reversal allowed); on request",
            "#74b816",
        ),
        MethodInfo(
            "jerk_limited",
            "industrial jerk-limited",
            "time-synchronised jerk-limited profile (ruckig)",
            "#5c677d",
        ),
    )
}

#: Methods planned only on request, never by default: the bound with reversal allowed.
ON_REQUEST_METHODS: tuple[str, ...] = ("bound_unrestricted",)
#: Every method but those on request: what "all methods" plans by default (CLI, API, demo).
STANDARD_METHODS: tuple[str, ...] = tuple(m for m in METHODS if m not in ON_REQUEST_METHODS)

#: ``human_optimal``'s human-likeness constraints (``app.planning.optimal.HUMAN_CONSTRAINTS``):
#: the elbow fastest at the template's angle, the A/B/C phase shares, the recorded lifts'
#: elbow-speed shape (mean ± SD; a template from recorded lifts only), or none.
HUMAN_CONSTRAINTS: tuple[str, ...] = ("peak", "phases", "shape", "none")
#: What each human constraint asks of ``human_optimal``, as the pages offer it.
HUMAN_CONSTRAINT_TEXT: dict[str, str] = {
    "peak": "the elbow is fastest where it passes the template's angle (one peak)",
    "phases": "A/B/C time shares within the template's spread",
    "shape": "the elbow's speed inside the recorded lifts' band (mean ± SD); a template from "
    "recorded lifts only",
    "none": "no human constraint (then it equals the physical bound)",
}
#: Constant-jerk intervals of the optimal-control transcription by default
#: (``app.planning.optimal.DEFAULT_INTERVALS``).
OPTIMAL_INTERVALS = 40
#: Metrics a Pareto front can trade (``app.planning.front``; ``peak_torque``: the largest
#: |τ_j| / τ_max,j; ``jerk``: ∫ Σ q⃛² dt [rad²/s⁵], a smoothness measure).
FRONT_METRICS: tuple[str, ...] = (*OBJECTIVES, "jerk")
#: Every axis of a front: the metrics and the duration [s].
FRONT_AXES: tuple[str, ...] = (*FRONT_METRICS, "duration")
#: A front's axes it measures differently from ``METRICS`` (or that they do not name): axis ->
#: (label, unit). A front's peak torque is the largest joint's over its limit (one number); its
#: jerk is the integral of the squared joint jerks.
FRONT_AXIS_TEXT: dict[str, tuple[str, str]] = {
    "peak_torque": ("peak torque over its limit (largest joint)", "τ/τ_max"),
    "jerk": ("jerk ∫Σ q⃛² dt (smoothness)", "rad²/s⁵"),
    "duration": ("duration", "s"),
}
#: Each physical floor's formula as printed (``app.planning.energy.Floors``), by floor or metric
#: name; ΔPE is the potential-energy change [J], T the duration [s].
FLOOR_FORMULAS: dict[str, str] = {
    "abs_work": "|ΔPE|",
    "pos_work": "max(ΔPE, 0)",
    "peak_power": "|ΔPE|/T (loose: the bound is the reference)",
    "electrical_energy": "ΔPE + friction",
    "delta_potential": "ΔPE",
    "min_peak_power": "ΔPE/T (loose: the bound is the reference)",
}
#: Older results name their floors after the physics only: metric -> that floor's name.
LEGACY_FLOOR_KEYS: dict[str, str] = {
    "abs_work": "delta_potential",
    "pos_work": "delta_potential",
    "peak_power": "min_peak_power",
}
#: What the floors mean, the sentence the Compare page prints under its metrics table.
FLOOR_NOTE = (
    "Floors: no rest-to-rest motion does less work than |ΔPE| or has a lower peak power than "
    "|ΔPE|/T (a loose floor: the bound is the reference); electrical energy adds the friction "
    "no motion avoids; tau_sq and peak torque have no floor."
)
#: Seeds of the paper's PSO per sweep cell (``app.simulation.sweep.SWEEP_SEEDS``): a verdict is
#: certain only when all agree.
SWEEP_SEEDS = 3

#: Muscle sites of the paper's EMG set-up, with their plot colours: hues at least 30 degrees
#: from every phase colour (or nearly grey), so an onset bar never reads as a phase.
MUSCLE_COLOURS: dict[str, str] = {
    "deltoid": "#8250df",
    "triceps": "#bf3989",
    "biceps": "#24292f",
    "forearm": "#9a8700",
}


@dataclass(frozen=True)
class PsoDefaults:
    """Default PSO budget of the paper's method."""

    particles: int = 40
    iterations: int = 100
    n_samples: int = 100
    seed: int = 0


PSO_DEFAULTS = PsoDefaults()


@dataclass(frozen=True)
class EmgDefaults:
    """Default EMG processing (band-pass, envelope) of ``app.analysis.emg``.

    Attributes:
        band_hz: band-pass corners [Hz].
        lowpass_hz: envelope low-pass corner [Hz].
        rms_window_s: moving-RMS window [s].
        order: Butterworth order.
    """

    band_hz: tuple[float, float] = (20.0, 450.0)
    lowpass_hz: float = 6.0
    rms_window_s: float = 0.1
    order: int = 4


EMG_DEFAULTS = EmgDefaults()

#: Longest video turned into pose by default [s] (``bioplan analyze --max-video-seconds``,
#: ``BIOPLAN_MAX_VIDEO_SECONDS``).
MAX_VIDEO_SECONDS = 600.0
#: Longest motion planned [s]: the API's and the CLI's cap on ``duration`` and ``durations``.
MAX_DURATION = 600.0
#: Frames of a video returned with the detected skeleton drawn, for the user to check the fit.
SKELETON_FRAMES = 4
#: How files uploaded together relate: separate trials (each on its own clock, the default) or
#: one session recorded at the same time (joined on one clock).
SESSION_MODES: tuple[str, ...] = ("separate", "together")

#: Every job state; a job in a terminal state never changes again.
JOB_STATES: tuple[str, ...] = ("queued", "running", "succeeded", "failed", "cancelled")
TERMINAL_JOB_STATES: frozenset[str] = frozenset({"succeeded", "failed", "cancelled"})


def as_json() -> dict[str, Any]:
    """Every shared name as plain JSON (served to the dashboard by ``GET /api/meta``)."""
    return {
        "metrics": [asdict(m) for m in METRICS.values()],
        "phases": [asdict(p) for p in PHASES],
        "phase_bounds_deg": list(PHASE_BOUNDS_DEG),
        "methods": [asdict(m) for m in METHODS.values()],
        "muscle_colours": dict(MUSCLE_COLOURS),
        "pso_defaults": asdict(PSO_DEFAULTS),
        "job_states": list(JOB_STATES),
        "terminal_job_states": sorted(TERMINAL_JOB_STATES),
        "front_axes": list(FRONT_AXES),
        "front_axis_text": {a: {"label": t[0], "unit": t[1]} for a, t in FRONT_AXIS_TEXT.items()},
        "floor_formulas": dict(FLOOR_FORMULAS),
        "legacy_floor_keys": dict(LEGACY_FLOOR_KEYS),
        "floor_note": FLOOR_NOTE,
        "human_constraints": [
            {"name": c, "description": HUMAN_CONSTRAINT_TEXT[c]} for c in HUMAN_CONSTRAINTS
        ],
    }
