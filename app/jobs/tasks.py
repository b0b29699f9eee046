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
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, overload

import numpy as np

from app.errors import BioPlanError, one_line
from app.jobs.front_task import front
from app.jsonsafe import json_safe
from app.names import PSO_DEFAULTS
from app.progress import ProgressFn, no_progress, report

TaskFn = Callable[[dict[str, Any], ProgressFn], dict[str, Any]]


def _entry(module: str, name: str) -> Any:
    """``module.name``, imported now (the science packages are imported only when needed)."""
    import importlib

    return getattr(importlib.import_module(module), name)


#: What the readers import when they first meet a format (CSV tables, MAT 7.3, EDF, robot
#: sidecars): imported before a sandboxed read limits its memory, so that a limit refuses a
#: file's data, never a library's code (``app.services.sandbox``).
READER_MODULES = (
    "pyarrow",
    "pyarrow.csv",
    "pyarrow.compute",
    "h5py",
    "pyedflib",
    "yaml",
    "xml.etree.ElementTree",
)


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
        *READER_MODULES,
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
    landmarks = options.pop("landmarks", None)
    if landmarks:
        options["pose_options"] = {**options.get("pose_options", {}), "landmarks": landmarks}
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


# ----------------------------------------------------------------------------------- cohorts


class _GroupFiles(Sequence[Any]):
    """One group's recording files, read when the comparison reaches each (one recording's
    arrays held at a time), reporting progress per recording file."""

    def __init__(self, files: list[dict[str, Any]], counter: list[int], total: int,
                 progress: ProgressFn, emg_rate: float | None) -> None:  # fmt: skip
        self.files, self.counter, self.total = files, counter, total
        self.progress, self.emg_rate = progress, emg_rate

    def __len__(self) -> int:
        return len(self.files)

    @overload
    def __getitem__(self, i: int) -> Any: ...
    @overload
    def __getitem__(self, i: slice) -> Sequence[Any]: ...
    def __getitem__(self, i: int | slice) -> Any:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        f = self.files[i]
        done = self.counter[0]
        report(self.progress, "analyse", done, self.total, fraction=0.95 * done / self.total,
               message=f"analysing {f['name']} (recording #{f['recording_id']})")  # fmt: skip
        self.counter[0] += 1
        read_options = dict(f["read_options"])
        if self.emg_rate is not None:  # as ``bioplan cohort --emg-rate``: every file reads so
            read_options["emg_rate"] = self.emg_rate
        rec = _read_file({**f, "read_options": read_options}, {})
        excluded = {str(n).strip().lower() for n in f.get("exclude_channels", ())}
        for name in [n for n in rec.channels if n.strip().lower() in excluded]:
            del rec.channels[name]
        return rec


