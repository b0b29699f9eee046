"""The typed result contract from NumPy to the browser: one pydantic model per result kind.

Each model names (at least) the fields the dashboard reads, with units; every result block also
keeps the fields it does not name (``extra="allow"``), so the CLI's ``--json`` passes through
unchanged. The get and list routes serve them as their response models, so they are in the
OpenAPI document, and ``scripts/js_types.py`` writes the dashboard's JSDoc/TypeScript types
(``app/frontend/js/api_types.d.ts``) from that document.

Fields a result may lack are optional; the routes serve them with ``exclude_unset``, so a field
absent from a stored result stays absent in the answer (it is not invented as ``null``). A field
the library added after results were first stored is optional too, so an older stored result is
still served (not a 500). For analyses, cohorts and identifications every key of a fresh
result is a declared field and every declared field is written
(``tests/api/test_result_contract_analyses.py``).
"""

from __future__ import annotations

from typing import Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    SerializerFunctionWrapHandler,
    ValidatorFunctionWrapHandler,
    model_serializer,
    model_validator,
)

from app.api.schemas import (
    AnalysisOut,
    CohortOut,
    IdentificationOut,
    Meta,
    PoseOut,
    ResultOut,
)

__all__ = [
    "RESULT_OUT_MODELS",
    "AnalysisResult",
    "AnalysisResultOut",
    "CohortResult",
    "CohortResultOut",
    "ComparisonView",
    "FrontOut",
    "FrontResult",
    "HumanTemplateOut",
    "IdentificationResult",
    "IdentificationResultOut",
    "MetaOut",
    "PlanOut",
    "PlanResult",
    "PoseResult",
    "PoseResultOut",
    "ProfilesOut",
    "ProfilesResult",
    "SimulationOut",
    "SweepOut",
    "SweepResult",
    "TrajectoryCurves",
]

#: (T,) or (T, n) samples; null where a value is not finite.
Series = list[float | None]
Series2 = list[list[float | None]]
#: A metric's value or change: one number, one per joint (``peak_torque``), or null.
Value = float | list[float | None] | None


class _Open(BaseModel):
    """A result block: its named fields checked, any other kept as stored, in the stored order
    (pydantic would put the named fields first; clients compare the JSON key by key)."""

    model_config = ConfigDict(extra="allow")
    _order: tuple[str, ...] = PrivateAttr(default=())

    @model_validator(mode="wrap")
    @classmethod
    def _remember_order(cls, data: Any, handler: ValidatorFunctionWrapHandler) -> Any:
        out = handler(data)
        if isinstance(data, dict) and isinstance(out, _Open):
            out._order = tuple(data)
        return out

    # No return annotation on purpose: pydantic would read it as the serialized schema and the
    # OpenAPI document would lose the fields.
    @model_serializer(mode="wrap")
    def _in_stored_order(self, handler: SerializerFunctionWrapHandler):  # type: ignore[no-untyped-def]
        out = handler(self)
        if not self._order or not isinstance(out, dict):
            return out
        rank = {key: i for i, key in enumerate(self._order)}
        return dict(sorted(out.items(), key=lambda item: rank.get(item[0], len(rank))))


# ------------------------------------------------------------------------------------- meta


class AxisText(BaseModel):
    """How a front's axis is printed where the shared metric's words do not fit."""

    label: str
    unit: str


class HumanConstraintText(BaseModel):
    """One human constraint of ``human_optimal`` (``app.names.HUMAN_CONSTRAINT_TEXT``)."""

    name: str
    description: str


class MetaOut(Meta):
    """``GET /api/meta``: the shared names, the floors' formulas and the front's axes."""

    front_axes: list[str] = Field(description="every axis a front can trade, in the CLI's order")
    front_axis_text: dict[str, AxisText] = Field(
        description="the axes a front measures in its own way (or no metric names): their words"
    )
    floor_formulas: dict[str, str] = Field(
        description="each physical floor's formula as printed, by floor or metric name"
    )
    legacy_floor_keys: dict[str, str] = Field(
        description="metric name -> the floor's name in older results (delta_potential...)"
    )
    floor_note: str = Field(description="what the floors mean, one sentence for the pages")
    human_constraints: list[HumanConstraintText] = Field(
        description="human_optimal's constraints, in the order offered, with what each asks"
    )


