"""Job functions: plain data in, plain data out, no database, no web framework.

These are the only places where the service layer calls the science packages, and they import
them inside the functions, so the API process starts without loading NumPy-heavy code and a Dask
worker only needs ``app`` on its path. Every job function has the signature
``fn(payload: dict, progress: ProgressFn) -> dict``; ``progress`` takes a structured
``app.progress.Progress`` and may raise to stop the job (cancellation on Dask).

Robot specs in payloads are ``{"name": str}`` for a built-in robot, or ``{"name", "urdf",
"urdf_name", "mjcf", "mjcf_name", "payload"}`` for an uploaded one (file contents as bytes).
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from app.errors import BioPlanError
from app.names import PSO_DEFAULTS
from app.planning.jsonsafe import json_safe
from app.progress import ProgressFn, no_progress, report

TaskFn = Callable[[dict[str, Any], ProgressFn], dict[str, Any]]


def _entry(module: str, name: str) -> Any:
    """``module.name``, imported now (the science packages are imported only when needed)."""
    import importlib

    return getattr(importlib.import_module(module), name)


def preload() -> None:
    """Import the science packages (used by the local runner's fork server and Dask workers).

    Job processes are forked from a server that already ran this, so a job starts in
    milliseconds instead of importing NumPy, SciPy and Pinocchio each time.
    """
    import importlib

    modules = (
        "app.recordings",
        "app.analysis",
        "app.planning",
        "app.planning.planner",
        "app.planning.robots",
        "app.planning.dynamics",
        "app.simulation",
        "pinocchio",
        "mujoco",
        "scipy.signal",
    )
    for name in modules:
        importlib.import_module(name)


# ------------------------------------------------------------------------------ recordings


def parse_recording(
    data: bytes,
    filename: str,
    options: dict[str, Any],
    sidecars: dict[str, bytes] | None = None,
) -> dict[str, Any]:
    """Read one uploaded file into plain data (run inline by the upload route).

    Args:
        data: the file's bytes.
        filename: the user's file name (used for format detection and error messages).
        options: reader overrides ``rate, emg_rate, muscle_map, image_size, frame_rate, format``.
        sidecars: file name -> bytes of the files uploaded beside it that belong to it (BIDS
            ``_channels.tsv`` / ``_emg.json`` of an EDF).

    Returns:
        ``{"format", "metadata", "channels": [{"name", "kind", "unit", "rate", "start",
        "site", "data" ((N,) or (N, 3) float64), "confidence", "time"}]}``.

    Raises:
        app.recordings.types.RecordingError: the file cannot be read (message names the file).
    """
    read_bytes = _entry("app.recordings", "read_bytes")
    kwargs = {k: v for k, v in options.items() if v is not None}
    if kwargs.get("image_size") is not None:
        kwargs["image_size"] = tuple(kwargs["image_size"])
    rec = read_bytes(data, filename, sidecars=sidecars or None, **kwargs)
    channels = []
    for ch in rec.channels.values():
        channels.append(
            {
                "name": ch.name,
                "kind": ch.kind,
                "unit": ch.unit,
                "rate": float(ch.rate),
                "start": float(ch.start),
                "site": ch.site,
                "data": np.asarray(ch.data, dtype=np.float64),
                "confidence": None if ch.confidence is None else np.asarray(ch.confidence),
                "time": None if ch.time is None else np.asarray(ch.time),
            }
        )
    return {"format": rec.format, "metadata": json_safe(rec.metadata), "channels": channels}


def _read_file(f: dict[str, Any], read_options: dict[str, Any]) -> Any:
    """One file of an analysis payload as a Recording, with the warnings stored beside it
    (e.g. what the pose extraction of its video said) in front of the reader's."""
    read_bytes = _entry("app.recordings", "read_bytes")
    options = {k: v for k, v in f.get("read_options", read_options).items() if v is not None}
    if options.get("image_size") is not None:
        options["image_size"] = tuple(options["image_size"])
    rec = read_bytes(f["data"], f["name"], sidecars=f.get("sidecars") or None, **options)
    extra = [str(w) for w in f.get("warnings", ())]
    if extra:
        rec.metadata["warnings"] = extra + list(rec.metadata.get("warnings", []))
    return rec


def _analysis_options(payload: dict[str, Any]) -> dict[str, Any]:
    """Keyword options of ``analyze_recordings`` from an analysis payload."""
    options = {k: v for k, v in payload.get("options", {}).items() if v is not None}
    if "phase_bounds_deg" in options:
        options["phase_bounds_deg"] = tuple(options["phase_bounds_deg"])
    side = options.pop("side", None)
    if side not in (None, "auto"):
        options["pose_options"] = {**options.get("pose_options", {}), "side": side}
    return options


def analyse(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
    """Analyse the files of one recording session.

    Payload: ``files`` [{"name", "data": bytes, "sidecars" {name: bytes}, "read_options"
    (reader overrides of this file; default the payload's ``read_options``), "warnings"}],
    ``options``: those of ``analyze_recordings`` (``emg_rate, muscle_map, exclude_channels,
    phase_bounds_deg, body_mass, body_height, load_mass, together, offset``) and ``side``
    (``auto``, ``left``, ``right``); ``echo``: more settings to echo in the result (the
    reader options the files were read with).

    Returns:
        ``{"result": AnalysisResult.to_dict(), "template": HumanTemplate.to_dict(), "arrays":
        AnalysisOverlays.to_arrays()}``: the overlays are what the recording detail page
        plots, decimated here once so the page never runs the analysis itself.
    """
    analyze_recordings = _entry("app.analysis", "analyze_recordings")

    files = payload["files"]
    read_options = dict(payload.get("read_options", {}))
    recordings = []
    for i, f in enumerate(files):
        report(progress, "read", i, len(files), fraction=0.4 * i / max(len(files), 1),
               message=f"reading {f['name']}")  # fmt: skip
        recordings.append(_read_file(f, read_options))
    report(progress, "analyse", 0, 1, fraction=0.4, message="analysing")
    result = analyze_recordings(recordings, **_analysis_options(payload))
    result.settings.update(payload.get("echo", {}))
    report(progress, "analyse", 1, 1, fraction=0.95, message="decimating the plot overlays")
    overlays = _entry("app.analysis", "AnalysisOverlays").from_result(result)
    report(progress, "done", 1, 1, message="analysed")
    return {
        "result": json_safe(result.to_dict()),
        "template": result.template.to_dict(),
        "arrays": overlays.to_arrays(),
    }


# ------------------------------------------------------------------------------------ videos


class _Terminated(Exception):
    """SIGTERM arrived (the job was cancelled): unwind, so temporary files go and the pose
    worker is killed, instead of dying on the spot."""


@contextmanager
def _unwind_on_sigterm() -> Iterator[None]:
    """Turn SIGTERM into :class:`_Terminated` while the block runs (main thread only)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: Any) -> None:
        raise _Terminated(f"terminated by signal {signum}")

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _pid_alive(pid: int) -> bool:
    import os

    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process holds that pid now
        return True
    return True


def _scratch(scratch_dir: str | None) -> str | None:
    """The folder for this job's temporary copy of the video (created), after removing what
    jobs killed outright (a server crash: SIGKILL, no unwinding) left there.

    Each job's folder is named ``pose-<pid>-...``: a folder whose process is gone is stale.
    """
    if scratch_dir is None:
        return None
    import re
    import shutil

    folder = Path(scratch_dir)
    folder.mkdir(parents=True, exist_ok=True)
    for entry in folder.glob("pose-*"):
        m = re.match(r"pose-(\d+)-", entry.name)
        if m and not _pid_alive(int(m.group(1))):
            shutil.rmtree(entry, ignore_errors=True)
    return str(folder)


def extract_pose_job(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
    """Pose landmarks of an uploaded video (``app.recordings.extract_pose``), read back as a
    MediaPipe file.

    Payload: ``name`` (the user's file name), ``data`` (the video's bytes), ``max_seconds``,
    ``skeleton_frames``, ``scratch_dir`` (folder for the temporary copy; None: the system's).

    Progress: stage ``pose``, frames done of the video's frames; then ``read``.

    Returns:
        ``{"result": {"source", "fps", "image_size", "frames", "frames_with_pose",
        "warnings", "skeleton_frames"}, "landmarks": {"name", "data", "format", "metadata",
        "channels"} (a parsed file, as the upload stores it), "skeletons": [{"frame", "time",
        "jpeg"}]}``.

    Raises:
        RecordingError: no pose environment, a corrupt video, one longer than ``max_seconds``,
            or one without a person; nothing is left behind.
    """
    import os

    extract_pose = _entry("app.recordings", "extract_pose")
    name = str(payload["name"])
    suffix = Path(name).suffix.lower()
    suffix = suffix if suffix in (".mp4", ".mov", ".avi", ".m4v") else ".mp4"
    scratch = _scratch(payload.get("scratch_dir"))
    with (
        _unwind_on_sigterm(),
        tempfile.TemporaryDirectory(prefix=f"pose-{os.getpid()}-", dir=scratch) as tmp,
    ):
        video = Path(tmp) / f"video{suffix}"  # a fixed name: the user's is never a path
        video.write_bytes(payload["data"])
        extraction = extract_pose(
            video,
            name=name,
            max_seconds=float(payload["max_seconds"]),
            skeleton_frames=int(payload.get("skeleton_frames", 4)),
            progress=progress,
        )
    report(progress, "read", 0, 1, fraction=0.97, message="reading the landmarks")
    return _pose_output(extraction)


def _pose_output(extraction: Any) -> dict[str, Any]:
    """The plain-data result of :func:`extract_pose_job`."""
    parsed = parse_recording(
        extraction.landmarks_json, extraction.landmarks_name, {"format": "mediapipe_json"}
    )
    summary = {
        "source": extraction.source,
        "fps": extraction.fps,
        "image_size": list(extraction.image_size),
        "frames": extraction.frames,
        "frames_with_pose": extraction.frames_with_pose,
        "warnings": list(extraction.warnings),
        "skeleton_frames": len(extraction.skeletons),
    }
    metadata = dict(parsed["metadata"])
    metadata["video"] = {k: summary[k] for k in ("source", "frames", "frames_with_pose")}
    metadata["pose_warnings"] = list(extraction.warnings)
    metadata["warnings"] = list(extraction.warnings) + list(metadata.get("warnings", []))
    return {
        "result": json_safe(summary),
        "landmarks": {
            "name": extraction.landmarks_name,
            "data": extraction.landmarks_json,
            "format": parsed["format"],
            "metadata": metadata,
            "channels": parsed["channels"],
        },
        "skeletons": [
            {"frame": s.frame, "time": s.time, "jpeg": s.jpeg} for s in extraction.skeletons
        ],
    }


# ----------------------------------------------------------------------------------- robots


@contextmanager
def robot_from_spec(spec: dict[str, Any], payload_kg: float | None = None) -> Iterator[Any]:
    """Load the robot of a job's spec; uploaded files are written to a temporary folder.

    Args:
        spec: ``{"name"}`` for a built-in robot, or ``{"name", "urdf", "mjcf", "payload"}``
            with the uploaded files' bytes.
        payload_kg: payload [kg]; None takes the spec's, then the model's default.

    Yields:
        The loaded ``app.planning.robots.Robot`` (its files exist while the context is open).

    Raises:
        RobotError: the model cannot be loaded (a ``BioPlanError``).
    """
    load_robot = _entry("app.planning.robots", "load_robot")
    payload = payload_kg if payload_kg is not None else spec.get("payload")
    if spec.get("urdf") is None:
        yield load_robot(spec["name"], payload=payload)
        return
    with tempfile.TemporaryDirectory(prefix="bioplan-robot-") as tmp:
        # Fixed names: the user's file names are never used as paths.
        urdf = Path(tmp) / "robot.urdf"
        urdf.write_bytes(spec["urdf"])
        mjcf = None
        if spec.get("mjcf") is not None:
            mjcf = Path(tmp) / "robot.xml"
            mjcf.write_bytes(spec["mjcf"])
        yield load_robot(str(urdf), payload=payload, mjcf=None if mjcf is None else str(mjcf))


def builtin_robots() -> list[str]:
    """Names of the built-in robots."""
    return sorted(_entry("app.planning.robots", "BUILTIN_ROBOTS"))


def describe_robot(spec: dict[str, Any]) -> dict[str, Any]:
    """Joints and limits of a robot (SI units: rad, rad/s, Nm; payload in kg).

    Raises:
        RobotError: the model cannot be loaded; one-line message.
    """
    with robot_from_spec(spec) as robot:
        described: dict[str, Any] = json_safe(
            {
                "name": spec["name"],
                "joint_names": list(robot.joint_names),
                "q_min": np.asarray(robot.q_min, float),
                "q_max": np.asarray(robot.q_max, float),
                "qd_max": np.asarray(robot.qd_max, float),
                "tau_max": np.asarray(robot.tau_max, float),
                "payload": float(getattr(robot.payload, "mass", robot.payload) or 0.0),
                "has_mjcf": robot.mjcf_path is not None,
            }
        )
    return described


# ---------------------------------------------------------------------------------- planning


def _task(robot: Any, start_deg: list[float] | None, goal_deg: list[float] | None) -> Any:
    """A PlanTask from start/goal angles [deg], each defaulting to the robot's curl task."""
    if start_deg is None and goal_deg is None:
        return None
    from app.planning.planner import PlanTask

    default = PlanTask.default(robot)
    start, goal = np.array(default.start, float), np.array(default.goal, float)
    n = len(robot.joint_names)
    for name, values, target in (("start_deg", start_deg, start), ("goal_deg", goal_deg, goal)):
        if values is None:
            continue
        if len(values) != n:
            raise BioPlanError(f"{name} needs {n} angles for {robot.name}, got {len(values)}")
        target[:] = np.radians(np.asarray(values, float))
    return PlanTask(start, goal)


def _template(payload: dict[str, Any]) -> Any:
    from app.planning.human_template import HumanTemplate

    template = payload.get("template")
    return None if template is None else HumanTemplate.from_dict(template)


def _arrays_of(result: Any) -> dict[str, Any] | None:
    arrays = getattr(result, "arrays", None)
    if not callable(arrays):
        return None
    return {k: np.asarray(v, dtype=np.float64) for k, v in arrays().items()}


def _planning_options(robot: Any, payload: dict[str, Any]) -> dict[str, Any]:
    """The keyword options ``plan`` and ``simulate_comparison`` share, from a job payload."""
    return {
        "task": _task(robot, payload.get("start_deg"), payload.get("goal_deg")),
        "duration": float(payload["duration"]),
        "objective": payload.get("objective", "abs_work"),
        "seed": int(payload.get("seed", PSO_DEFAULTS.seed)),
        "particles": int(payload.get("particles", PSO_DEFAULTS.particles)),
        "iterations": int(payload.get("iterations", PSO_DEFAULTS.iterations)),
        "peak_angle_deg": payload.get("peak_angle_deg"),
        "template": _template(payload),
    }


def plan(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
    """Plan standard and bio-inspired trajectories (``bioplan plan``).

    Payload: ``robot`` (spec), ``duration`` [s], ``payload`` [kg] or None, ``objective``,
    ``seed``, ``particles``, ``iterations``, ``n_samples``, ``peak_angle_deg``, ``start_deg``,
    ``goal_deg``, ``template`` (HumanTemplate dict or None).

    Returns:
        ``{"result": PlanResult.to_dict(), "arrays": PlanResult.arrays()}``.
    """
    run_plan = _entry("app.planning", "plan")
    with robot_from_spec(payload["robot"], payload.get("payload")) as robot:
        result = run_plan(
            robot,
            n_samples=int(payload.get("n_samples", PSO_DEFAULTS.n_samples)),
            progress=progress,
            **_planning_options(robot, payload),
        )
    return {"result": json_safe(result.to_dict()), "arrays": _arrays_of(result)}


def simulate(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
    """Simulate standard and optimised trajectories (``bioplan simulate``).

    Payload: as for :func:`plan` but without ``n_samples`` (the simulation grid is used).

    Returns:
        ``{"result": SimulationResult.to_dict(), "arrays": SimulationResult.arrays()}``.
    """
    simulate_comparison = _entry("app.simulation", "simulate_comparison")
    with robot_from_spec(payload["robot"], payload.get("payload")) as robot:
        result = simulate_comparison(robot, progress=progress, **_planning_options(robot, payload))
    return {"result": json_safe(result.to_dict()), "arrays": _arrays_of(result)}


def sweep(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
    """Savings over a grid of durations, payloads and objectives (``bioplan sweep``).

    Payload: ``robot`` (spec), ``durations`` [s], ``payloads`` [kg], ``objectives``, ``seed``,
    ``particles``/``iterations`` (None: the sweep's defaults), ``workers`` (processes inside
    the job).
    """
    run_sweep = _entry("app.simulation", "run_sweep")
    budget = {k: int(payload[k]) for k in ("particles", "iterations") if payload.get(k)}
    with robot_from_spec(payload["robot"]) as robot:
        result = run_sweep(
            robot=robot,
            durations=[float(d) for d in payload["durations"]],
            payloads=[float(p) for p in payload["payloads"]],
            objectives=list(payload["objectives"]),
            seed=int(payload.get("seed", 0)),
            progress=progress,
            workers=payload.get("workers"),
            **budget,
        )
    return {"result": json_safe(result.to_dict())}


TASKS: dict[str, TaskFn] = {
    "analysis": analyse,
    "pose": extract_pose_job,
    "plan": plan,
    "simulation": simulate,
    "sweep": sweep,
}


def run_task(kind: str, payload: dict[str, Any], progress: ProgressFn) -> dict[str, Any]:
    """Run the job function of ``kind`` (the runners' single entry point)."""
    try:
        fn = TASKS[kind]
    except KeyError:
        raise ValueError(f"unknown job kind {kind!r} (expected one of {sorted(TASKS)})") from None
    return fn(payload, progress)
