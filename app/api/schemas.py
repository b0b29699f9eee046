"""Request and response bodies of the REST API.

Field names follow the CLI (``robot``, ``duration``, ``payload``, ``objective``, ``seed``,
``particles``, ``iterations``, ``peak_angle_deg``...), and results are the CLI's JSON, so a
script can move between ``bioplan plan --json`` and ``POST /api/plans``. SI units inside;
``*_deg`` fields are degrees.
"""

from __future__ import annotations

import json
from collections.abc import Collection
from datetime import datetime
from typing import TYPE_CHECKING, Annotated, Any, Generic, Literal, TypeVar, get_args

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    StringConstraints,
    ValidationInfo,
    field_validator,
)

from app.kinds import KindName
from app.names import (
    FRONT_AXES,
    HUMAN_CONSTRAINTS,
    JOB_STATES,
    MAX_DURATION,
    METHODS,
    MUSCLE_COLOURS,
    OBJECTIVES,
    OPTIMAL_INTERVALS,
    PHASE_BOUNDS_DEG,
    STANDARD_METHODS,
    MethodInfo,
    MetricInfo,
    PhaseInfo,
    PsoDefaults,
)
from app.options import OptionSpec, option_specs
from app.planning.options import PlanOptions
from app.recordings import FORMATS
from app.simulation.options import SimulationOptions, SweepGrid

if TYPE_CHECKING:
    Objective = str
    Site = str
    JobState = str
    MethodName = str
    HumanConstraint = str
    ReaderFormat = str
else:
    # The allowed values come from ``app.names`` (one home); OpenAPI lists them as enums.
    Objective = Literal[OBJECTIVES]
    Site = Literal[tuple(MUSCLE_COLOURS)]
    JobState = Literal[JOB_STATES]
    MethodName = Literal[tuple(METHODS)]
    HumanConstraint = Literal[HUMAN_CONSTRAINTS]
    ReaderFormat = Literal[FORMATS]
JobKind = KindName  # one home: ``app.kinds``

ROBOT_NAME = r"^[A-Za-z0-9_.\-]{1,100}$"
#: ``WIDTHxHEIGHT`` in pixels (1 to 99999 each), or blank for none.
IMAGE_SIZE = r"^\s*([1-9][0-9]{0,4}\s*[xX]\s*[1-9][0-9]{0,4})?\s*$"
T = TypeVar("T")

_strict = ConfigDict(extra="forbid")


def _no_repeats(values: list[T]) -> list[T]:
    """A list whose values are all different, else the error names the repeated ones."""
    repeated = sorted({x for x in values if values.count(x) > 1}, key=str)
    if repeated:
        raise ValueError(f"must not repeat (repeated: {repeated})")
    return values


#: A list without repeats, stated in the schema (``uniqueItems``) so that a client or a fuzzer
#: knows ``["paper", "paper"]`` is no request: no method is planned twice, no grid value swept
#: twice.
Distinct = Annotated[
    list[T], AfterValidator(_no_repeats), Field(json_schema_extra={"uniqueItems": True})
]


def blank_label_is_none(value: object) -> object:
    """A label without its surrounding blanks; an empty one is no label."""
    return (value.strip() or None) if isinstance(value, str) else value


def _types_in(annotation: object) -> set[object]:
    """Every type an annotation names, nested ones included (``list[float] | None``...)."""
    found: set[object] = {annotation}
    for arg in get_args(annotation):
        found |= _types_in(arg)
    return found


class _Request(BaseModel):
    """A request body: unknown fields are refused, and ``true``/``false`` are never read as
    numbers nor numbers as booleans (pydantic would take ``true`` for a duration of 1 s and
    ``1`` for ``true``)."""

    model_config = _strict

    @field_validator("*", mode="before")
    @classmethod
    def _booleans_are_booleans(cls, value: object, info: ValidationInfo) -> object:
        field = cls.model_fields.get(info.field_name or "")
        if field is None:
            return value
        types = _types_in(field.annotation)
        values = value if isinstance(value, list) else [value]
        numbers = bool(types & {float, int}) and bool not in types
        if numbers and any(isinstance(v, bool) for v in values):
            raise ValueError(f"{json.dumps(value)} holds a boolean: expected a number")
        flags = bool in types and not types & {float, int, str}
        if flags and any(v is not None and not isinstance(v, bool) for v in values):
            raise ValueError(f"{json.dumps(value)} is no boolean: expected true or false")
        return value


def left_out(body: BaseModel) -> set[str]:
    """The fields a request did not give (they hold their defaults)."""
    return set(type(body).model_fields) - body.model_fields_set


# ------------------------------------------------------------------- options, defined once
# The options of plan, simulate and sweep live in their dataclasses (``PlanOptions``,
# ``SimulationOptions``, ``SweepGrid``): each request field below takes its default, bounds,
# length and description from there (``option_field``), and ``options_model`` builds a whole
# request model from a dataclass (tests/test_options.py checks the two agree field by field).


def _spec(cls: type, name: str) -> OptionSpec:
    return next(s for s in option_specs(cls) if s.name == name)


def _item_type(spec: OptionSpec) -> Any:
    """The pydantic type of one value (of each item of a list option)."""
    if spec.choices is not None:
        return Literal[spec.choices]
    kind = spec.kind if spec.kind in (float, int, str, bool) else Any
    bounds: dict[str, Any] = spec.bounds() if spec.sequence else {}
    return Annotated[kind, Field(**bounds)] if bounds else kind