def cohort(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
    """Compare groups of stored recordings (``bioplan cohort``).

    Payload: ``groups`` {name: [{"recording_id", "subject" (stored, or None), "exclude_channels",
    "files": [as :func:`analyse`'s]}]}, ``options``: the fields of ``CohortOptions``. Every
    recording file is one measured recording; a recording's stored subject, where it has one,
    is its subject (pairing by subject uses it), else the library's rule.

    Progress: stage ``analyse``, one unit per recording file; then ``compare``.

    Returns:
        ``{"result": CohortResult.to_dict() + "recording_ids"}`` (aligned with
        ``recordings``).
    """
    import importlib
    from dataclasses import replace

    lib = importlib.import_module("app.analysis.cohort")
    options = lib.CohortOptions(**payload["options"])
    files: dict[str, list[dict[str, Any]]] = {}
    for name, recs in payload["groups"].items():
        files[name] = [
            {**f, "recording_id": r["recording_id"], "exclude_channels": r["exclude_channels"]}
            for r in recs
            for f in r["files"]
        ]
    total = max(sum(len(v) for v in files.values()), 1)
    counter = [0]
    groups = {
        name: _GroupFiles(fs, counter, total, progress, options.emg_rate)
        for name, fs in files.items()
    }
    result = lib.cohort_statistics(groups, options)
    if any(r.get("subject") for recs in payload["groups"].values() for r in recs):
        report(progress, "compare", 0, 1, fraction=0.96, message="pairing by stored subjects")
        result = _with_stored_subjects(result, payload, options, lib, replace)
    report(progress, "done", 1, 1, message="compared")
    out = json_safe(result.to_dict())
    out["recording_ids"] = [f["recording_id"] for fs in files.values() for f in fs]
    return {"result": out}


def _with_stored_subjects(
    result: Any, payload: dict[str, Any], options: Any, lib: Any, replace: Any
) -> Any:
    """The comparison again with each recording's stored subject (no analysis rerun)."""
    subjects = [r.get("subject") for recs in payload["groups"].values() for r in recs
                for _ in r["files"]]  # fmt: skip
    measures = [
        m if not s else replace(m, subject=str(s), subject_from="the recording's stored subject")
        for m, s in zip(result.recordings, subjects, strict=True)
    ]
    again = lib.compare_groups(measures, options)
    rule = str(again.subject_rule).removeprefix("subject = ")
    return replace(
        again,
        subject_rule="subject = the recording's stored subject (set at upload or by PATCH) where"
        f" it has one, else {rule}",
    )


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
        "warnings", "skeleton_frames", "skeletons": [{"frame", "time", "person", "quality",
        "note"}]}, "landmarks": {"name", "data", "format", "metadata", "channels"} (a parsed
        file, as the upload stores it), "skeletons": [{"frame", "time", "person", "quality",
        "note", "jpeg"}]}``.

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
        # whom each skeleton frame shows: the stored frames keep only the image, and the page
        # must say when a skeleton is drawn on someone (or something) else
        "skeletons": [_skeleton_label(s) for s in extraction.skeletons],
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
        "skeletons": [{**_skeleton_label(s), "jpeg": s.jpeg} for s in extraction.skeletons],
    }


def _skeleton_label(s: Any) -> dict[str, Any]:
    """A skeleton frame's index, time [s] and whom it shows (``app.recordings.SkeletonFrame``:
    person 0 = the tracked person, >0 another, -1 unknown; quality 0-1 or None; note)."""
    quality = float(s.quality)
    return {
        "frame": int(s.frame),
        "time": float(s.time),
        "person": int(s.person),
        "quality": quality if quality == quality else None,  # NaN: unknown
        "note": str(s.note),
    }


# ----------------------------------------------------------------------------------- robots


#: Fixed file names of uploaded single files in a robot's folder (the user's names are never
#: used as paths).
UPLOAD_NAMES = {"urdf": "robot.urdf", "mjcf": "robot.xml", "sidecar": "robot.yaml"}


def _member(root: Path, relative: str | None, what: str) -> Path | None:
    """``root/relative`` when ``relative`` names a file inside ``root`` (a package member)."""
    from app.planning.robots import RobotError

    if relative is None:
        return None
    try:
        path = (root / relative).resolve()
        inside = path.is_relative_to(root.resolve()) and path.is_file()
    except (OSError, ValueError):  # a name too long for the file system, a NUL byte
        inside = False
    if not inside:
        raise RobotError(f"{what} '{one_line(relative, 80)}' is not a file of the robot package")
    return path


def _robot_files(spec: dict[str, Any], folder: Path) -> dict[str, Any]:
    """Write a spec's files into ``folder`` (a package zip extracted safely, single files under
    fixed names); the ``load_robot`` file arguments and the package's folders."""
    from app.planning.robots import open_robot_package

    package_dirs: tuple[Path, ...] = ()
    root = folder
    if spec.get("package") is not None:
        archive = folder.parent / f"{folder.name}.zip"
        archive.write_bytes(spec["package"])
        try:
            package = open_robot_package(archive, folder)  # refuses ../, absolute, links
        finally:
            archive.unlink(missing_ok=True)
        root, package_dirs = package.root, package.package_dirs
    else:
        folder.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path | None] = {}
    for key in ("urdf", "mjcf", "sidecar"):
        if spec.get(key) is not None:
            path = root / UPLOAD_NAMES[key]
            path.write_bytes(spec[key])
            files[key] = path
        else:
            files[key] = _member(root, spec.get(f"{key}_member"), key)
    return {**files, "package_dirs": package_dirs, "root": folder}


