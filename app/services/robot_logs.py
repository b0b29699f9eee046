"""Robot logs the service keeps: upload (read, matched to the robot and validated before it is
stored), validation against any robot version (and a stored plan), and identification jobs
whose result is stored as a new robot version beside the nominal one.

Every read of an uploaded log runs in the parse sandbox (``app.services.sandbox``) through the
job function ``app.jobs.tasks.validate_log``, so a log the library refuses is refused with its
message (file, line or joint named) and nothing is stored.
"""

from __future__ import annotations

import math
from typing import Any

from sqlalchemy.orm import Session

from app.db import crud
from app.db.blobs import BlobStore
from app.db.models import IdentificationRecord, JobRecord, Plan, RobotLogRecord
from app.errors import BioPlanError
from app.jobs import tasks
from app.services.errors import (
    ConflictError,
    NotFoundError,
    ParseLimitError,
    ServiceError,
    found,
)
from app.services.job_views import not_finished
from app.services.robots import RobotCatalog
from app.services.sandbox import read_untrusted

__all__ = [
    "identify_params",
    "identify_payload",
    "log_to_dict",
    "store_identification",
    "upload_log",
    "validate_stored",
]

#: The validation figures kept with a log at upload (the rest is computed when asked).
_SUMMARY_KEYS = ("joints", "abs_work", "electrical_energy", "filter", "units")
#: Shortest fitted part of a log identification accepts [s] (``identification.MIN_DURATION``).
MIN_IDENTIFY_SECONDS = 2.0


def log_to_dict(row: RobotLogRecord) -> dict[str, object]:
    """The JSON form of a stored log (``app.api.schemas.RobotLogOut``)."""
    return {
        "id": row.id,
        "robot": row.robot,
        "file": row.original_name,
        "format": row.format,
        "bytes": row.size,
        "topic": row.topic,
        "label": row.label,
        "created_at": row.created_at,
        **row.summary,
    }


def _refused(name: str, exc: BioPlanError) -> ServiceError:
    """A library refusal as a 422 naming the file (its message names line, channel, joint)."""
    message = str(exc)
    if not message.startswith(name):
        message = f"{name}: {message}"
    return ServiceError(message, file=name, field="file")


def _run(payload: dict[str, Any], name: str) -> dict[str, Any]:
    """``tasks.validate_log`` in the parse sandbox; the library's refusals become 422s."""
    try:
        out = read_untrusted(tasks.validate_log, payload, what=name)
    except ParseLimitError:
        raise
    except ServiceError:
        raise
    except BioPlanError as exc:
        raise _refused(name, exc) from None
    result: dict[str, object] = out["result"]
    return result


def upload_log(
    session: Session,
    blobs: BlobStore,
    robots: RobotCatalog,
    *,
    robot: str,
    file: tuple[str, bytes],
    topic: str | None = None,
    label: str | None = None,
) -> dict[str, object]:
    """Read a robot log, match it to ``robot``'s joints, validate it against the robot's model,
    then store it (bytes and row together); a log refused at any step stores nothing.

    Raises:
        UnknownRobotError: no such robot (404 naming ``robot``).
        ServiceError: empty, unreadable or bad log (422 naming the file and the line, channel
            or joint), or one without joint torques.
        ParseLimitError: the read needed more memory or time than the sandbox allows (413).
    """
    name, data = file
    if not data:
        raise ServiceError(f"{name}: the file is empty", file=name, field="file")
    spec = robots.spec(session, robot)
    payload = {"robot": spec, "log": {"name": name, "data": data}, "topic": topic}
    result = _run(payload, name)
    log = result["log"]
    summary = {
        "samples": log["samples"],
        "rate_hz": log["rate_hz"],
        "duration_s": log["duration_s"],
        "notes": log["notes"],
        "joint_names": list(result["joints"]),
        "validation": {k: result[k] for k in _SUMMARY_KEYS if k in result},
    }
    row = crud.create_robot_log(
        session=session,
        blobs=blobs,
        robot=robot,
        file=file,
        format=log["format"],
        topic=topic,
        summary=summary,
        label=label,
    )
    return log_to_dict(row)