def option_type(cls: type, name: str) -> Any:
    """The annotation of option ``name`` of options dataclass ``cls`` in a request model."""
    spec = _spec(cls, name)
    kind = Distinct[_item_type(spec)] if spec.sequence else _item_type(spec)  # type: ignore[misc]
    return kind | None if spec.nullable else kind


def option_field(cls: type, name: str, **extra: object) -> Any:
    """A request field for option ``name`` of ``cls``: the interface default, the bounds (of
    each item, in the annotation, for a list), the list's length and the description."""
    spec = _spec(cls, name)
    default = spec.interface_default
    kwargs: dict[str, Any] = {
        "default": list(default) if isinstance(default, tuple) else default,
        "description": spec.description(),
    }
    if spec.sequence:
        if "min_items" in spec.meta:
            kwargs["min_length"] = spec.meta["min_items"]
        if "max_items" in spec.meta:
            kwargs["max_length"] = spec.meta["max_items"]
    else:
        kwargs.update(spec.bounds())
    return Field(**{**kwargs, **extra})


def options_model(
    cls: type,
    name: str,
    *,
    base: type[BaseModel] | None = None,
    doc: str | None = None,
    only: Collection[str] | None = None,
) -> type[BaseModel]:
    """A request model with every API option of options dataclass ``cls`` (``api`` not False),
    each from :func:`option_type` and :func:`option_field`, after the fields of ``base``.

    Args:
        only: the names of the options to take (in ``cls``'s order), when a request offers
            some of an operation's options (``ProfilesRequest``: the PSO's); default: all.
    """
    from pydantic import create_model

    unknown = sorted(set(only or ()) - {s.name for s in option_specs(cls)})
    if unknown:
        raise ValueError(f"{cls.__name__} has no option(s) {', '.join(unknown)}")
    spec = {
        s.name: (option_type(cls, s.name), option_field(cls, s.name))
        for s in option_specs(cls)
        if s.meta.get("api", True) and (only is None or s.name in only)
    }
    model: type[BaseModel] = create_model(  # type: ignore[call-overload]
        name, __base__=base or _Request, __doc__=doc or cls.__doc__, **spec
    )
    return model


#: The user's short name for a recording, plan or simulation (at most 200 characters).
Label = Annotated[
    Annotated[str, StringConstraints(max_length=200)] | None, BeforeValidator(blank_label_is_none)
]


#: A recording's experimental condition ("light", "heavy"), at most 100 characters.
Condition = Annotated[
    Annotated[str, StringConstraints(max_length=100)] | None, BeforeValidator(blank_label_is_none)
]


class Problem(BaseModel):
    """An error (RFC 9457 ``application/problem+json``)."""

    type: str = "about:blank"
    title: str
    status: int
    detail: str | None = None
    field: str | None = Field(default=None, description="the request field at fault")
    file: str | None = Field(default=None, description="the uploaded file at fault")
    files: list[dict[str, object]] | None = Field(
        default=None, description="every unreadable file of an upload: [{file, detail}]"
    )
    errors: list[dict[str, object]] | None = Field(default=None, description="every invalid field")
    job: dict[str, object] | None = Field(default=None, description="a job to follow or inspect")


class Page(BaseModel, Generic[T]):
    """One page of a list, newest first."""

    items: list[T]
    total: int = Field(description="items matching the filters, on all pages")
    limit: int
    offset: int


# ---------------------------------------------------------------------------------- service


class Disk(BaseModel):
    free_mb: float = Field(description="free space where the data directory is [MB]")
    total_mb: float
    used_mb: float | None = Field(
        default=None, description="space the data directory takes [MB] (against quota_mb)"
    )
    quota_mb: float | None = Field(
        default=None, description="BIOPLAN_DATA_QUOTA_MB: uploads past it are refused (413)"
    )
    ok: bool = Field(
        description="free_mb is at least BIOPLAN_MIN_FREE_MB and used_mb below quota_mb"
    )


class Health(BaseModel):
    status: Literal["ok", "degraded"]
    database: str
    disk: Disk | None = Field(description="null when the data directory cannot be read")
    executor: str
    workers: int | None
    running: int | None
    queued: int | None
    uptime_seconds: float


class Version(BaseModel):
    name: str = "bioplan"
    version: str
    api: str = "1"
    database_revision: str | None
    python: str


class Meta(BaseModel):
    """The names every page shares (``app.names``), so none is written twice."""

    model_config = ConfigDict(extra="allow")

    metrics: list[MetricInfo] = Field(description="every metric, in table order")
    phases: list[PhaseInfo] = Field(description="the A/B/C lift phases with their colours")
    phase_bounds_deg: list[float] = Field(description="default A/B and B/C bounds [deg]")
    methods: list[MethodInfo] = Field(description="planning methods with labels and colours")
    muscle_colours: dict[str, str]
    pso_defaults: PsoDefaults
    job_states: list[str]
    terminal_job_states: list[str]


class ViewerInfo(BaseModel):
    """Where the 3-D viewer listens (``enabled`` is false when the server runs none)."""

    enabled: bool
    url: str | None = None
    host: str | None = None
    port: int | None = None


# -------------------------------------------------------------------------------------- jobs