# ------------------------------------------------------------------------ plans, simulations


class SafetyFinding(_Open):
    """One contact of a method's trajectory (``app.planning.safety.Finding.to_dict``)."""

    method: str
    time: float = Field(description="first time in contact [s]")
    kind: str = Field(description="self, plane or obstacle")
    links: list[str]
    obstacle: str | None = Field(description='"mount plane" or the obstacle; null for self')
    depth: float = Field(description="deepest penetration [m]")


class Safety(_Open):
    """The collision and workspace check (``app.planning.safety.SafetyReport.to_dict``)."""

    checked: bool
    ok: bool | None = Field(description="null when not checked")
    reason: str | None = Field(default=None, description="why it was not checked (only then)")
    min_clearance: float | None = Field(
        default=None, description="smallest signed distance of any checked pair [m]"
    )
    findings: list[SafetyFinding] = Field(default_factory=list)


class Optimizer(_Open):
    """The paper's PSO run (``app.planning.pso``)."""

    iterations: int
    stopped_early: bool = False
    history: list[float] | None = Field(default=None, description="best objective per iteration")


class MethodResult(_Open):
    """One method's metrics [SI] and checks (``app.planning.methods.MethodResult.to_dict``);
    each metric of ``/api/meta`` is a field by its name."""

    label: str | None = None
    peak_torque: list[float | None] = Field(description="peak |torque| per joint [Nm]")
    peak_velocity_angle_deg: float | None = None
    improvement_pct: dict[str, Value] | None = None
    share_of_achievable_pct: float | None = None
    solver: dict[str, Any] | None = None


class Conditions(_Open):
    """What a plan or simulation was asked: objective, payload [kg], duration [s], template."""

    objective: str | None = None
    payload: float | None = None
    duration: float | None = None
    template: str | None = None
    target_peak_velocity_angle_deg: float | None = None


class Planned(_Open):
    """A simulation's planned result's facts."""

    optimizer: Optimizer | None = None


class PlanResult(_Open):
    """A plan's (``bioplan plan --json``) or a simulation's (``bioplan simulate --json``)
    result: every method's metrics, the physical floors, the changes against the quintic."""

    joint_names: list[str] | None = Field(default=None, description="plans only")
    duration: float | None = Field(default=None, description="[s]; plans only")
    standard: MethodResult
    optimized: MethodResult | None = None
    methods: dict[str, MethodResult] | None = Field(
        default=None, description="every method by name (older results: standard/optimized)"
    )
    floors: dict[str, Value] | None = Field(
        default=None, description="physical floors [SI] by metric or floor name; null: none"
    )
    improvement_pct: dict[str, Value] | None = None
    share_of_achievable_pct: dict[str, Value] | None = None
    target_peak_velocity_angle_deg: float | None = None
    optimizer: Optimizer | None = None
    planned: Planned | None = None
    conditions: Conditions | None = None
    warnings: list[str] | None = None
    safety: Safety | None = None


class PlanOut(ResultOut):
    """A plan: its job and, once it succeeded, its result."""

    result: PlanResult | None  # type: ignore[assignment]


class SimulationOut(ResultOut):
    """A simulation: its job and, once it succeeded, its result."""

    result: PlanResult | None  # type: ignore[assignment]


# ---------------------------------------------------------------------------------- profiles


class ProfilesResult(_Open):
    """Classical profiles beside the planning methods on one task (``bioplan profiles``)."""

    robot: str
    duration: float = Field(description="[s]")
    payload: float | None = Field(default=None, description="[kg]")
    objective: str | None = None
    profiles: dict[str, dict[str, Any]] = Field(description="metrics [SI] by profile name")
    methods: dict[str, MethodResult] | None = None
    floors: dict[str, Value] | None = None


class ProfilesOut(ResultOut):
    result: ProfilesResult | None  # type: ignore[assignment]


# ------------------------------------------------------------------------------------ sweeps


