"""Robots: built-ins and uploaded URDF (+ MJCF) models, their joints and limits."""

from __future__ import annotations

from pathlib import PurePosixPath
from typing import Annotated, Any

from fastapi import APIRouter, File, Form, Path, Response, UploadFile

from app.api.deps import RobotsDep, SessionDep, WriteAccess
from app.api.errors import ApiError
from app.api.routes._common import PROBLEM_RESPONSES
from app.api.schemas import ROBOT_NAME, RobotInfo

router = APIRouter(prefix="/api/robots", tags=["robots"], responses=PROBLEM_RESPONSES)

RobotName = Annotated[str, Path(pattern=ROBOT_NAME)]
#: Largest robot model file accepted [bytes]; URDF/MJCF text is small.
MAX_MODEL_BYTES = 5 * 1024 * 1024


@router.get("", response_model=list[RobotInfo])
def list_robots(session: SessionDep, robots: RobotsDep) -> list[dict[str, Any]]:
    """Built-in robots first, then uploaded ones, each with joints and limits (SI units)."""
    return robots.all(session)


@router.get("/{name}", response_model=RobotInfo)
def get_robot(session: SessionDep, robots: RobotsDep, name: RobotName) -> dict[str, Any]:
    return robots.describe(session, name)


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
    session: SessionDep,
    robots: RobotsDep,
    name: Annotated[str, Form(pattern=ROBOT_NAME, description="name used in requests")],
    urdf: Annotated[UploadFile, File(description="URDF (single file, no meshes)")],
    mjcf: Annotated[UploadFile | None, File(description="matching MJCF for simulation")] = None,
    payload: Annotated[float | None, Form(ge=0, le=10000, description="default [kg]")] = None,
) -> dict[str, Any]:
    """Store a robot model after checking that the planning package can load it."""
    return robots.upload(
        session,
        name=name,
        urdf=_read_model(urdf, "urdf"),
        mjcf=None if mjcf is None else _read_model(mjcf, "mjcf"),
        payload=payload,
    )


@router.delete("/{name}", status_code=204, dependencies=[WriteAccess])
def delete_robot(session: SessionDep, robots: RobotsDep, name: RobotName) -> Response:
    robots.delete(session, name)
    return Response(status_code=204)