def get_log(session: Session, log_id: int) -> RobotLogRecord:
    """The stored log ``log_id``.

    Raises:
        NotFoundError: no such log.
    """
    return found(crud.get_robot_log(session=session, log_id=log_id), f"robot log {log_id}")


def list_logs(session: Session, robot: str | None = None) -> list[dict[str, object]]:
    """Stored logs (JSON form), newest first (of one robot when ``robot`` is given)."""
    return [log_to_dict(r) for r in crud.list_robot_logs(session=session, robot=robot)]


def delete_log(session: Session, blobs: BlobStore, log_id: int) -> None:
    """Delete a stored log and its file.

    Raises:
        NotFoundError: no such log.
    """
    if not crud.delete_robot_log(session=session, blobs=blobs, log_id=log_id):
        raise NotFoundError(f"robot log {log_id} does not exist")


def _plan_motion(session: Session, plan_id: int) -> dict[str, object]:
    row = session.get(Plan, plan_id)
    if row is None:
        raise NotFoundError(f"plan {plan_id} does not exist", field="plan")
    motion = (row.result or {}).get("motion")
    if not isinstance(motion, dict):
        raise not_finished(session, plan_id, f"plan {plan_id}", lacks="no planned motion",
                           expected="a finished plan", field="plan")  # fmt: skip
    return motion


def validate_stored(
    session: Session,
    blobs: BlobStore,
    robots: RobotCatalog,
    log_id: int,
    *,
    robot: str | None = None,
    plan_id: int | None = None,
    cutoff_hz: float | None = None,
) -> dict[str, object]:
    """Measured against predicted torque of a stored log, with the plotted series.

    Args:
        robot: the robot model to predict with (default: the log's robot); e.g. its identified
            version.
        plan_id: a stored plan the log executed: aligned in time, tracking error, savings.
        cutoff_hz: zero-phase low-pass cutoff [Hz] (default: the library's 10 Hz).

    Raises:
        NotFoundError: no such log, robot or plan; ConflictError: the plan has no result;
        ServiceError: the log or plan does not fit the robot (422 naming file and joint).
    """
    row = get_log(session, log_id)
    name = robot or row.robot
    payload = {
        "robot": robots.spec(session, name),
        "log": {"name": row.original_name, "data": blobs.get(row.sha256)},
        "topic": row.topic,
        "cutoff_hz": cutoff_hz,
        "plan": None if plan_id is None else _plan_motion(session, plan_id),
        "series": True,
    }
    result = _run(payload, row.original_name)
    result["log_id"] = row.id
    result["plan_id"] = plan_id
    return result


def identify_params(
    session: Session,
    robots: RobotCatalog,
    *,
    log_ids: list[int],
    version: str | None,
    validate_fraction: float,
    cutoff_hz: float | None,
    identify_payload: bool,
) -> dict[str, object]:
    """The request of an identification job, checked before anything is stored.

    Raises:
        NotFoundError: a log does not exist (404 naming ``log_ids``).
        ConflictError: the logs are of different robots, the robot is built in (its model
            takes no sidecar), or ``version`` is taken (409).
        ServiceError: a log too short to identify from (422 naming the file).
    """
    rows = [get_log(session, i) for i in dict.fromkeys(log_ids)]
    robot = rows[0].robot
    others = sorted({r.robot for r in rows} - {robot})
    if others:
        raise ConflictError(
            f"the logs are of robots {[robot, *others]}: expected logs of one robot",
            field="log_ids",
        )
    if robot in robots.builtin:
        raise ConflictError(
            f"{robot!r} is built in and takes no sidecar: upload its URDF as a robot, and its "
            "logs for that robot, to identify it",
            field="log_ids",
        )
    robots.spec(session, robot)  # 404 when it was deleted
    name = version or _free_name(session, robots, f"{robot}-identified")
    if name in robots.builtin or crud.get_robot(session=session, name=name) is not None:
        raise ConflictError(f"a robot named {name!r} already exists", field="version")
    keep = 1.0 - validate_fraction
    for r in rows:
        fitted = float(r.summary.get("duration_s", 0.0)) * keep
        if fitted < MIN_IDENTIFY_SECONDS:
            raise ServiceError(
                f"{r.original_name}: {fitted:.3g} s to fit after holding back "
                f"{100 * validate_fraction:g} %: expected at least {MIN_IDENTIFY_SECONDS:g} s of "
                "motion to identify from (a longer log)",
                file=r.original_name,
                field="log_ids",
            )
    return {
        "robot": robot,
        "log_ids": [r.id for r in rows],
        "version": name,
        "validate_fraction": validate_fraction,
        "cutoff_hz": cutoff_hz,
        "identify_payload": identify_payload,
    }