class SweepTable(_Open):
    """One objective's and metric's (durations x payloads) table of the paper's method."""

    change_pct: Series2 = Field(description="change against the quintic [%]; null: no cell")
    classification: list[list[str]] = Field(description="each cell's checked verdict")


class SweepCell(_Open):
    """One (duration, payload, objective) cell of a sweep."""

    duration: float = Field(description="[s]")
    payload: float = Field(description="[kg]")
    objective: str
    status: str = Field(description="ok, or why the cell has no result")
    methods_change_pct: dict[str, dict[str, Value]] | None = Field(
        default=None, description="method -> metric -> change against the quintic [%]"
    )


class SweepResult(_Open):
    """A sweep (``bioplan sweep --json``): durations x payloads x objectives."""

    robot: str
    durations: list[float] = Field(description="[s]")
    payloads: list[float] = Field(description="[kg]")
    objectives: list[str]
    metrics: list[str]
    tables: dict[str, dict[str, SweepTable]] = Field(description="objective -> metric -> table")
    cells: list[SweepCell]


class SweepOut(ResultOut):
    result: SweepResult | None  # type: ignore[assignment]


# ------------------------------------------------------------------------------------ fronts


class FrontConvergence(_Open):
    """The mesh refinement of one optimal-control solve of a front."""

    sequence: list[dict[str, Any]] = Field(description="each mesh: n_intervals, objective/error")
    relative_change: float | None
    converged: bool
    final_intervals: int
    tolerance: float
    end_grading: int = Field(
        0, description="graded ends: pieces added at each segment's end intervals (0: equal)"
    )


class FrontPoint(_Open):
    """One point of a front; each axis of ``front_axes`` is a field by its name [SI]."""

    id: str
    peak_torques: dict[str, float | None] = Field(description="peak |torque| by joint [Nm]")
    human_likeness: float | None
    epsilon: float | None = Field(description="the bound on B; null at the ends")
    end: str | None = Field(description='"A end", "B end" or null')
    knee: bool
    convergence: FrontConvergence
    violations: list[str]


class FrontReference(_Open):
    """A reference method's axis values at the front's duration, or why it failed there."""

    error: str | None = None


class ShortestDuration(_Open):
    duration: float = Field(description="[s]")
    infeasible_below: float | None = Field(description="[s]")


class FrontResult(_Open):
    """A Pareto front (``Front.to_dict`` with the service's ``references`` and ``methods``)."""

    robot: str
    payload_mass: float = Field(description="[kg]")
    objectives: list[str] = Field(description="[A, B]: A is minimised with B <= epsilon")
    method: str
    duration: float | None = Field(description="the fixed duration [s]; null when an axis")
    rules: list[str]
    knee: str | None
    points: list[FrontPoint]
    shortest_duration: ShortestDuration | None
    dropped: list[dict[str, Any]]
    solves: int
    seconds: float
    notes: list[str]
    references: dict[str, FrontReference] | None = None
    methods: list[str] | None = None


class FrontOut(ResultOut):
    result: FrontResult | None  # type: ignore[assignment]


# ------------------------------------------------------------------------------------ cohorts


class CohortRecording(_Open):
    """One measured recording (``app.analysis.cohort.RecordingMeasures.to_dict``)."""

    group: str = Field(description="its group (condition)")
    source: str = Field(description="file name")
    subject: str
    subject_from: str = Field(description="where the subject label came from")
    measures: dict[str, float | None] = Field(
        description="measure -> value in the result's ``units``; null: not measurable"
    )
    missing: dict[str, str] = Field(description="measure -> why it has no value")
    activation_order: list[str] = Field(description="the recording's consensus onset order")
    warnings: list[str]


class CohortMeasureSummary(_Open):
    """One measure over a group's recordings, in the measure's unit (``MeasureSummary``)."""

    n: int = Field(description="recordings with a value")
    missing: int = Field(description="recordings without one")
    mean: float | None
    sd: float | None = Field(description="sample SD (ddof=1); null for n < 2")
    median: float | None
    q1: float | None = Field(description="first quartile (linear interpolation)")
    q3: float | None = Field(description="third quartile")
    iqr: float | None = Field(description="q3 - q1")


