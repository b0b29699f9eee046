"""The types every job function shares: each kind's payload, the robot spec and the result.

A job function is ``fn(payload, progress) -> JobResult``: plain data in and out (numbers,
strings, bytes, lists, dicts and NumPy arrays; nothing of the database or the web), so it can run
in a forked process or on a Dask worker and its output can be pickled back.

Each kind's payload is a ``TypedDict`` (``total=False`` where the service may leave keys out;
a missing or None option takes the library's default). The planning payloads carry the fields
of the operation's options object (``PlanOptions``, ``SimulationOptions``, ``SweepGrid``, read
back with ``from_payload``); they are listed here with the options object's value types (lists
for tuples), and ``tests/jobs/test_payload_types.py`` checks that each lists every option.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Required, TypedDict

from numpy.typing import NDArray

from app.progress import ProgressFn

__all__ = [
    "AnalysisPayload",
    "CohortPayload",
    "CohortRecording",
    "FrontPayload",
    "IdentifyPayload",
    "JobResult",
    "LogFile",
    "Payload",
    "PlanPayload",
    "PosePayload",
    "ProfilesPayload",
    "RobotOptions",
    "RobotSpec",
    "SimulationPayload",
    "SweepPayload",
    "TaskFn",
    "UploadedFile",
    "ValidatePayload",
    "robot_options",
]

#: The payload of every kind as the service layer builds and stores it (read by the runner without
#: knowing its kind; each task function takes its own ``*Payload`` below).
Payload = Mapping[str, object]


class RobotOptions(TypedDict, total=False):
    """An uploaded robot's options (stored with it; ``RobotSpec`` carries them)."""

    urdf_member: str | None  #: the URDF inside the package
    mjcf_member: str | None  #: the MJCF inside the package
    sidecar_member: str | None  #: the sidecar inside the package
    shoulder_joint: str | None  #: joint playing the shoulder (None: the loader's choice)
    elbow_joint: str | None  #: joint playing the elbow
    locks: dict[str, float] | None  #: joint -> fixed position [deg, or m for prismatic]
    base_link: str | None  #: first link of the planned chain
    tip_link: str | None  #: last link of the planned chain


def robot_options(options: Mapping[str, Any]) -> RobotOptions:
    """The robot options among ``options`` (a stored robot's JSON options or an upload's
    form fields); each absent one is None."""
    return {
        "urdf_member": options.get("urdf_member"),
        "mjcf_member": options.get("mjcf_member"),
        "sidecar_member": options.get("sidecar_member"),
        "shoulder_joint": options.get("shoulder_joint"),
        "elbow_joint": options.get("elbow_joint"),
        "locks": options.get("locks"),
        "base_link": options.get("base_link"),
        "tip_link": options.get("tip_link"),
    }


class RobotSpec(RobotOptions, total=False):
    """A robot in a payload: ``{"name"}`` for a built-in robot, or an uploaded one's files and
    options (``app.services.robots.RobotService.spec``; read by
    ``app.planning.robots.write_robot_files``/``load_robot_files``)."""

    name: Required[str]  #: the robot's name (built-in, or the uploaded robot's)
    urdf: bytes | None  #: URDF file
    urdf_name: str | None  #: the URDF's uploaded file name
    mjcf: bytes | None  #: MJCF file
    mjcf_name: str | None  #: the MJCF's uploaded file name
    package: bytes | None  #: zip with the model and its meshes
    sidecar: bytes | None  #: YAML sidecar (joint roles, motors, payload, friction)
    payload: float | None  #: payload [kg] (None: the model's default)


class _TaskPayload(TypedDict, total=False):
    """Keys shared by the payloads of tasks on one robot and one start/goal task."""

    robot: Required[RobotSpec]
    start_deg: list[float] | None  #: start angles [deg] (n,); None: the robot's curl
    goal_deg: list[float] | None  #: goal angles [deg] (n,)
    template: dict[str, object] | None  #: a ``HumanTemplate.to_dict()``, or None
    label: str | None  #: the user's name for the job


class _MethodFields(_TaskPayload, total=False):
    """The fields of ``app.planning.options.MethodOptions`` (lists for tuples)."""

    payload: float | None  #: payload [kg]; None: the spec's, then the model's default
    duration: float  #: [s]
    objective: str
    seed: int
    particles: int
    iterations: int
    peak_angle_deg: float | None
    methods: list[str] | None  #: None: the default methods
    human_constraint: str
    no_reversal: bool
    n_intervals: int
    converge: bool


class PlanPayload(_MethodFields, total=False):
    """``plan``: the fields of ``PlanOptions`` with the robot and task."""

    n_samples: int
    report_samples: int
    safety: bool


class SimulationPayload(_MethodFields, total=False):
    """``simulation``: the fields of ``SimulationOptions`` with the robot and task."""

    timestep: float  #: [s]
    feedforward: str
    natural_frequency_hz: float  #: [Hz]
    damping_ratio: float


