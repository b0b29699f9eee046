"""The typed result contract from NumPy to the browser: one pydantic model per result kind.

Each model names (at least) the fields the dashboard reads, with units; every result block also
keeps the fields it does not name (``extra="allow"``), so the CLI's ``--json`` passes through
unchanged. The get and list routes serve them as their response models, so they are in the
OpenAPI document, and ``scripts/js_types.py`` writes the dashboard's JSDoc/TypeScript types
(``app/frontend/js/api_types.d.ts``) from that document.

Fields a result may lack are optional; the routes serve them with ``exclude_unset``, so a field
absent from a stored result stays absent in the answer (it is not invented as ``null``).
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
    "AnalysisResultOut",
    "CohortResult",
    "CohortResultOut",
    "ComparisonView",
    "FrontOut",
    "FrontResult",
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


# --------------------------------------------------------------------- cohorts, recordings


class CohortResult(_Open):
    """A cohort comparison (``bioplan cohort --json``)."""

    groups: Any = Field(description="the groups compared, with their recordings")
    units: Any = None
    warnings: list[str] = Field(default_factory=list)


class CohortResultOut(CohortOut):
    result: CohortResult | None  # type: ignore[assignment]


class AnalysisResultOut(AnalysisOut):
    """An analysis (its result block is ``bioplan analyze --json``, left open)."""


class PoseResult(_Open):
    """A video's pose extraction: frames, frame rate [Hz] and warnings."""

    fps: float | None = Field(default=None, description="[Hz]")
    frames: int | None = None
    frames_with_pose: int | None = None
    warnings: list[str] = Field(default_factory=list)


class PoseResultOut(PoseOut):
    result: PoseResult | None  # type: ignore[assignment]


class IdentificationResultOut(IdentificationOut):
    """An identification (its result block is ``bioplan identify --json``, left open)."""


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