def _load_uploaded(spec: dict[str, Any], files: dict[str, Any], payload: float | None) -> Any:
    """``load_robot`` of an uploaded robot's files with its roles and locks (display units)."""
    from app.planning.robots import RobotError, load_robot, locks_from_display
    from app.planning.robots._package import check_mjcf_files

    urdf, mjcf = files["urdf"], files["mjcf"]
    if urdf is None and mjcf is None:
        raise RobotError("the robot has no URDF and no MJCF: expected at least one model file")
    if mjcf is not None:
        check_mjcf_files(mjcf, files["root"])  # before MuJoCo opens anything it names
    locks = spec.get("locks") or {}
    if locks:
        if urdf is None:
            from app.planning.robots._mjcf_urdf import urdf_from_mjcf

            locks = locks_from_display(urdf_from_mjcf(mjcf), locks)
        else:
            locks = locks_from_display(urdf, locks)
    return load_robot(
        str(urdf if urdf is not None else mjcf),
        payload=payload,
        mjcf=None if urdf is None or mjcf is None else str(mjcf),
        shoulder_joint=spec.get("shoulder_joint"),
        elbow_joint=spec.get("elbow_joint"),
        locks=locks or None,
        sidecar=files["sidecar"],
        package_dirs=files["package_dirs"],
        base_link=spec.get("base_link"),
        tip_link=spec.get("tip_link"),
    )


@contextmanager
def robot_from_spec(
    spec: dict[str, Any], payload_kg: float | None = None, *, folder: Path | None = None
) -> Iterator[Any]:
    """Load the robot of a job's spec; uploaded files are written to a folder first.

    This is the one function that reads uploaded robot files (URDF, MJCF, package zip,
    sidecar): every upload is checked through it before it is stored.

    Args:
        spec: ``{"name"}`` for a built-in robot, or an uploaded one: ``{"name", "urdf",
            "mjcf", "sidecar", "package"}`` (bytes or None; a package is a zip with meshes),
            ``urdf_member``/``mjcf_member``/``sidecar_member`` (files inside the package),
            ``shoulder_joint``, ``elbow_joint`` (names or None), ``locks`` (name -> degrees,
            or metres for prismatic joints) and ``payload`` [kg].
        payload_kg: payload [kg]; None takes the spec's, then the model's default.
        folder: where to keep the files (kept after the context, e.g. for the viewer's meshes;
            reused when it exists); None: a temporary folder removed afterwards.

    Yields:
        The loaded ``app.planning.robots.Robot`` (its files exist while the context is open).

    Raises:
        RobotError: the model cannot be loaded, or the package is refused (a ``BioPlanError``).
    """
    load_robot = _entry("app.planning.robots", "load_robot")
    payload = payload_kg if payload_kg is not None else spec.get("payload")
    uploaded = any(spec.get(k) is not None for k in ("urdf", "mjcf", "package"))
    if not uploaded:
        yield load_robot(spec["name"], payload=payload)
        return
    if folder is not None:
        ready = folder / ".complete"
        if not ready.exists():
            with tempfile.TemporaryDirectory(prefix=".partial-", dir=folder.parent) as tmp:
                files = _robot_files(spec, Path(tmp) / "robot")
                _load_uploaded(spec, files, payload)  # refuse before keeping anything
                try:
                    Path(tmp, "robot").rename(folder)
                except OSError:
                    if not ready.exists():  # not another request that kept it meanwhile
                        raise
                ready.touch()
        yield _load_uploaded(spec, _robot_files_in(spec, folder), payload)
        return
    with tempfile.TemporaryDirectory(prefix="bioplan-robot-") as tmp:
        yield _load_uploaded(spec, _robot_files(spec, Path(tmp) / "robot"), payload)


def _robot_files_in(spec: dict[str, Any], folder: Path) -> dict[str, Any]:
    """The file arguments of a robot folder written earlier by :func:`_robot_files`."""
    from app.planning.robots._package import _package_dirs

    files: dict[str, Any] = {}
    for key in ("urdf", "mjcf", "sidecar"):
        if spec.get(key) is not None:
            files[key] = folder / UPLOAD_NAMES[key]
        else:
            files[key] = _member(folder, spec.get(f"{key}_member"), key)
    has_package = spec.get("package") is not None
    files["package_dirs"] = _package_dirs(folder.resolve()) if has_package else ()
    files["root"] = folder
    return files