class CohortLiftOrders(_Open):
    """The most common activation order over the group's single lifts."""

    most_common: list[str]
    count: int = Field(description="lifts with that order")
    n: int = Field(description="lifts with an order of at least two muscles")
    frequency: float | None = Field(description="count / n; null when n = 0")


class CohortOrderSummary(_Open):
    """A group's activation orders (``OrderSummary.to_dict``)."""

    most_common: list[str] = Field(description="the most common recording order; [] if none")
    count: int = Field(description="recordings with that order")
    n: int = Field(description="recordings with an order of at least two muscles")
    frequency: float | None = Field(description="count / n; null when n = 0")
    orders: dict[str, int] = Field(description='order ("a > b > c") -> recordings, most first')
    lifts: CohortLiftOrders
    mean_onset_s: dict[str, float] = Field(description="muscle -> mean onset latency [s]")


class CohortGroup(_Open):
    """One group of a comparison (``GroupSummary.to_dict``)."""

    n: int = Field(description="recordings measured")
    subjects: list[str]
    measures: dict[str, CohortMeasureSummary] = Field(description="measure -> its summary")
    activation_order: CohortOrderSummary


class CohortTest(_Open):
    """One measure compared between two groups (``TestResult.to_dict``); effects are the first
    group minus the second."""

    measure: str
    unit: str
    groups: list[str] = Field(description="[a, b]")
    design: str = Field(description='"paired" or "independent"')
    n: list[int] = Field(description="values used per group (pairs: both the same)")
    test: str | None = Field(description="welch_t, mann_whitney_u, paired_t, wilcoxon; null")
    rule: str = Field(description="why this test (normality checks or the user's choice)")
    statistic: float | None
    p: float | None = Field(description="two-sided p-value; null when not tested")
    p_adjusted: float | None = Field(description="p after the correction")
    significant: bool | None = Field(description="p_adjusted < alpha")
    effect_name: str | None = Field(description="hedges_g, hedges_g_z or rank_biserial")
    effect: float | None = Field(description="null when undefined (no spread)")
    skipped: str | None = Field(description="why there is no test; null when tested")


class CohortPairing(_Open):
    """How two groups are compared: design, the subjects paired, and why."""

    groups: list[str] = Field(description="[a, b]")
    design: str = Field(description='"paired" or "independent"')
    subjects: list[str] = Field(description="the subjects paired (paired design only)")
    why: str


class CohortCorrection(_Open):
    """The multiple-comparison correction over every test reported."""

    method: str = Field(description="holm, bonferroni, fdr_bh or none")
    family_size: int = Field(description="tests corrected over")
    alpha: float
    statement: str = Field(description="what was done, one sentence")


class CohortResult(_Open):
    """A cohort comparison (``bioplan cohort --json``, ``CohortResult.to_dict``)."""

    recordings: list[CohortRecording] = Field(description="every recording's measures")
    groups: dict[str, CohortGroup] = Field(description="group name -> summary, in order given")
    tests: list[CohortTest] = Field(description="one per measure and pair of groups")
    pairings: list[CohortPairing] = Field(description="one per pair of groups")
    correction: CohortCorrection
    units: dict[str, str] = Field(description="measure -> unit, in the table's order")
    subject_rule: str = Field(description="how subjects were found")
    options: dict[str, object] = Field(description="the CohortOptions used, by name")
    warnings: list[str] = Field(description="what the analyses or the comparison assumed")
    recording_ids: list[int] | None = Field(
        default=None, description="the service's: recording id of each of ``recordings``"
    )


class CohortResultOut(CohortOut):
    """A cohort comparison: the job, its groups and, once it succeeded, the result."""

    result: CohortResult | None  # type: ignore[assignment]


# ---------------------------------------------------------------------------------- analyses


