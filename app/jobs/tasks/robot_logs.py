"""Robot-log jobs: validate a robot's dynamics against a measured log, identify its link
inertias and friction from logs (``bioplan validate``, ``bioplan identify``)."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from app.jobs.tasks.robots import describe_robot, robot_from_spec
from app.jobs.tasks.types import IdentifyPayload, JobResult, LogFile, RobotSpec, ValidatePayload
from app.jsonsafe import json_safe
from app.progress import ProgressFn, no_progress, report

if TYPE_CHECKING:
    from app.planning.validation import Validation
    from app.recordings.robot_logs import RobotLog

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


def _read_log(log: LogFile, folder: Path, topic: str | None) -> RobotLog:
    """The ``RobotLog`` of an uploaded log ``{"name", "data"}`` (written into ``folder``)."""
    from app.recordings.robot_logs import read_robot_log

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


def _series(validation: Validation) -> dict[str, object]:
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


def validate_log(payload: ValidatePayload, progress: ProgressFn = no_progress) -> JobResult:
    """Measured against predicted joint torque of an uploaded robot log (``bioplan validate``).

    Payload: ``robot`` (spec), ``payload`` [kg] or None, ``log`` (``{"name", "data"}``),
    ``topic`` (a bag's JointState topic) or None, ``cutoff_hz`` [Hz] or None, ``plan`` (a
    stored plan's ``motion`` block) or None, ``series`` (bool: add the plotted series).

    Returns:
        ``{"result": Validation.result (+ "series")}``.
    """
    from app.planning.validation import ValidateOptions as options_type
    from app.planning.validation import validate

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
        out: dict[str, object] = dict(validation.result)
        if payload.get("series"):
            out["series"] = _series(validation)
    return {"result": json_safe(out)}


def identify_robot(payload: IdentifyPayload, progress: ProgressFn = no_progress) -> JobResult:
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

    from app.planning.identification import IdentifyOptions as options_type
    from app.planning.identification import identify, write_sidecar

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
        base: dict[str, object] = {}
        given = spec.get("sidecar")
        if given is not None:
            loaded = yaml.safe_load(given.decode("utf-8")) or {}
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
    version: RobotSpec = {
        **spec,
        "name": payload["version"],
        "sidecar": sidecar,
        "sidecar_member": None,
    }
    description = describe_robot(version)
    out = json_safe(result.to_dict())
    out["version"] = payload["version"]
    report(progress, "done", 3, 3, message="identified")
    return {"result": out, "sidecar": sidecar, "description": description}