def package_members(data: bytes) -> list[dict[str, Any]]:
    """Files of a robot package zip: relative path, size [bytes] and role (names only; the
    zip is checked and extracted by :func:`robot_from_spec`)."""
    import io
    import zipfile

    roles = {".urdf": "urdf", ".xml": "mjcf", ".mjcf": "mjcf", ".yaml": "sidecar"}
    roles.update({".yml": "sidecar", ".stl": "mesh", ".dae": "mesh", ".obj": "mesh"})
    out = []
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        for info in archive.infolist():
            if info.is_dir():
                continue
            role = roles.get(Path(info.filename).suffix.lower(), "other")
            out.append({"path": info.filename, "bytes": info.file_size, "role": role})
    return out


def builtin_robots() -> list[str]:
    """Names of the built-in robots."""
    return sorted(_entry("app.planning.robots", "BUILTIN_ROBOTS"))


def _joint_rows(robot: Any) -> list[dict[str, Any]]:
    """Every movable joint of the robot's URDF: name, kind, limits, free or locked (SI)."""
    parse_urdf = _entry("app.planning.robots._urdf", "parse_urdf")
    model = parse_urdf(Path(robot.urdf_path))
    roles = {robot.shoulder_joint_name: "shoulder", robot.elbow_joint_name: "elbow"}
    rows = []
    for joint in model.joints:
        if joint.name not in robot.all_joint_names:
            continue  # a mimic follower or a joint the reduced model drops
        rows.append(
            {
                "name": joint.name,
                "kind": joint.kind,
                "unit": "m" if joint.kind == "prismatic" else "rad",
                "lower": joint.lower,
                "upper": joint.upper,
                "velocity": joint.velocity,
                "effort": joint.effort,
                "locked": joint.name in robot.locks,
                "lock_value": robot.locks.get(joint.name),
                "role": roles.get(joint.name),
            }
        )
    return rows


def describe_robot(spec: dict[str, Any], folder: Path | None = None) -> dict[str, Any]:
    """Joints, limits, roles, locks, motors and default task of a robot (SI units: rad, rad/s,
    Nm; payload in kg; ``*_deg`` in degrees).

    Args:
        spec: the robot's spec (:func:`robot_from_spec`).
        folder: keep an uploaded robot's files there (see :func:`robot_from_spec`).

    Raises:
        RobotError: the model cannot be loaded; one-line message.
    """
    with robot_from_spec(spec, folder=folder) as robot:
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
                "shoulder_joint": robot.shoulder_joint_name,
                "elbow_joint": robot.elbow_joint_name,
                "locks": dict(robot.locks),
                "all_joint_names": list(robot.all_joint_names),
                "joints": _joint_rows(robot),
                "motors_modelled": bool(robot.motors_modelled),
                "default_start_deg": np.degrees(np.asarray(robot.default_start, float)),
                "default_goal_deg": np.degrees(np.asarray(robot.default_goal, float)),
                "missing_meshes": _entry("app.planning.robots", "missing_meshes")(robot),
                "default_task_safety": default_task_safety(robot),
            }
        )
    return described


#: Duration of the default task's quintic checked at onboarding [s]; the path a quintic
#: sweeps does not depend on its duration, only the times of the findings scale with it.
DEFAULT_TASK_CHECK_S = 1.0