class HumanTemplateOut(_Open):
    """The HumanTemplate, the planner's input (``app.planning.human_template.HumanTemplate``;
    what ``bioplan analyze --out`` writes and ``plan --template`` reads)."""

    peak_velocity_angle_deg: float = Field(
        description="elbow flexion where the elbow's velocity peaks, mean over lifts [deg]"
    )
    peak_velocity_angle_sd_deg: float = Field(description="its SD over lifts [deg]")
    phase_bounds_deg: tuple[float, float] = Field(description="(A/B, B/C) elbow flexion [deg]")
    peak_velocity_time_fraction: float | None = Field(
        description="time of the velocity peak as a fraction of the lift; null: unknown"
    )
    normalized_time: list[float] = Field(description="(K,) grid in [0, 1] of the profiles")
    velocity_mean: list[float] = Field(description="(K,) elbow velocity over its peak")
    velocity_sd: list[float] = Field(description="(K,)")
    acceleration_mean: list[float] = Field(description="(K,) elbow acceleration over its peak")
    acceleration_sd: list[float] = Field(description="(K,)")
    activation_order: list[str] = Field(description="EMG sites in onset order")
    emg_peak_time_fraction: dict[str, float] = Field(
        description="site -> time of its EMG envelope peak as a fraction of the lift"
    )
    n_lifts: int = Field(description="lifts the kinematic fields rest on; 0: paper defaults")
    source: str = Field(description='"N lift(s) with kinematics" or "paper default: ..."')
    peak_velocity_range_fraction: float | None = Field(
        default=None, description="where the peak lies within each lift's range, mean"
    )
    peak_velocity_range_fraction_sd: float | None = None
    lift_range_deg: tuple[float, float] | None = Field(
        default=None, description="mean (start, top) elbow flexion of the lifts [deg]"
    )
    files: list[str] | None = Field(default=None, description="recordings it was built from")
    emg_lifts: int | None = Field(default=None, description="lifts the EMG timing rests on")
    assumptions: list[str] | None = Field(default=None, description="what had to be assumed")


class AnalysisPhase(_Open):
    """One phase of one lift with its EMG and kinematics (``PhaseStats.to_dict``)."""

    name: str = Field(description='"A", "B" or "C"')
    part: str = Field(description='"concentric" or "eccentric"')
    start_s: float = Field(description="[s] on the file's clock")
    end_s: float = Field(description="[s]")
    duration_s: float = Field(description="[s]")
    emg_mean: dict[str, float | None] = Field(
        description="muscle -> mean envelope over the phase / its peak over the recording"
    )
    emg_peak: dict[str, float | None] = Field(description="muscle -> peak envelope, same scale")
    peak_velocity_deg_s: float | None = Field(description="largest |elbow velocity| [deg/s]")
    peak_acceleration_deg_s2: float | None = Field(description="[deg/s^2]")


class PhaseEnergetics(_Open):
    """One phase's energy flow (``app.analysis.energetics.PhaseEnergetics.to_dict``)."""

    phase: str = Field(description='"A", "B" or "C"')
    part: str
    start: float = Field(description="[s]")
    end: float = Field(description="[s]")
    delta_kinetic_j: float | None = Field(description="[J]")
    delta_potential_j: float | None = Field(description="[J]")
    work_j: list[float | None] = Field(description="(2,) shoulder, elbow work [J]")
    positive_work_j: list[float | None] = Field(description="(2,) [J]")
    kinetic_to_potential_j: float | None = Field(description="[J]")
    peak_power_w: float | None = Field(description="[W]")


class LiftEnergetics(_Open):
    """A lift's metrics and per-phase flow on the arm model (``Energetics.to_dict``)."""

    metrics: dict[str, Value] = Field(
        description="tau_sq [N^2 m^2 s], abs_work, pos_work, delta_potential [J], peak_power,"
        " min_peak_power [W], peak_torque (2,) [Nm], duration [s]"
    )
    phases: list[PhaseEnergetics]


class LiftQuality(_Open):
    """How much of a lift's pose is low quality."""

    low_quality_share: float = Field(description="share of its frames that are low quality")
    low_quality: bool = Field(description="over the limit: left out of the template")
    reasons: dict[str, int] = Field(description="reason -> frames")