class _JobState(BaseModel):
    """What every form of a job carries."""

    id: int
    kind: JobKind
    state: JobState
    progress: float = Field(ge=0, le=1, description="fraction of the whole job done")
    stage: str = Field(description="what runs now: read, analyse, pso, simulate, sweep, ...")
    done: int = Field(ge=0, description="units of this stage done (iterations, cells, files)")
    of: int = Field(ge=1, description="units this stage has in all")
    best: float | None = Field(description="best objective value so far (optimisers), or null")
    message: str = Field(description="one line for people (never parsed: read the fields)")
    error: str | None = Field(description="why it failed (state 'failed')")
    attempts: int = Field(description="how many times it was started")
    label: str | None = Field(description="the user's short name for the result")
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    queue_seconds: float | None = Field(description="time from submission to (last) start [s]")
    run_seconds: float | None = Field(description="running time so far or in all [s]")
    result_url: str
    events_url: str


class Job(_JobState):
    """A background job (analysis, pose, plan, simulation, sweep, profiles or cohort)."""

    params: dict[str, object] = Field(description="the request, with the CLI's field names")


class JobSummary(_JobState):
    """A job as the job drawer shows it (``GET /api/events/jobs``): no request, one line."""

    about: str = Field(description="what it works on: 'curtain_wall_6dof, 4 kg, 1 s, abs_work'")
    recording_id: int | None = Field(description="the recording an analysis or pose job reads")


# -------------------------------------------------------------------------------- recordings
# Recordings, videos and analyses (F2). Ranges below are those the readers and the analysis
# accept, so a request the API takes does not fail later in its job.

#: Lowest EMG rate accepted [Hz]: the band-pass starts at 20 Hz and surface EMG carries
#: 50-150 Hz, which a lower rate cannot hold.
EMG_RATE_MIN_HZ = 100.0
#: Highest sampling rate any reader accepts [Hz].
RATE_MAX_HZ = 100_000.0

SessionMode = Literal["separate", "together"]
FileRole = Literal["recording", "sidecar", "video"]
if TYPE_CHECKING:
    SiteOrNone = str
else:  # a site, or "none" to unmap a channel the reader mapped
    SiteOrNone = Literal[(*MUSCLE_COLOURS, "none")]
ChannelName = Annotated[str, Field(min_length=1, max_length=200)]
#: Channel label -> EMG site (``"none"`` unmaps a channel the reader mapped), 200 at most.
MuscleMap = Annotated[dict[ChannelName, SiteOrNone], Field(max_length=200)]
#: Channel labels (500 at most).
ChannelNames = Annotated[list[ChannelName], Field(max_length=500)]


class ChannelInfo(BaseModel):
    id: int
    name: str
    kind: str
    unit: str
    rate: float = Field(description="sampling rate [Hz]")
    start: float = Field(description="time of the first sample [s]")
    site: str | None
    n_samples: int
    dims: int = Field(description="1 for scalar signals, 3 for landmarks and markers")
    duration: float = Field(description="[s]")
    flat: bool = Field(description="constant (an unused input): left out of the analysis")
    excluded: bool = Field(description="left out of the analysis by the user (PATCH)")


class RateCheckInfo(BaseModel):
    """An implausible stored EMG rate (``app.recordings.rate_check``) and the one-request fix."""

    file: str = Field(description="the file whose EMG rate looks wrong")
    stored_rate_hz: float
    suggested_rate_hz: float
    median_frequency_hz: float = Field(description="EMG spectral median at the stored rate")
    channels: list[str]
    reason: str
    rerun: dict[str, object] = Field(
        description="the request that re-reads the files at the suggested rate and reruns the"
        " analysis: {method, url, json}"
    )


class PoseStatus(BaseModel):
    """The newest pose extraction of an uploaded video."""

    job: Job
    result: dict[str, object] | None = Field(
        description="frames, frames_with_pose, fps, image_size, warnings, landmarks_file_id"
    )


class FileInfo(BaseModel):
    id: int
    original_name: str
    format: str
    size: int = Field(description="[bytes]")
    sha256: str
    metadata: dict[str, object]
    role: FileRole = Field(
        description="recording (read and analysed), sidecar (of parent_id), video (to pose)"
    )
    parent_id: int | None = Field(
        description="a sidecar's EDF; the video a landmarks file was extracted from"
    )
    warnings: list[str] = Field(description="what the reader noted (flat channels, rates...)")
    rate_check: RateCheckInfo | None
    video: dict[str, object] | None = Field(
        description="a video's container: duration_s, width, height, frames, fps_hz"
    )
    pose: PoseStatus | None = Field(description="a video's newest pose extraction")
    channels: list[ChannelInfo]


class RecordingSummary(BaseModel):
    id: int
    subject: str | None
    task: str | None
    load_kg: float | None
    notes: str | None
    label: str | None = Field(description="the user's short name for the session")
    condition: str | None = Field(
        default=None, description="the experimental condition (a cohort groups by it)"
    )
    created_at: datetime
    n_files: int
    formats: list[str]
    file_names: list[str]
    session: SessionMode = Field(description="separate trials, or recorded together")


