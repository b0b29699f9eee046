"""Robots: built-ins and uploaded URDF (+ MJCF) models, their joints and limits."""

from __future__ import annotations

from pathlib import PurePosixPath
from typing import Annotated, Any

from fastapi import APIRouter, File, Form, Path, Response, UploadFile

from app.api.deps import RunnerDep, ServicesDep, SessionDep, WriteAccess
from app.api.errors import ApiError
from app.api.routes._common import PROBLEM_RESPONSES
from app.api.schemas import ROBOT_NAME, RobotInfo
from app.db import crud
from app.db.models import RobotRecord

router = APIRouter(prefix="/api/robots", tags=["robots"], responses=PROBLEM_RESPONSES)

RobotName = Annotated[str, Path(pattern=ROBOT_NAME)]
#: Largest robot model file accepted [bytes]; URDF/MJCF text is small.
MAX_MODEL_BYTES = 5 * 1024 * 1024


def _uploaded(row: RobotRecord) -> dict[str, Any]:
    out = dict(row.description)
    out.update(
        name=row.name,
        builtin=False,
        payload=row.payload if row.payload is not None else out.get("payload"),
        has_mjcf=row.mjcf_sha256 is not None,
        urdf_name=row.urdf_name,
        mjcf_name=row.mjcf_name,
    )
    return out


@router.get("", response_model=list[RobotInfo])
def list_robots(session: SessionDep, jobs: RunnerDep) -> list[dict[str, Any]]:
    """Built-in robots first, then uploaded ones, each with joints and limits (SI units)."""
    out = [jobs.describe_builtin(name) for name in jobs.builtin_robots]
    out += [_uploaded(r) for r in crud.list_robots(session=session)]
    return out


@router.get("/{name}", response_model=RobotInfo)
def get_robot(session: SessionDep, jobs: RunnerDep, name: RobotName) -> dict[str, Any]:
    if name in jobs.builtin_robots:
        return jobs.describe_builtin(name)
    row = crud.get_robot(session=session, name=name)
    if row is None:
        raise ApiError(404, f"robot {name!r} does not exist")
    return _uploaded(row)


def _read_model(upload: UploadFile, field: str) -> tuple[str, bytes]:
    name = PurePosixPath((upload.filename or field).replace("\\", "/")).name[:255] or field
    data = upload.file.read(MAX_MODEL_BYTES + 1)
    if not data:
        raise ApiError(422, f"{name}: the file is empty", field=field, file=name)
    if len(data) > MAX_MODEL_BYTES:
        raise ApiError(
            413, f"{name}: robot models are limited to {MAX_MODEL_BYTES} bytes", file=name
        )
    return name, data


@router.post("", status_code=201, response_model=RobotInfo, dependencies=[WriteAccess])
def upload_robot(
    services: ServicesDep,
    session: SessionDep,
    jobs: RunnerDep,
    name: Annotated[str, Form(pattern=ROBOT_NAME, description="name used in requests")],
    urdf: Annotated[UploadFile, File(description="URDF (single file, no meshes)")],
    mjcf: Annotated[UploadFile | None, File(description="matching MJCF for simulation")] = None,
    payload: Annotated[float | None, Form(ge=0, le=10000, description="default [kg]")] = None,
) -> dict[str, Any]:
    """Store a robot model after checking that the planning package can load it."""
    from app.jobs.tasks import describe_robot

    if name in jobs.builtin_robots or crud.get_robot(session=session, name=name) is not None:
        raise ApiError(409, f"a robot named {name!r} already exists", field="name")
    urdf_file = _read_model(urdf, "urdf")
    mjcf_file = None if mjcf is None else _read_model(mjcf, "mjcf")
    spec = {
        "name": name,
        "urdf": urdf_file[1],
        "mjcf": None if mjcf_file is None else mjcf_file[1],
        "payload": payload,
    }
    try:
        description = describe_robot(spec)
    except (ValueError, TypeError, KeyError, OSError) as exc:
        raise ApiError(
            422,
            f"{urdf_file[0]}: cannot load the robot model: {exc}",
            title="Unreadable robot model",
            file=urdf_file[0],
        ) from None
    row = crud.create_robot(
        session=session,
        blobs=services.blobs,
        name=name,
        urdf=urdf_file,
        mjcf=mjcf_file,
        payload=payload,
        description=description,
    )
    return _uploaded(row)


@router.delete("/{name}", status_code=204, dependencies=[WriteAccess])
def delete_robot(
    services: ServicesDep, session: SessionDep, jobs: RunnerDep, name: RobotName
) -> Response:
    if name in jobs.builtin_robots:
        raise ApiError(409, f"{name!r} is built in and cannot be deleted")
    if not crud.delete_robot(session=session, blobs=services.blobs, name=name):
        raise ApiError(404, f"robot {name!r} does not exist")
    return Response(status_code=204)