class AnalysisLift(_Open):
    """One lift with everything measured on it (``LiftReport.to_dict``); times [s] on the
    file's clock, angles elbow flexion [deg]."""

    index: int = Field(description="1-based within its file")
    source: str = Field(description='what found it: "angle" or "emg"')
    start_s: float
    top_s: float
    end_s: float
    concentric_s: list[float] = Field(description="[start, top] [s]")
    hold_s: list[float] | None = Field(default=None, description="[start, end] [s]")
    eccentric_s: list[float] = Field(description="[start, end] [s]")
    start_angle_deg: float | None
    top_angle_deg: float | None
    end_angle_deg: float | None
    peak_velocity_deg_s: float | None
    peak_velocity_angle_deg: float | None = Field(description="flexion at the velocity peak")
    peak_velocity_time_fraction: float | None
    peak_velocity_range_fraction: float | None = None
    kinematics_rejected: str | None = Field(
        default=None, description="why its kinematics do not shape the template; null: used"
    )
    phases: list[AnalysisPhase] = Field(description="empty for EMG-only lifts")
    onsets_s: dict[str, float | None] = Field(
        description="muscle -> onset after the lift's start [s] (negative: before)"
    )
    activation_order: list[str]
    emg_peak_s: dict[str, float | None] = Field(description="muscle -> envelope peak time [s]")
    emg_peak_time_fraction: dict[str, float | None] = Field(
        description="muscle -> envelope peak as a fraction of the concentric part"
    )
    emg_peak_after_velocity_peak_s: dict[str, float | None] | None = Field(
        default=None, description="muscle -> envelope peak minus velocity peak time [s]"
    )
    energetics: LiftEnergetics | None = Field(description="null without angles or dynamics")
    quality: LiftQuality | None = Field(default=None, description="null without per-frame quality")


class EmgChannelInfo(_Open):
    """One processed EMG channel of a file."""

    channel: str = Field(description="name in the file")
    rate_hz: float = Field(description="[Hz]")
    unit: str
    onsets_s: list[list[float]] = Field(description="(M, 2) onset/offset times [s]")
    saturated_fraction: float = Field(description="share of samples flagged as clipped")


class PoseQualitySummary(_Open):
    """Per-frame pose quality, counted (video and MediaPipe landmarks only)."""

    frames: int
    low_quality_frames: int
    reasons: dict[str, int] = Field(description="reason -> frames")
    persons_tracked: int
    switch_frames: list[int] = Field(description="frames where the track changed person")
    other_person_frames: int
    min_visibility: float
    length_tolerance: float = Field(description="relative limb-length tolerance")


class PoseInfo(_Open):
    """A file's arm angles."""

    side: str = Field(description="left, right or unspecified")
    rate_hz: float = Field(description="[Hz]")
    samples: int
    valid_fraction: float
    gaps_s: list[list[float]] = Field(description="(G, 2) gaps in the elbow angle [s]")
    elbow_range_deg: list[float] | None = Field(description="[min, max] [deg]")
    quality: PoseQualitySummary | None = Field(default=None, description="null: no such data")


class RateCheckOut(_Open):
    """An implausible stored EMG rate and the likely one (``RateCheck.to_dict``)."""

    stored_rate_hz: float = Field(description="the rate the file states [Hz]")
    suggested_rate_hz: float = Field(description="where the spectrum looks like EMG [Hz]")
    median_frequency_hz: float = Field(description="spectral median at the stored rate [Hz]")
    channels: list[str]
    reason: str


class AnalysedFile(_Open):
    """Everything measured on one file or merged session (``RecordingAnalysis.to_dict``)."""

    source: str = Field(description="file name(s)")
    format: str = Field(description="detected format(s)")
    offset_s: float = Field(description="t_emg = t_pose + offset [s]")
    emg: dict[str, EmgChannelInfo] = Field(description="muscle (or channel name) -> channel")
    pose: PoseInfo | None = Field(description="null without pose")
    lifts: list[AnalysisLift]
    warnings: list[str]
    rate_check: RateCheckOut | None = Field(default=None, description="null when plausible")