class RecordingDetail(RecordingSummary):
    options: dict[str, object] = Field(
        description="reader options (rate, emg_rate, muscle_map, image_size, frame_rate, format)"
        " and exclude_channels, as uploaded or last changed"
    )
    updated_at: datetime | None
    rate_check: RateCheckInfo | None = Field(description="the first file's implausible EMG rate")
    warnings: list[str] = Field(description="every file's reader warnings, named by file")
    frames_url: str | None = Field(description="the video frames with the detected skeleton")
    files: list[FileInfo]
    pose_jobs: list[Job] = Field(description="pose extractions started by this request")
    analysis_job: Job | None = Field(
        default=None, description="the analysis this request started (PATCH with analyse)"
    )


class RecordingPatch(_Request):
    """Change a stored recording; the files are read again with the new options (no upload).

    A field left out keeps its value; ``null`` clears an option.
    """

    subject: str | None = Field(default=None, max_length=200)
    task: str | None = Field(default=None, max_length=200)
    notes: str | None = Field(default=None, max_length=10000)
    label: Label = Field(default=None, description="a short name; null or blank: none")
    condition: Condition = Field(
        default=None, description="the experimental condition; null or blank: none"
    )
    load_kg: float | None = Field(default=None, ge=0, le=100, description="load lifted [kg]")
    session: SessionMode | None = Field(default=None, description="separate or together")
    muscle_map: MuscleMap | None = Field(
        default=None, description='channel label -> site ("none" unmaps); replaces the stored map'
    )
    exclude_channels: ChannelNames | None = Field(
        default=None, description="channels left out of the analysis"
    )
    emg_rate: float | None = Field(
        default=None, ge=EMG_RATE_MIN_HZ, le=RATE_MAX_HZ, description="true EMG rate [Hz]"
    )
    rate: float | None = Field(
        default=None, ge=1, le=RATE_MAX_HZ, description="rate of files that state none [Hz]"
    )
    frame_rate: float | None = Field(default=None, gt=0, le=1e4, description="pose [fps]")
    image_size: (
        tuple[Annotated[int, Field(ge=1, le=100000)], Annotated[int, Field(ge=1, le=100000)]] | None
    ) = Field(default=None, description="[width, height] of the video MediaPipe ran on [px]")
    format: ReaderFormat | None = Field(
        default=None, description="reader to use instead of detecting it"
    )
    analyse: bool = Field(
        default=True,
        description="rerun the analysis now (options of the newest analysis, files as changed)",
    )


class SignalSeries(BaseModel):
    label: str
    t: list[float] = Field(description="sample times [s]")
    y: list[float | None] = Field(description="values (null where the sample is missing)")


class Signal(BaseModel):
    channel_id: int
    name: str
    file: str
    kind: str
    unit: str
    n_samples: int = Field(description="samples in the stored channel")
    n_points: int = Field(description="points returned per series")
    series: list[SignalSeries]


class Signals(BaseModel):
    recording_id: int
    points: int
    channels: list[Signal]


class SkeletonFrameInfo(BaseModel):
    k: int = Field(description="index in this list; the image is at url")
    file_id: int = Field(description="the video")
    video: str = Field(description="the video's file name")
    frame: int = Field(description="0-based frame index in the video")
    time_s: float = Field(description="its time in the video [s]")
    url: str
    person: int | None = Field(
        default=None,
        description="whom the skeleton is on: 0 the tracked person, 1, 2... someone or"
        " something else the track jumped to, -1 unknown (None: not recorded)",
    )
    quality: float | None = Field(
        default=None, description="the frame's detection quality, 0-1 (the better arm's score)"
    )
    note: str | None = Field(default=None, description="whom it shows, in words")


class SkeletonFrames(BaseModel):
    recording_id: int
    frames: list[SkeletonFrameInfo]


# -------------------------------------------------------------------------------- analyses


#: An elbow angle strictly between straight and folded [deg].
_OpenAngle = Annotated[float, Field(gt=0, lt=180)]