def default_task_safety(robot: Any) -> dict[str, Any]:
    """The safety check of the robot's default task (its quintic from the default start to the
    default goal over ``DEFAULT_TASK_CHECK_S``), run before the robot is offered.

    Returns:
        ``{ok (None when not checked), checked, reason, min_clearance [m], duration [s],
        findings (count), worst (the deepest finding's dict, or None), summary}``; ``worst``
        holds ``links``, ``kind``, ``obstacle``, ``depth`` [m] and ``deepest_time`` [s].
    """
    quintic = _entry("app.planning.profiles", "quintic")
    safety = _entry("app.planning.safety", "check_safety")
    summary = _entry("app.planning.safety", "safety_summary")
    trajectory = quintic(
        np.asarray(robot.default_start, float),
        np.asarray(robot.default_goal, float),
        DEFAULT_TASK_CHECK_S,
        n_samples=201,
    )
    try:
        report = safety(robot, {"quintic": trajectory}).to_dict()
    except BioPlanError as exc:  # e.g. a sidecar changed since: the robot is still offered
        report = _entry("app.planning.safety", "not_checked")(f"not checked: {exc}").to_dict()
    findings = list(report.get("findings") or [])
    worst = max(findings, key=lambda f: float(f["depth"])) if findings else None
    return {
        "ok": report["ok"],
        "checked": report["checked"],
        "reason": report.get("reason"),
        "min_clearance": report.get("min_clearance"),
        "duration": DEFAULT_TASK_CHECK_S,
        "findings": len(findings),
        "worst": worst,
        "summary": summary(report),
    }


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


def _method_options(payload: dict[str, Any]) -> dict[str, Any]:
    """The methods and their options (``methods``, ``human_constraint``, ``no_reversal``,
    ``n_intervals``, ``converge``) of a job payload; absent keys keep the library's
    defaults."""
    out: dict[str, Any] = {}
    if payload.get("methods") is not None:
        out["methods"] = [str(m) for m in payload["methods"]]
    if payload.get("human_constraint") is not None:
        out["human_constraint"] = str(payload["human_constraint"])
    if payload.get("no_reversal") is not None:
        out["no_reversal"] = bool(payload["no_reversal"])
    if payload.get("n_intervals") is not None:
        out["n_intervals"] = int(payload["n_intervals"])
    if payload.get("converge") is not None:
        out["converge"] = bool(payload["converge"])
    return out