class AnalysisSettings(_Open):
    """Every option of an analysis as used (``analyze_recordings``), and the reader options
    the CLI or the service echo."""

    emg_rate_hz: float | None = Field(description="the EMG rate given [Hz]; null: the file's")
    muscle_map: dict[str, str] = Field(description="channel -> site")
    exclude_channels: list[str] | None = None
    phase_bounds_deg: list[float] = Field(description="[A/B, B/C] [deg]")
    body_mass_kg: float
    body_height_m: float
    load_mass_kg: float
    offset_s: float | str | None = Field(description='[s], "auto" or null (same clock)')
    session: str | None = Field(default=None, description='"separate" or "together"')
    emg: dict[str, object] = Field(description="EMG filter: band_hz, lowpass_hz, method")
    pose: dict[str, object] = Field(description="pose options given")
    keep_low_quality_lifts: bool | None = None
    frame_rate_hz: float | None = Field(default=None, description="reader's frame rate [Hz]")
    image_size_px: list[int] | None = Field(default=None, description="[width, height] [px]")
    side: str | None = Field(default=None, description="auto, left or right")
    rate_hz: float | None = Field(default=None, description="the service's reader rate [Hz]")
    format: str | None = Field(default=None, description="the service's reader format")


class AnalysisResult(_Open):
    """An analysis (``bioplan analyze --json``, ``AnalysisResult.to_dict``)."""

    files: list[AnalysedFile] = Field(description="per file (or merged session)")
    n_lifts: int
    activation_order: list[str] = Field(description="consensus onset order over all lifts")
    template: HumanTemplateOut
    settings: AnalysisSettings
    warnings: list[str]


class AnalysisResultOut(AnalysisOut):
    """An analysis: the job and, once it succeeded, its summary, result and template."""

    result: AnalysisResult | None = Field(  # type: ignore[assignment]
        description="the JSON of `bioplan analyze --json`"
    )
    template: HumanTemplateOut | None = Field(  # type: ignore[assignment]
        description="the HumanTemplate (planner input)"
    )


class PoseResult(_Open):
    """A video's pose extraction: frames, frame rate [Hz] and warnings."""

    fps: float | None = Field(default=None, description="[Hz]")
    frames: int | None = None
    frames_with_pose: int | None = None
    warnings: list[str] = Field(default_factory=list)


class PoseResultOut(PoseOut):
    result: PoseResult | None  # type: ignore[assignment]


# ---------------------------------------------------------------------------- identification


class IdentifiedLink(_Open):
    """A link's identified inertial parameters, physically consistent."""

    mass: float = Field(description="[kg]")
    com: list[float] = Field(description="(3,) centre of mass in the joint frame [m]")
    inertia: list[float] = Field(
        description="(6,) ixx ixy ixz iyy iyz izz about the centre of mass [kg m^2]"
    )


class JointFriction(_Open):
    """A joint's identified friction and torque offset."""

    viscous: float = Field(description="[Nm s/rad]")
    coulomb: float = Field(description="[Nm]")
    offset: float = Field(description="[Nm]")


class IdentifiedPayload(_Open):
    """A point payload identified instead of the last link's inertia."""

    mass: float = Field(description="[kg]")
    com: list[float] = Field(description="(3,) in the body's frame [m]")
    body: str


class TorqueFit(_Open):
    """How well the model predicts one joint's torque."""

    rms_measured: float | None = Field(description="rms of the measured torque [Nm]")
    residual_rms: float | None = Field(description="rms of measured - predicted [Nm]")
    r2: float | None = Field(description="R^2; null without spread")


class FilterNote(_Open):
    """The low-pass filter applied before identifying."""

    kind: str
    cutoff_hz: float = Field(description="[Hz]")
    delay_s: float = Field(description="[s] (zero-phase: 0)")


