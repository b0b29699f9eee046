"""Robots: built-ins and uploaded URDF (+ MJCF) models, their joints and limits."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, File, Form, Path, Response, UploadFile

from app.api.deps import RobotsDep, ServicesDep, SessionDep, WriteAccess
from app.api.errors import ApiError
from app.api.routes._common import PROBLEM_RESPONSES, upload_name
from app.api.schemas import ROBOT_NAME, RobotInfo
from app.services.robots import UploadLimits, parse_locks

router = APIRouter(prefix="/api/robots", tags=["robots"], responses=PROBLEM_RESPONSES)

RobotName = Annotated[str, Path(pattern=ROBOT_NAME)]
#: Largest robot model file accepted [bytes]; URDF/MJCF text is small.
MAX_MODEL_BYTES = 5 * 1024 * 1024
#: Largest robot package zip accepted [bytes] (meshes).
MAX_PACKAGE_BYTES = 100 * 1024 * 1024
#: Most locked joints in one upload.
MAX_LOCKS = 64


@router.get("", response_model=list[RobotInfo])
def list_robots(session: SessionDep, robots: RobotsDep) -> list[dict[str, object]]:
    """Built-in robots first, then uploaded ones, each with joints and limits (SI units)."""
    return robots.all(session)


@router.get("/{name}", response_model=RobotInfo)
def get_robot(session: SessionDep, robots: RobotsDep, name: RobotName) -> dict[str, object]:
    return robots.describe(session, name)


def _read_model(upload: UploadFile, field: str, limit: int = MAX_MODEL_BYTES) -> tuple[str, bytes]:
    name = upload_name(upload.filename, field, field=field)
    data = upload.file.read(limit + 1)
    if not data:
        raise ApiError(422, f"{name}: the file is empty", field=field, file=name)
    if len(data) > limit:
        raise ApiError(413, f"{name}: {field} files are limited to {limit} bytes", file=name)
    return name, data


def _optional(
    upload: UploadFile | None, field: str, limit: int = MAX_MODEL_BYTES
) -> tuple[str, bytes] | None:
    return None if upload is None else _read_model(upload, field, limit)


Member = Annotated[
    str | None,
    Form(max_length=1000, description="a file inside the package (default: its only one)"),
]


#: The schema says what the service checks: a robot needs a model, as a file or in a package.
_A_MODEL = {
    "requestBody": {
        "content": {
            "multipart/form-data": {
                "schema": {"anyOf": [{"required": [f]} for f in ("urdf", "mjcf", "package")]}
            }
        }
    }
}


@router.post(
    "",
    status_code=201,
    response_model=RobotInfo,
    dependencies=[WriteAccess],
    openapi_extra=_A_MODEL,
)
def upload_robot(
    services: ServicesDep,
    session: SessionDep,
    robots: RobotsDep,
    name: Annotated[str, Form(pattern=ROBOT_NAME, description="name used in requests")],
    urdf: Annotated[UploadFile | None, File(description="URDF")] = None,
    mjcf: Annotated[
        UploadFile | None, File(description="MJCF (alone, or the URDF's for simulation)")
    ] = None,
    package: Annotated[
        UploadFile | None,
        File(description="zip of the robot's folder: model files, meshes (package:// paths)"),
    ] = None,
    sidecar: Annotated[
        UploadFile | None, File(description="motor, gear, payload YAML (docs/robots.md)")
    ] = None,
    payload: Annotated[float | None, Form(ge=0, le=10000, description="default [kg]")] = None,
    shoulder_joint: Annotated[
        str | None, Form(max_length=200, description="joint human shoulder flexion maps to")
    ] = None,
    elbow_joint: Annotated[
        str | None, Form(max_length=200, description="joint human elbow flexion maps to")
    ] = None,
    lock: Annotated[
        list[str] | None,
        Form(description="NAME=VALUE, repeatable: joints held fixed [deg, or m if prismatic]"),
    ] = None,
    base_link: Annotated[
        str | None,
        Form(max_length=200, description="the arm's base link on a legged or multi-arm robot"),
    ] = None,
    tip_link: Annotated[
        str | None,
        Form(max_length=200, description="the arm's end link when it branches below its base"),
    ] = None,
    urdf_member: Member = None,
    mjcf_member: Member = None,
    sidecar_member: Member = None,
) -> dict[str, object]:
    """Store a robot (URDF and/or MJCF, or a zip with meshes, plus a sidecar) after checking
    that the planning package loads it; a URDF/MJCF pair that disagrees is refused naming the
    joint."""
    if len(lock or []) > MAX_LOCKS:
        raise ApiError(422, f"at most {MAX_LOCKS} locks", field="lock")
    with services.parse_slots:  # a bounded number of models are compiled at once
        return robots.upload(
            session,
            name=name,
            urdf=_optional(urdf, "urdf"),
            mjcf=_optional(mjcf, "mjcf"),
            package=_optional(package, "package", MAX_PACKAGE_BYTES),
            sidecar=_optional(sidecar, "sidecar"),
            payload=payload,
            options={
                "shoulder_joint": shoulder_joint,
                "elbow_joint": elbow_joint,
                "locks": parse_locks(lock or []),
                "base_link": base_link,
                "tip_link": tip_link,
                "urdf_member": urdf_member,
                "mjcf_member": mjcf_member,
                "sidecar_member": sidecar_member,
            },
            limits=UploadLimits.from_settings(services.settings),
        )


@router.delete("/{name}", status_code=204, dependencies=[WriteAccess])
def delete_robot(session: SessionDep, robots: RobotsDep, name: RobotName) -> Response:
    robots.delete(session, name)
    return Response(status_code=204)