def _free_name(session: Session, robots: RobotCatalog, stem: str) -> str:
    """``stem``, or ``stem-2``, ``stem-3``... : the first name no robot has."""
    for k in range(1, 10_000):
        name = stem if k == 1 else f"{stem}-{k}"
        if name not in robots.builtin and crud.get_robot(session=session, name=name) is None:
            return name[:100]
    raise ConflictError(f"no free robot name like {stem!r}", field="version")


def identify_payload(
    session: Session, blobs: BlobStore, robots: RobotCatalog, params: dict[str, Any]
) -> dict[str, object]:
    """The identify job's input: the robot's spec and the logs' bytes."""
    logs = []
    topic = None
    for log_id in params["log_ids"]:
        row = get_log(session, int(log_id))
        logs.append({"name": row.original_name, "data": blobs.get(row.sha256)})
        topic = topic or row.topic
    return {**params, "robot": robots.spec(session, params["robot"]), "logs": logs, "topic": topic}


def store_identification(
    session: Session,
    blobs: BlobStore,
    robots: RobotCatalog,
    job_id: int,
    out: dict[str, Any],
    *,
    inline_bytes: int | None = None,
) -> str | None:
    """Store an identify job's result and its robot version (the nominal robot's files with the
    identified sidecar); returns why it could not, or None when it was stored.

    The version is stored first and removed again when the result cannot be (a job cancelled
    meanwhile): a version exists only beside a succeeded job.
    """
    record = session.get(IdentificationRecord, job_id)
    job = session.get(JobRecord, job_id)
    if record is None or job is None:
        return "its job was deleted"
    nominal = crud.get_robot(session=session, name=record.robot)
    if nominal is None:
        return f"robot {record.robot!r} was deleted while it was identified"
    if crud.get_robot(session=session, name=record.version) is not None:
        return f"a robot named {record.version!r} was stored meanwhile"

    def file(sha: str | None, name: str | None) -> tuple[str, bytes] | None:
        return None if sha is None else (name or "model", blobs.get(sha))

    description = dict(out["description"])
    description["identified_from"] = {
        "robot": record.robot,
        "log_ids": list(job.params.get("log_ids") or []),
        "job_id": job_id,
    }
    options = {k: v for k, v in (nominal.options or {}).items() if k != "sidecar_member"}
    crud.create_robot(
        session=session,
        blobs=blobs,
        name=record.version,
        urdf=file(nominal.urdf_sha256, nominal.urdf_name),
        mjcf=file(nominal.mjcf_sha256, nominal.mjcf_name),
        package=file(nominal.package_sha256, nominal.package_name),
        sidecar=("identified.yaml", out["sidecar"]),
        options=options,
        payload=nominal.payload,
        description=description,
    )
    stored = crud.store_result(
        session=session,
        job_id=job_id,
        kind="identify",
        result=out["result"],
        blobs=blobs,
        inline_bytes=inline_bytes,
    )
    if not stored:
        crud.delete_robot(session=session, blobs=blobs, name=record.version)
    return None


def check_cutoff(cutoff_hz: float | None) -> float | None:
    """``cutoff_hz`` when it is a positive finite frequency [Hz] (422 otherwise)."""
    if cutoff_hz is not None and not (math.isfinite(cutoff_hz) and cutoff_hz > 0):
        raise ServiceError(f"cutoff_hz is {cutoff_hz}: expected a value > 0 Hz", field="cutoff_hz")
    return cutoff_hz