class ProfilesPayload(PlanPayload, total=False):
    """``profiles``: classical profiles and the planning methods on one task (the methods read
    the ``PlanOptions`` fields)."""

    min_torque_change: bool  #: add the minimum-torque-change baseline (default True)
    mtc_intervals: int  #: its collocation intervals (default 100)


class SweepPayload(TypedDict, total=False):
    """``sweep``: the fields of ``SweepGrid`` with the robot, ``workers`` and the runner's
    ``cell_executor`` (``"dask"`` on a Dask worker)."""

    robot: Required[RobotSpec]
    label: str | None
    durations: list[float]  #: [s]
    payloads: list[float]  #: [kg]
    objectives: list[str]
    seed: int
    particles: int
    iterations: int
    methods: list[str]
    check_seed: int
    no_check: bool
    seeds: int
    converge: bool
    timestep: float  #: [s]
    workers: int | None  #: processes for the cells (None: the library's choice)
    cell_executor: str  #: ``"local"`` or ``"dask"``


class FrontPayload(_TaskPayload, total=False):
    """``front``: a Pareto front (``app.api.schemas`` front request, names as sent)."""

    objectives: Required[list[str]]  #: the two objectives [A, B]
    payload_mass: float | None  #: [kg]
    duration: float | None  #: [s]; None: duration is an axis or the library's default
    method: str | None
    points: int | None
    intervals: int | None  #: the library's ``n_intervals``
    tolerance: float | None
    allow_reversal: bool
    max_duration: float | None  #: [s]


class UploadedFile(TypedDict, total=False):
    """One stored recording file in an analysis or cohort payload."""

    name: Required[str]  #: the user's file name
    data: Required[bytes]
    sidecars: dict[str, bytes]  #: file name -> bytes of its BIDS sidecars
    #: reader overrides of this file (``app.recordings.read_bytes`` keywords)
    read_options: Mapping[str, Any]
    warnings: list[str]  #: what was said when it was stored (e.g. by the pose extraction)


class AnalysisPayload(TypedDict, total=False):
    """``analysis``: the files of one recording session."""

    files: Required[list[UploadedFile]]
    #: ``analyze_recordings`` keywords, ``side`` and ``landmarks`` (forwarded as keywords)
    options: Mapping[str, Any]
    read_options: Mapping[str, Any]  #: default reader overrides of the files
    echo: dict[str, object]  #: settings echoed in the result


class PosePayload(TypedDict, total=False):
    """``pose``: an uploaded video."""

    name: Required[str]  #: the user's file name
    data: Required[bytes]  #: the video
    max_seconds: Required[float]  #: [s] longest video accepted
    skeleton_frames: int  #: frames kept as skeleton images (default 4)
    scratch_dir: str | None  #: folder for the temporary copy (None: the system's)


class CohortRecording(TypedDict, total=False):
    """One recording of a cohort group."""

    recording_id: Required[int]
    subject: str | None  #: stored subject, or None
    exclude_channels: list[str]
    files: Required[list[UploadedFile]]


class CohortPayload(TypedDict):
    """``cohort``: groups of stored recordings."""

    groups: dict[str, list[CohortRecording]]  #: group name -> its recordings
    options: Mapping[str, Any]  #: the fields of ``CohortOptions`` (forwarded as keywords)


class LogFile(TypedDict):
    """An uploaded robot log."""

    name: str
    data: bytes


class ValidatePayload(TypedDict, total=False):
    """``bioplan validate``: measured against predicted torque of a robot log."""

    robot: Required[RobotSpec]
    log: Required[LogFile]
    payload: float | None  #: [kg]
    topic: str | None  #: a bag's JointState topic
    cutoff_hz: float | None  #: [Hz]
    plan: dict[str, object] | None  #: a stored plan's ``motion`` block
    series: bool  #: add the plotted series


class IdentifyPayload(TypedDict, total=False):
    """``identify``: link inertias and friction from logs of an uploaded robot."""

    robot: Required[RobotSpec]
    logs: Required[list[LogFile]]
    version: Required[str]  #: the new robot version's name
    topic: str | None
    validate_fraction: float  #: share of samples held out (default 0.2)
    cutoff_hz: float | None  #: [Hz] (None: 10)
    identify_payload: bool


class JobResult(TypedDict, total=False):
    """A job's output; the service stores it by kind (``app.services.kinds``)."""

    result: Required[dict[str, object]]  #: JSON-safe result
    #: name -> array (float64; the analysis overlays keep their own dtypes)
    arrays: dict[str, NDArray[Any]] | None
    template: dict[str, object]  #: ``HumanTemplate.to_dict()`` (analysis)
    landmarks: dict[str, object]  #: the parsed landmarks file (pose)
    skeletons: list[dict[str, object]]  #: skeleton frames with their JPEG (pose)
    sidecar: bytes  #: the identified YAML sidecar (identify)
    description: dict[str, object]  #: the new robot version described (identify)


#: The common type of :data:`app.jobs.tasks.TASKS`: a payload of any kind (each function reads
#: its own ``*Payload``; the registry casts, since the service builds the payload of the kind).
TaskFn = Callable[[Payload, ProgressFn], JobResult]