class AnalysisRequest(_Request):
    """Analyse the files of one recording (``bioplan analyze``). Options left out take the
    recording's (emg_rate, muscle_map, exclude_channels, session, load)."""

    recording_id: int = Field(ge=1, le=2**31 - 1)
    emg_rate: float | None = Field(
        default=None, ge=EMG_RATE_MIN_HZ, le=RATE_MAX_HZ, description="override [Hz]"
    )
    muscle_map: MuscleMap | None = Field(
        default=None, description="channel label -> EMG site; overrides the upload's"
    )
    exclude_channels: ChannelNames | None = Field(
        default=None, description="channels left out; default: the recording's"
    )
    phase_bounds_deg: tuple[_OpenAngle, _OpenAngle] = Field(
        default=PHASE_BOUNDS_DEG, description="A/B and B/C elbow-flexion bounds [deg], in order"
    )
    body_mass: float = Field(default=75.0, ge=20, le=250, description="[kg]")
    body_height: float = Field(default=1.75, ge=1.0, le=2.5, description="[m]")
    load_mass: float | None = Field(
        default=None, ge=0, le=100, description="[kg]; default: the recording's load_kg, else 12"
    )
    together: bool | None = Field(
        default=None,
        description="the files were recorded at the same time (one clock); default: the"
        " recording's session mode",
    )
    offset: Annotated[float, Field(ge=-3600, le=3600)] | Literal["auto"] | None = Field(
        default=None,
        description='t_emg = t_pose + offset [s]; "auto" estimates it by cross-correlation',
    )
    side: Literal["auto", "left", "right"] = Field(
        default="auto", description="which arm of pose data (auto: the better visible one)"
    )
    landmarks: str | None = Field(
        default=None,
        max_length=1000,
        description="which markers are the shoulder, elbow and wrist: a preset (plugin_gait_right,"
        " plugin_gait_left, opencap_right, opencap_left, pose2sim_right, pose2sim_left, or"
        " without _right/_left) or 'shoulder=RSHO,elbow=RELB,wrist=RWRA'; default: automatic",
    )
    keep_low_quality_lifts: bool = Field(
        default=False,
        description="keep lifts on mostly low-quality pose frames (another person tracked, arm"
        " poorly seen, implausible limb lengths) in the template; default: flagged, left out",
    )

    @field_validator("landmarks")
    @classmethod
    def _landmarks(cls, v: str | None) -> str | None:
        from app.analysis.pose import landmark_spec

        if v is None or not v.strip():
            return None
        landmark_spec(v)  # a ValueError naming the presets
        return v.strip()

    @field_validator("phase_bounds_deg")
    @classmethod
    def _ordered(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not 0 < v[0] < v[1] < 180:
            raise ValueError("phase bounds must satisfy 0 < A/B < B/C < 180 deg")
        return v


class AnalysisSummary(BaseModel):
    """What a list shows of a finished analysis: the template's origin, lifts, every warning."""

    n_lifts: int
    template_source: str = Field(description='"N lift(s) with kinematics" or "paper default: ..."')
    is_paper_default: bool = Field(description="no recorded lift shaped the template")
    template_lifts: int = Field(description="lifts with kinematics in the template")
    peak_velocity_angle_deg: float
    session: SessionMode
    files: list[dict[str, object]] = Field(
        description="per file: file, format, lifts, lifts_with_kinematics, warnings, rate_check"
    )
    warnings: list[str] = Field(description="every warning: the analysis' and each file's")
    settings: dict[str, object] = Field(description="every option, as used")


class AnalysisOut(BaseModel):
    id: int
    recording_id: int | None
    job: Job
    summary: AnalysisSummary | None = Field(description="null until the job succeeded")
    result: dict[str, object] | None = Field(description="the JSON of `bioplan analyze --json`")
    template: dict[str, object] | None = Field(description="the HumanTemplate (planner input)")


class PoseOut(BaseModel):
    """A pose-extraction job of a video and, once it succeeded, what it found."""

    id: int
    recording_id: int | None
    video_file_id: int | None
    job: Job
    result: dict[str, object] | None


# ----------------------------------------------------------------------------------- plans


#: A task's start or goal joint angles [deg] (the service checks there is one per joint).
JointAnglesDeg = list[Annotated[float, Field(ge=-720, le=720)]] | None


def _task_angles(end: str) -> Any:
    """The request field of a task's ``end`` (``"start"`` or ``"goal"``) joint angles [deg]."""
    return Field(
        default=None, max_length=32, description=f"{end} joint angles (default: the curl task's)"
    )


def _payload_field() -> Any:
    """The request field of the payload [kg] a task carries (None: the robot's own)."""
    return Field(default=None, ge=0, le=10000, description="payload [kg] (default: the robot's)")


def _template_analysis_field() -> Any:
    """The request field naming a finished analysis whose human template a task takes."""
    return Field(
        default=None, ge=1, le=2**31 - 1, description="use the template of this finished analysis"
    )


class _RobotTask(_Request):
    """The robot and the task of a plan or a simulation; their options are added from
    ``PlanOptions`` / ``SimulationOptions`` (:func:`options_model`)."""

    label: Label = Field(default=None, description="a short name for the result (not planned)")
    robot: str = Field(
        default="curtain_wall_6dof",
        pattern=ROBOT_NAME,
        description="built-in or uploaded robot name",
    )
    payload: float | None = _payload_field()
    start_deg: JointAnglesDeg = _task_angles("start")
    goal_deg: JointAnglesDeg = _task_angles("goal")
    template: dict[str, object] | None = Field(
        default=None, description="a HumanTemplate (as written by `bioplan analyze --out`)"
    )
    template_analysis_id: int | None = _template_analysis_field()


class _SweepTarget(_Request):
    """The robot and the workers of a sweep; the grid and the cells' options are added from
    ``SweepGrid`` (:func:`options_model`)."""

    robot: str = Field(default="curtain_wall_6dof", pattern=ROBOT_NAME)
    workers: int | None = Field(
        default=None,
        ge=1,
        le=64,
        description="processes for the cells on the local runner (default: the runner's "
        "workers); on Dask every cell is a task on the cluster",
    )


if TYPE_CHECKING:  # what type checkers see; the models themselves are generated below

    class _MethodFields(_RobotTask):
        duration: float
        objective: str
        seed: int
        particles: int
        iterations: int
        peak_angle_deg: float | None
        methods: list[str]
        human_constraint: str
        no_reversal: bool
        n_intervals: int
        converge: bool

    class PlanRequest(_MethodFields):
        n_samples: int

    class SimulationRequest(_MethodFields):
        pass

    # The grid's fields are ``SweepGrid``'s, read through it (``SweepGrid.from_payload``):
    # type checkers see the robot and the workers only.
    SweepRequest = _SweepTarget

else:
    # Every option field (default, range, choices, unit, help) comes from its dataclass: a new
    # option there is a new request field here, with nothing written twice.
    PlanRequest = options_model(
        PlanOptions,
        "PlanRequest",
        base=_RobotTask,
        doc="Plan the standard and the bio-inspired trajectory (``bioplan plan``).",
    )
    SimulationRequest = options_model(
        SimulationOptions,
        "SimulationRequest",
        base=_RobotTask,
        doc="Plan, then simulate both trajectories in MuJoCo (``bioplan simulate``).",
    )
    SweepRequest = options_model(
        SweepGrid,
        "SweepRequest",
        base=_SweepTarget,
        doc="Savings over a grid (``bioplan sweep``).",
    )


#: Most points of one front requested through the API.
MAX_FRONT_POINTS = 25

if TYPE_CHECKING:
    FrontAxis = str
else:
    FrontAxis = Literal[FRONT_AXES]


class FrontRequest(_Request):
    """The Pareto front between two metrics, or a metric and the duration (``bioplan front``),
    with the quintic's, the paper's and the jerk-limited points beside it."""

    label: Label = Field(default=None, description="a short name for the result (not planned)")
    robot: str = Field(
        default="curtain_wall_6dof", pattern=ROBOT_NAME, description="built-in or uploaded robot"
    )
    payload_mass: float | None = _payload_field()
    # Before ``duration`` and ``max_duration``: their checks read it.
    objectives: Distinct[FrontAxis] = Field(
        min_length=2,
        max_length=2,
        description="A,B: minimise A with B <= epsilon; two different axes (a metric or duration)",
        examples=[["abs_work", "peak_power"]],
    )
    duration: float | None = Field(
        default=None,
        gt=0,
        le=MAX_DURATION,
        description="motion time [s] (default 1 s); none when duration is an axis",
    )
    method: Literal["bound", "human_optimal"] = Field(
        default="bound",
        description="bound: the limits only; human_optimal: also the elbow's human-like peak",
    )
    points: int = Field(
        default=9, ge=2, le=MAX_FRONT_POINTS, description="points of the front, ends included"
    )
    intervals: int = Field(
        default=OPTIMAL_INTERVALS,
        ge=8,
        le=400,
        description="coarsest constant-jerk mesh; every point is refined from it to convergence",
    )
    tolerance: float = Field(
        default=1e-3,
        gt=0,
        lt=1,
        description="mesh refinement stops when the objective changes by less than this fraction",
    )
    allow_reversal: bool = Field(
        default=False, description="let joints move against their stroke (default: none does)"
    )
    max_duration: float | None = Field(
        default=None,
        gt=0,
        le=MAX_DURATION,
        description="the duration axis' longest duration [s] (default: 3 x the shortest "
        "feasible); only with duration as an axis",
    )
    start_deg: JointAnglesDeg = _task_angles("start")
    goal_deg: JointAnglesDeg = _task_angles("goal")
    template: dict[str, object] | None = Field(
        default=None, description="a HumanTemplate (human_optimal's; default: the paper's)"
    )
    template_analysis_id: int | None = _template_analysis_field()

    @field_validator("duration")
    @classmethod
    def _no_duration_on_a_duration_axis(
        cls, value: float | None, info: ValidationInfo
    ) -> float | None:
        if value is not None and "duration" in (info.data.get("objectives") or ()):
            raise ValueError(
                "duration is an axis of objectives: expected no fixed duration (max_duration "
                "sets the axis' longest)"
            )
        return value

    @field_validator("max_duration")
    @classmethod
    def _max_duration_needs_the_axis(
        cls, value: float | None, info: ValidationInfo
    ) -> float | None:
        objectives = info.data.get("objectives")
        if value is not None and objectives is not None and "duration" not in objectives:
            raise ValueError("max_duration given but duration is not an axis of objectives")
        return value


class _ProfilesTask(_Request):
    """The robot, the task and the baselines of a profiles comparison; the planning methods'
    duration, objective and PSO budget are added from ``PlanOptions`` (:func:`options_model`)."""

    robot: str = Field(
        default="curtain_wall_6dof", pattern=ROBOT_NAME, description="built-in or uploaded robot"
    )
    payload: float | None = _payload_field()
    start_deg: JointAnglesDeg = _task_angles("start")
    goal_deg: JointAnglesDeg = _task_angles("goal")
    min_torque_change: bool = Field(
        default=True, description="also solve the minimum-torque-change baseline (IPOPT)"
    )
    mtc_intervals: int = Field(
        default=100, ge=8, le=400, description="intervals of the minimum-torque-change solve"
    )
    # Not ``PlanOptions.methods``: a comparison of the profiles alone plans none ([]).
    methods: Distinct[MethodName] = Field(
        default=list(STANDARD_METHODS),
        max_length=len(METHODS),
        description="planning methods listed beside the profiles ([] = none; default: all)",
    )


#: The ``PlanOptions`` a profiles comparison offers (the planning methods beside the profiles).
PROFILES_OPTIONS = ("duration", "objective", "seed", "particles", "iterations")

if TYPE_CHECKING:
    ProfilesRequest = _ProfilesTask
else:
    ProfilesRequest = options_model(
        PlanOptions,
        "ProfilesRequest",
        base=_ProfilesTask,
        only=PROFILES_OPTIONS,
        doc="Classical profiles, minimum torque change and the planning methods on one task\n"
        "(``bioplan profiles``).",
    )


# ---------------------------------------------------------------------------------- cohorts

#: Longest regular expression a request may give (it runs on file names in the job).
_PATTERN_MAX = 200


def _cohort_options_model() -> type[BaseModel]:
    from pydantic import create_model

    from app.analysis.cohort import CohortError, CohortOptions

    def checked(self: BaseModel) -> BaseModel:
        try:  # what no schema states (a regular expression that compiles), in the library's words
            CohortOptions(**self.model_dump())
        except CohortError as exc:
            name = next((n for n in type(self).model_fields if n in str(exc)), None)
            raise ValueError(f"{name or 'options'}: {exc}") from None
        return self

    def regex(value: str) -> str:
        import re

        try:
            re.compile(value)
        except re.error as exc:
            raise ValueError(f"{value!r} is not a regular expression ({exc})") from None
        return value

    from pydantic import model_validator

    # Types, defaults, bounds and choices from the options' fields, as every options model.
    spec = {
        s.name: (
            option_type(CohortOptions, s.name),
            option_field(
                CohortOptions,
                s.name,
                **({"max_length": _PATTERN_MAX} if s.name == "subject_pattern" else {}),
            ),
        )
        for s in option_specs(CohortOptions)
    }
    model: type[BaseModel] = create_model(  # type: ignore[call-overload]
        "CohortOptionsIn",
        __base__=_Request,
        __doc__="Options of a cohort comparison (``app.analysis.cohort.CohortOptions``).",
        __validators__={
            "_regex": field_validator("subject_pattern")(regex),
            "_library_checks": model_validator(mode="after")(checked),
        },
        **spec,
    )
    return model


if TYPE_CHECKING:
    CohortOptionsIn = BaseModel
else:
    CohortOptionsIn = _cohort_options_model()

#: A group (condition) name (one of blanks only is refused by the service, naming ``groups``).
GroupName = Annotated[str, StringConstraints(min_length=1, max_length=100)]
#: The id of a stored row (recording, log...): what the database's integer key can hold.
StoredId = Annotated[int, Field(ge=1, le=2**31 - 1)]
RecordingId = StoredId
#: Most groups and recordings per group of one cohort.
COHORT_MAX_GROUPS = 20
COHORT_MAX_PER_GROUP = 500


class CohortRequest(_Request):
    """Compare groups of stored recordings (``bioplan cohort``): explicit ``groups`` of
    recording ids, or the recordings (``recording_ids``, default: all) grouped by their
    ``condition``. A recording of several files (trials on their own clocks) gives one
    measured recording per file."""

    label: Label = Field(default=None, description="a short name for the result")
    groups: (
        Annotated[
            dict[
                GroupName,
                Annotated[list[RecordingId], Field(min_length=1, max_length=COHORT_MAX_PER_GROUP)],
            ],
            Field(min_length=2, max_length=COHORT_MAX_GROUPS),
        ]
        | None
    ) = Field(
        default=None,
        description="group name -> recording ids (at least two groups, each recording in one)",
    )
    group_by: Literal["condition"] | None = Field(
        default=None,
        description='"condition": group the recordings by their condition (the default when no'
        " groups are given); not beside groups",
    )
    recording_ids: Distinct[RecordingId] | None = Field(
        default=None,
        min_length=2,
        max_length=COHORT_MAX_GROUPS * COHORT_MAX_PER_GROUP,
        description="the recordings grouped by condition (default: every recording that has one);"
        " not beside groups",
    )
    options: CohortOptionsIn = Field(
        default_factory=lambda: CohortOptionsIn(), description="options of the comparison"
    )


class CohortOut(BaseModel):
    """A cohort comparison: the job, the groups it compared and, once it succeeded, the
    result (``bioplan cohort --json`` and ``recording_ids``, aligned with ``recordings``)."""

    id: int
    label: str | None = Field(description="the user's short name for it")
    groups: dict[str, list[int]] = Field(description="group name -> recording ids compared")
    job: Job
    result: dict[str, object] | None


class CohortOptionInfo(BaseModel):
    """One option of a cohort comparison as the page offers it (from ``CohortOptions``)."""

    name: str
    default: object
    help: str
    unit: str | None = None
    choices: list[str] | None = None
    low: float | None = Field(default=None, description="exclusive lower bound")
    high: float | None = Field(default=None, description="exclusive upper bound")
    minimum: int | None = Field(default=None, description="inclusive lower bound (integers)")
    type: str = Field(description="number, integer or string")


class ResultOut(BaseModel):
    """A plan, simulation or sweep: the job and, once it succeeded, the CLI's JSON."""

    id: int
    robot: str
    label: str | None = Field(description="the user's short name for it")
    job: Job
    result: dict[str, object] | None


class LabelPatch(_Request):
    """Rename a plan or simulation."""

    label: Label = Field(description="the new short name; null or blank: none")


class ArraysOut(BaseModel):
    """Arrays for plotting (SI units), downsampled to at most ``points`` samples."""

    id: int
    points: int
    arrays: dict[str, list[object]]


class MetricDiff(BaseModel):
    a: object
    b: object
    diff: object = Field(description="b - a")
    diff_pct: object = Field(description="100 (b - a) / |a|")


class PlanComparison(BaseModel):
    a: int
    b: int
    conditions: dict[str, dict[str, object]]
    standard: dict[str, MetricDiff]
    optimized: dict[str, MetricDiff]
    improvement_pct: dict[str, dict[str, object]]


# ----------------------------------------------------------------------------------- robots


class RobotJoint(BaseModel):
    """One movable joint of a robot's URDF."""

    name: str
    kind: str = Field(description="revolute, continuous or prismatic")
    unit: str = Field(description="rad or m")
    lower: float | None = Field(description="[rad or m]; null = unbounded")
    upper: float | None = Field(description="[rad or m]; null = unbounded")
    velocity: float | None = Field(description="[rad/s or m/s]")
    effort: float | None = Field(description="[Nm or N]")
    locked: bool
    lock_value: float | None = Field(description="[rad or m] when locked")
    role: str | None = Field(description="shoulder, elbow or null")


class RobotFile(BaseModel):
    """A file of an uploaded robot package."""

    path: str = Field(description="relative to the package")
    bytes: int
    role: str = Field(description="urdf, mjcf, sidecar, mesh or other")


class RobotInfo(BaseModel):
    name: str
    builtin: bool
    joint_names: list[str]
    q_min: list[float | None] = Field(description="[rad]; null = unbounded")
    q_max: list[float | None] = Field(description="[rad]; null = unbounded")
    qd_max: list[float | None] = Field(description="[rad/s]; null = unbounded")
    tau_max: list[float | None] = Field(description="[Nm]; null = unbounded")
    payload: float | None = Field(description="default payload [kg]")
    has_mjcf: bool
    urdf_name: str | None = None
    mjcf_name: str | None = None
    # ---- onboarding (issue 12); None for robots stored before these fields existed ----------
    shoulder_joint: str | None = Field(default=None, description="joint human shoulder maps to")
    elbow_joint: str | None = Field(default=None, description="joint human elbow maps to")
    locks: dict[str, float] = Field(default={}, description="locked joints [rad, or m]")
    all_joint_names: list[str] | None = Field(default=None, description="free and locked")
    joints: list[RobotJoint] | None = Field(default=None, description="every movable joint")
    motors_modelled: bool | None = Field(
        default=None, description="false: electrical metrics are reported as not modelled"
    )
    default_start_deg: list[float] | None = Field(default=None, description="curl task start")
    default_goal_deg: list[float] | None = Field(default=None, description="curl task goal")
    files: list[RobotFile] | None = Field(default=None, description="stored files (uploads)")
    package_dirs: list[str] | None = Field(
        default=None, description="folders package:// mesh paths resolve in (uploads)"
    )
    missing_meshes: list[str] | None = Field(
        default=None,
        description="mesh references of the URDF that resolve to no file: the viewer draws "
        "those links without bodies (upload a package zip holding them)",
    )
    default_task_safety: dict[str, object] | None = Field(
        default=None,
        description="the safety check of the default task's quintic, run at upload: {ok "
        "(null: not checked), checked, reason, min_clearance [m], duration [s], findings "
        "(count), worst (the deepest finding: links, kind, obstacle, depth [m], "
        "deepest_time [s]), summary}",
    )
    identified_from: dict[str, object] | None = Field(
        default=None,
        description="a version identified from robot logs: {robot (the nominal one), log_ids, "
        "job_id}; null for a robot as uploaded",
    )


# ------------------------------------------------------------------------------- robot logs


class RobotLogOut(BaseModel):
    """A stored robot log: what was read and how it compared with the robot's model at upload."""

    id: int
    robot: str = Field(description="the robot it was recorded on")
    file: str
    format: str = Field(description="ros2_bag, ur_rtde_csv or csv")
    bytes: int
    topic: str | None = None
    label: str | None = None
    created_at: datetime
    samples: int
    rate_hz: float = Field(description="[Hz] (resampled onto an even grid when uneven)")
    duration_s: float = Field(description="[s]")
    notes: list[str] = Field(description="repairs made while reading, how torque was obtained")
    joint_names: list[str]
    validation: dict[str, object] = Field(
        description="joints {name: {rms_measured, residual_rms [Nm], r2}}, abs_work {measured, "
        "predicted} [J], filter, electrical_energy when currents and motors exist"
    )


class IdentifyRequest(_Request):
    """Identify a robot's inertias and friction from stored logs of it (``bioplan identify``);
    the result is stored as a new robot version beside the nominal one."""

    log_ids: list[StoredId] = Field(
        min_length=1, max_length=20, description="stored logs of one robot"
    )
    version: str | None = Field(
        default=None,
        pattern=ROBOT_NAME,
        description="name of the identified robot (default: <robot>-identified[-k])",
    )
    validate_fraction: float = Field(
        default=0.2, ge=0.0, lt=0.9, description="last fraction of each log held back"
    )
    cutoff_hz: float | None = Field(
        default=None, gt=0, le=1000, description="zero-phase low-pass cutoff [Hz] (default 10)"
    )
    identify_payload: bool = Field(
        default=False, description="identify a point payload instead of the last link's inertia"
    )
    label: str | None = Field(default=None, max_length=200)


class IdentificationOut(BaseModel):
    """An identification: the job, the robot and its new version's name and, once it
    succeeded, the result (``bioplan identify --json``)."""

    id: int
    robot: str
    version: str = Field(description="the robot the identified model is stored as")
    job: Job
    result: dict[str, object] | None