class IdentificationResult(_Open):
    """An identification (``bioplan identify --json``, ``Identification.to_dict``)."""

    joints: list[str]
    n_base_parameters: int = Field(description="identifiable base parameters of the links")
    base_parameters: list[float] = Field(description="(n_base,) least squares, unconstrained")
    links: dict[str, IdentifiedLink] = Field(description="link -> its identified inertia")
    friction: dict[str, JointFriction] = Field(description="joint -> friction and offset")
    payload: IdentifiedPayload | None = Field(description="null unless a payload was asked")
    fit: dict[str, TorqueFit] = Field(description="joint -> fit on the identified part")
    held_back: dict[str, TorqueFit] = Field(description="joint -> fit on the held-back part")
    samples: int = Field(description="regression samples used")
    filter: FilterNote
    notes: list[str] = Field(description="how the logs were read and repaired")
    seconds: float = Field(description="wall time [s]")
    version: str | None = Field(
        default=None, description="the service's: the robot version it is stored as"
    )


class IdentificationResultOut(IdentificationOut):
    """An identification: the job, the robot version and, once it succeeded, the result."""

    result: IdentificationResult | None  # type: ignore[assignment]


# --------------------------------------------------------------------- the Compare page


class TrajectoryCurves(_Open):
    """One trajectory's curves on the comparison's grid [SI]."""

    q: Series2 = Field(description="(T, n) joint angles [rad]")
    qd: Series2 = Field(description="(T, n) joint velocities [rad/s]")
    qdd: Series2 = Field(description="(T, n) joint accelerations [rad/s^2]")
    tau: Series2 = Field(description="(T, n) joint torques [Nm]")
    power: Series = Field(description="(T,) total absolute power [W]")
    energy: Series = Field(description="(T,) its running integral [J]")
    joint_power: Series2 = Field(description="(T, n) |tau_j qd_j| per joint [W]")
    joint_energy: Series2 = Field(description="(T, n) its running integral (trapezoid) [J]")
    elbow_flexion_deg: Series
    elbow_velocity_normalised: Series = Field(description="(T,) elbow velocity over its peak")


class HumanCurves(_Open):
    elbow_velocity_normalised: Series


class ComparisonCurves(_Open):
    t: list[float] = Field(description="(T,) sample times [s], finite")
    joint_names: list[str]
    standard: TrajectoryCurves
    optimized: TrajectoryCurves
    human: HumanCurves | None


class Payload(_Open):
    mass: float = Field(description="[kg]")
    body: str
    com: list[float] = Field(description="[m]")
    size: list[float] = Field(description="[m]")


class PhaseTimes(_Open):
    standard: list[float | None] = Field(description="A/B and B/C crossing times [s]")
    optimized: list[float | None]


class MethodPair(_Open):
    standard: str = Field(description="the solid robot's method")
    optimized: str = Field(description="the ghost robot's method")


class Lift(_Open):
    index: int | None = None
    file: str | None = None
    start_s: float | None = None
    top_s: float | None = None


class HumanInfo(_Open):
    shown: bool
    note: str | None = None
    lift: Lift | None = None


class TemplateInfo(_Open):
    source: str | None = None
    angle_text: str | None = None


class ViewerAddress(_Open):
    enabled: bool
    host: str | None = None
    url: str | None = None


class ComparisonView(_Open):
    """``GET /api/viewer/comparisons/{kind}/{id}``: what the Compare page draws."""

    robot: str
    joint_names: list[str]
    elbow_joint: int
    duration: float = Field(description="[s]")
    payload: Payload
    phase_times: PhaseTimes
    methods: MethodPair
    planned: list[str] = Field(description="every planned method, in column order")
    floor_tolerance: float | None = Field(
        default=None, description="relative: within it a value is at its floor"
    )
    template: TemplateInfo | None = None
    human: HumanInfo | None = None
    curves: ComparisonCurves
    result: PlanResult
    viewer: ViewerAddress
    exports: dict[str, str]


#: The response model of each stored result kind's get and list routes.
RESULT_OUT_MODELS: dict[str, type[BaseModel]] = {
    "plan": PlanOut,
    "simulation": SimulationOut,
    "profiles": ProfilesOut,
    "sweep": SweepOut,
    "front": FrontOut,
    "cohort": CohortResultOut,
    "analysis": AnalysisResultOut,
    "pose": PoseResultOut,
    "identify": IdentificationResultOut,
}