def _planning_options(robot: Any, payload: dict[str, Any]) -> dict[str, Any]:
    """The keyword options ``plan`` and ``simulate_comparison`` share, from a job payload."""
    return {
        **_method_options(payload),
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
    ``goal_deg``, ``template`` (HumanTemplate dict or None), ``methods``,
    ``human_constraint``, ``no_reversal``, ``n_intervals``, ``converge``.

    Returns:
        ``{"result": PlanResult.to_dict() + "motion", "arrays": PlanResult.arrays()}``; the
        ``motion`` block (``plan_motion(result, robot).to_dict()``) holds every method's exact
        knots, so the stored result can be exported at any rate.
    """
    run_plan = _entry("app.planning", "plan")
    plan_motion = _entry("app.planning.export", "plan_motion")
    with robot_from_spec(payload["robot"], payload.get("payload")) as robot:
        result = run_plan(
            robot,
            n_samples=int(payload.get("n_samples", PSO_DEFAULTS.n_samples)),
            progress=progress,
            **_planning_options(robot, payload),
        )
        out = json_safe(result.to_dict())
        out["motion"] = plan_motion(result, robot).to_dict()
    return {"result": out, "arrays": _arrays_of(result)}


def simulate(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
    """Simulate standard and optimised trajectories (``bioplan simulate``).

    Payload: as for :func:`plan` but without ``n_samples`` (the simulation grid is used).

    Returns:
        ``{"result": SimulationResult.to_dict() + "motion", "arrays":
        SimulationResult.arrays()}`` (the motion block of the simulated plan).
    """
    simulate_comparison = _entry("app.simulation", "simulate_comparison")
    plan_motion = _entry("app.planning.export", "plan_motion")
    with robot_from_spec(payload["robot"], payload.get("payload")) as robot:
        result = simulate_comparison(robot, progress=progress, **_planning_options(robot, payload))
        out = json_safe(result.to_dict())
        out["motion"] = plan_motion(result.plan, robot).to_dict()
    return {"result": out, "arrays": _arrays_of(result)}


def sweep(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
    """Savings over a grid of durations, payloads and objectives (``bioplan sweep``).

    Payload: ``robot`` (spec), ``durations`` [s], ``payloads`` [kg], ``objectives``, ``seed``,
    ``particles``/``iterations`` (None: the sweep's defaults), ``methods``, ``check_seed``,
    ``no_check``, ``seeds``, ``converge``, ``workers`` (processes for the cells), and
    ``cell_executor``: set by the runner to ``"dask"`` when the job runs on a Dask worker, so
    that every cell becomes a task of its own on the cluster (submitted from this task through
    ``worker_client``); otherwise the cells run in a local pool of ``workers`` processes.
    Progress is reported per cell.
    """
    run_sweep = _entry("app.simulation", "run_sweep")
    budget = {k: int(payload[k]) for k in ("particles", "iterations") if payload.get(k)}
    options: dict[str, Any] = {}
    if payload.get("methods") is not None:
        options["methods"] = [str(m) for m in payload["methods"]]
    if payload.get("no_check"):
        options["check_seed"] = None
    elif payload.get("check_seed") is not None:
        options["check_seed"] = int(payload["check_seed"])
    if payload.get("seeds") is not None:
        options["seeds"] = int(payload["seeds"])
    if payload.get("converge") is not None:
        options["converge"] = bool(payload["converge"])
    with robot_from_spec(payload["robot"]) as robot, _cell_executor(payload) as executor:
        result = run_sweep(
            robot=robot,
            durations=[float(d) for d in payload["durations"]],
            payloads=[float(p) for p in payload["payloads"]],
            objectives=list(payload["objectives"]),
            seed=int(payload.get("seed", 0)),
            progress=progress,
            workers=payload.get("workers"),
            executor=executor,
            **budget,
            **options,
        )
    return {"result": json_safe(result.to_dict())}


@contextmanager
def _cell_executor(payload: dict[str, Any]) -> Iterator[Any]:
    """Where a sweep job's cells run: ``"local"``, or (on a Dask worker) a client that submits
    them to the same cluster while this task steps out of the worker's thread pool."""
    if payload.get("cell_executor") != "dask":
        yield "local"
        return
    import importlib

    distributed = importlib.import_module("distributed")
    with distributed.worker_client() as client:
        yield client


def profiles(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
    """Classical profiles and the minimum-torque-change baseline on one task, with the planning
    methods beside them (``bioplan profiles --json``).

    Payload: ``robot`` (spec), ``payload`` [kg], ``duration`` [s], ``start_deg``, ``goal_deg``,
    ``min_torque_change``, ``mtc_intervals``, ``methods`` ([] = none), ``objective``, ``seed``,
    ``particles``, ``iterations``.
    """
    compare_profiles = _entry("app.planning.comparison", "compare_profiles")
    run_plan = _entry("app.planning", "plan")
    within = _entry("app.progress", "within")
    with robot_from_spec(payload["robot"], payload.get("payload")) as robot:
        task = _task(robot, payload.get("start_deg"), payload.get("goal_deg"))
        duration = float(payload["duration"])
        report(progress, "profiles", 0, 1, fraction=0.0, message="classical profiles")
        result = compare_profiles(
            robot,
            task=task,
            duration=duration,
            include_min_torque_change=bool(payload.get("min_torque_change", True)),
            mtc_intervals=int(payload.get("mtc_intervals", 100)),
        )
        out: dict[str, Any] = json_safe(result.to_dict())
        methods = payload.get("methods")
        if methods is None or methods:
            planned = run_plan(
                robot,
                task=task,
                duration=duration,
                objective=payload.get("objective", "abs_work"),
                seed=int(payload.get("seed", PSO_DEFAULTS.seed)),
                particles=int(payload.get("particles", PSO_DEFAULTS.particles)),
                iterations=int(payload.get("iterations", PSO_DEFAULTS.iterations)),
                progress=within(progress, 0.3, 1.0),
                **({} if methods is None else {"methods": [str(m) for m in methods]}),
            ).to_dict()
            out["objective"] = planned["conditions"]["objective"]
            out["methods"] = planned["methods"]
            out["share_of_achievable_pct"] = planned["share_of_achievable_pct"]
    report(progress, "done", 1, 1, message="profiles compared")
    return {"result": json_safe(out)}


# ------------------------------------------------------------------------------ robot logs

#: Most bytes a bag's zip may unpack to.
MAX_BAG_UNPACKED = 1 << 30


def _bag_from_zip(data: bytes, folder: Path, name: str) -> Path:
    """Unpack a zipped ROS 2 bag folder (``metadata.yaml`` and its ``.mcap``/``.db3`` files,
    by base name only: no path of the archive is used) into ``folder``."""
    import io
    import zipfile

    from app.recordings.types import RecordingError

    expected = "a zip of a ROS 2 bag folder (metadata.yaml and its .mcap or .db3 files)"
    try:
        archive = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile:
        raise RecordingError("not a readable zip archive", file=name, expected=expected) from None
    with archive:
        members = [
            i
            for i in archive.infolist()
            if not i.is_dir() and Path(i.filename).suffix.lower() in (".yaml", ".mcap", ".db3")
        ]
        if sum(i.file_size for i in members) > MAX_BAG_UNPACKED:
            raise RecordingError(
                f"unpacks to more than {MAX_BAG_UNPACKED} bytes", file=name, expected=expected
            )
        kept = [i for i in members if Path(i.filename).name == "metadata.yaml"]
        if len(kept) != 1:
            raise RecordingError(f"{len(kept)} metadata.yaml files", file=name, expected=expected)
        folder.mkdir(parents=True, exist_ok=True)
        for info in members:
            base = Path(info.filename).name
            if base != "metadata.yaml" and Path(info.filename).suffix.lower() == ".yaml":
                continue
            (folder / base).write_bytes(archive.read(info))
    return folder


def _read_log(log: dict[str, Any], folder: Path, topic: str | None) -> Any:
    """The ``RobotLog`` of an uploaded log ``{"name", "data"}`` (written into ``folder``)."""
    read_robot_log = _entry("app.recordings.robot_logs", "read_robot_log")
    name = str(log["name"])
    suffix = Path(name).suffix.lower()
    folder.mkdir(parents=True, exist_ok=True)
    if suffix == ".zip":
        path = _bag_from_zip(log["data"], folder / "bag", name)
    else:
        # Under the user's base name, so the reader's messages name their file (in a folder of
        # its own; the format is sniffed from the content, never from the name).
        safe = Path(name).name
        if safe in ("", ".", "..") or len(safe.encode("utf-8", "replace")) > 200:
            safe = "log.csv"  # a name the file system may not take (too long in bytes)
        path = folder / safe
        path.write_bytes(log["data"])
    robot_log = read_robot_log(path, topic=topic)
    # Messages name the user's file, not the temporary one.
    import dataclasses

    return dataclasses.replace(robot_log, path=Path(name))


#: Most points per curve of a validation's plotted series (a 20 s log at 1 kHz is 20 000).
MAX_PLOT_POINTS = 2000


def _series(validation: Any) -> dict[str, Any]:
    """Measured and predicted torque [Nm] and power [W] per joint on at most
    :data:`MAX_PLOT_POINTS` times [s] (every k-th sample: the series are low-passed already)."""
    t = np.asarray(validation.t)
    step = max(1, -(-t.size // MAX_PLOT_POINTS))
    keep = slice(None, None, step)
    measured, predicted = validation.measured[keep], validation.predicted[keep]
    qd = validation.qd[keep]
    return {
        "t": t[keep],
        "joints": list(validation.joint_names),
        "measured": measured.T,
        "predicted": predicted.T,
        "power_measured": np.sum(np.abs(measured * qd), axis=1),
        "power_predicted": np.sum(np.abs(predicted * qd), axis=1),
    }


def validate_log(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
    """Measured against predicted joint torque of an uploaded robot log (``bioplan validate``).

    Payload: ``robot`` (spec), ``payload`` [kg] or None, ``log`` (``{"name", "data"}``),
    ``topic`` (a bag's JointState topic) or None, ``cutoff_hz`` [Hz] or None, ``plan`` (a
    stored plan's ``motion`` block) or None, ``series`` (bool: add the plotted series).

    Returns:
        ``{"result": Validation.result (+ "series")}``.
    """
    validate = _entry("app.planning.validation", "validate")
    options_type = _entry("app.planning.validation", "ValidateOptions")
    cutoff = payload.get("cutoff_hz")
    options = options_type() if cutoff is None else options_type(cutoff_hz=float(cutoff))
    with (
        robot_from_spec(payload["robot"], payload.get("payload")) as robot,
        tempfile.TemporaryDirectory(prefix="bioplan-log-") as tmp,
    ):
        log = _read_log(payload["log"], Path(tmp) / "log", payload.get("topic"))
        plan_path = None
        if payload.get("plan") is not None:
            import json

            plan_path = Path(tmp) / "plan.json"
            plan_path.write_text(json.dumps({"motion": payload["plan"]}), encoding="utf-8")
        validation = validate(robot, log, options=options, plan=plan_path)
        out: dict[str, Any] = dict(validation.result)
        if payload.get("series"):
            out["series"] = _series(validation)
    return {"result": json_safe(out)}


def identify_robot(payload: dict[str, Any], progress: ProgressFn = no_progress) -> dict[str, Any]:
    """Identify a robot's link inertias and friction from uploaded logs (``bioplan identify``)
    and describe the robot version that carries the identified sidecar.

    Payload: ``robot`` (spec of an uploaded robot), ``logs`` (``[{"name", "data"}]``),
    ``topic``, ``validate_fraction``, ``cutoff_hz``, ``identify_payload``, ``version`` (the new
    robot's name).

    Returns:
        ``{"result": Identification.to_dict() + "version", "sidecar": YAML bytes,
        "description": the new version's describe_robot}``.
    """
    import yaml

    identify = _entry("app.planning.identification", "identify")
    write_sidecar = _entry("app.planning.identification", "write_sidecar")
    options_type = _entry("app.planning.identification", "IdentifyOptions")
    options = options_type(
        validate_fraction=float(payload.get("validate_fraction", 0.2)),
        cutoff_hz=float(payload.get("cutoff_hz") or 10.0),
        identify_payload=bool(payload.get("identify_payload", False)),
    )
    spec = payload["robot"]
    report(progress, "read", 0, 3, fraction=0.0, message="reading the logs")
    with robot_from_spec(spec) as robot, tempfile.TemporaryDirectory(prefix="bioplan-id-") as tmp:
        logs = [
            _read_log(log, Path(tmp) / str(i), payload.get("topic"))
            for i, log in enumerate(payload["logs"])
        ]
        report(progress, "identify", 1, 3, fraction=0.2, message="identifying the parameters")
        result = identify(robot, logs, options)
        base: dict[str, Any] = {}
        if spec.get("sidecar") is not None:
            loaded = yaml.safe_load(spec["sidecar"].decode("utf-8")) or {}
            base = {k: v for k, v in loaded.items() if k not in ("links", "friction")}
        held = result.held_back
        names = ", ".join(str(log["name"]) for log in payload["logs"])
        comment = f"Identified by the BioPlan service from {names}"
        if held:
            residuals = ", ".join(f"{k} {v['residual_rms']:.3g}" for k, v in held.items())
            comment += f"; held-back residual rms [Nm]: {residuals}"
        sidecar_path = Path(tmp) / "identified.yaml"
        write_sidecar(sidecar_path, robot, result, base=base, comment=comment)
        sidecar = sidecar_path.read_bytes()
    report(progress, "describe", 2, 3, fraction=0.9, message="loading the identified robot")
    version = {**spec, "name": payload["version"], "sidecar": sidecar, "sidecar_member": None}
    description = describe_robot(version)
    out = json_safe(result.to_dict())
    out["version"] = payload["version"]
    report(progress, "done", 3, 3, message="identified")
    return {"result": out, "sidecar": sidecar, "description": description}


TASKS: dict[str, TaskFn] = {
    "analysis": analyse,
    "pose": extract_pose_job,
    "plan": plan,
    "simulation": simulate,
    "sweep": sweep,
    "profiles": profiles,
    "cohort": cohort,
    "identify": identify_robot,
    "front": front,
}


def run_task(kind: str, payload: dict[str, Any], progress: ProgressFn) -> dict[str, Any]:
    """Run the job function of ``kind`` (the runners' single entry point)."""
    try:
        fn = TASKS[kind]
    except KeyError:
        raise ValueError(f"unknown job kind {kind!r} (expected one of {sorted(TASKS)})") from None
    return fn(payload, progress)
