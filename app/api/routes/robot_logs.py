"""Robot logs: upload (read, matched and validated before storing), list, fetch, delete,
validate against a robot version (and a plan); identifications as background jobs."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, File, Form, Query, Response, UploadFile
from sqlalchemy.orm import Session

from app.api.deps import RobotsDep, ServicesDep, SessionDep, WriteAccess
from app.api.errors import ApiError
from app.api.result_models import IdentificationResultOut
from app.api.routes._common import PROBLEM_RESPONSES, IdPath, upload_name
from app.api.routes._results import ResultRoutes, add_result_routes
from app.api.schemas import (
    ROBOT_NAME,
    IdentifyRequest,
    RobotLogOut,
)
from app.services import Services, robot_logs
from app.services.results import get_result_row, job_of, list_results
from app.services.robots import check_data_quota

router = APIRouter(prefix="/api/robot-logs", tags=["robot logs"], responses=PROBLEM_RESPONSES)
identifications = APIRouter(
    prefix="/api/identifications", tags=["robot logs"], responses=PROBLEM_RESPONSES
)

#: Largest robot log accepted [bytes] (20 s of a 7-joint arm at 1 kHz as CSV is about 5 MB).
MAX_LOG_BYTES = 200 * 1024 * 1024


@router.post("", status_code=201, response_model=RobotLogOut, dependencies=[WriteAccess])
def upload_robot_log(
    services: ServicesDep,
    session: SessionDep,
    robots: RobotsDep,
    robot: Annotated[str, Form(pattern=ROBOT_NAME, description="the robot it was recorded on")],
    file: Annotated[
        UploadFile,
        File(
            description="generic CSV (time, <joint>/position|velocity|effort), UR RTDE CSV, or "
            "a ROS 2 bag folder as a zip (metadata.yaml and its .mcap/.db3)"
        ),
    ],
    topic: Annotated[
        str | None, Form(max_length=200, description="a bag's JointState topic")
    ] = None,
    label: Annotated[str | None, Form(max_length=200)] = None,
) -> dict[str, object]:
    """Read the log, match its joints to the robot's, validate it against the robot's model and
    store it. A log refused at any step (unknown joint names, time going back, a gap, a NaN run,
    too short, no torques) is a 422 naming the file and the line, channel or joint, and nothing
    is stored."""
    name = upload_name(file.filename, "robot-log.csv", field="file")
    data = file.file.read(MAX_LOG_BYTES + 1)
    if len(data) > MAX_LOG_BYTES:
        raise ApiError(413, f"{name}: robot logs are limited to {MAX_LOG_BYTES} bytes", file=name)
    settings = services.settings
    check_data_quota(settings.data_dir, int(settings.data_quota_mb * 1024 * 1024), name, len(data))
    with services.parse_slots:  # a bounded number of logs are read at once
        return robot_logs.upload_log(
            session,
            services.blobs,
            robots,
            robot=robot,
            file=(name, data),
            topic=topic or None,
            label=(label or "").strip() or None,
        )


@router.get("", response_model=list[RobotLogOut])
def list_robot_logs(
    session: SessionDep,
    robot: Annotated[str | None, Query(pattern=ROBOT_NAME)] = None,
) -> list[dict[str, object]]:
    """Stored logs, newest first (of one robot with ``robot``)."""
    return robot_logs.list_logs(session, robot)


@router.get("/{log_id:int}", response_model=RobotLogOut)
def get_robot_log(session: SessionDep, log_id: IdPath) -> dict[str, object]:
    return robot_logs.log_to_dict(robot_logs.get_log(session, log_id))


@router.get("/{log_id:int}/validation")
def validate_robot_log(
    services: ServicesDep,
    session: SessionDep,
    robots: RobotsDep,
    log_id: IdPath,
    robot: Annotated[
        str | None,
        Query(pattern=ROBOT_NAME, description="robot to predict with (default: the log's)"),
    ] = None,
    plan: Annotated[
        int | None,
        Query(ge=1, le=2**31 - 1, description="a stored plan the log executed"),
    ] = None,
    cutoff_hz: Annotated[
        float | None, Query(gt=0, le=1000, description="low-pass cutoff [Hz] (default 10)")
    ] = None,
) -> dict[str, object]:
    """Measured against predicted torque per joint (``bioplan validate --json``) with the
    plotted series (``series``: t [s], measured and predicted [Nm] per joint, power [W]),
    computed now (about half a second for 20 s at 1 kHz, so no job). With ``plan``: the log
    aligned to the plan, the tracking error and the planned against the measured saving."""
    with services.parse_slots:
        return robot_logs.validate_stored(
            session,
            services.blobs,
            robots,
            log_id,
            robot=robot,
            plan_id=plan,
            cutoff_hz=cutoff_hz,
        )


@router.delete("/{log_id:int}", status_code=204, dependencies=[WriteAccess])
def delete_robot_log(services: ServicesDep, session: SessionDep, log_id: IdPath) -> Response:
    robot_logs.delete_log(session, services.blobs, log_id)
    return Response(status_code=204)


def _submit(body: IdentifyRequest, session: Session, services: Services) -> dict[str, object]:
    params = robot_logs.identify_params(
        session,
        services.robots,
        log_ids=body.log_ids,
        version=body.version,
        validate_fraction=body.validate_fraction,
        cutoff_hz=body.cutoff_hz,
        identify_payload=body.identify_payload,
    )
    return services.jobs.submit(
        kind="identify",
        params=params,
        resource={"robot": params["robot"], "version": params["version"]},
        label=body.label,
    )


def _item(session: Session, identification_id: int) -> dict[str, object]:
    row = get_result_row(session, "identify", identification_id)
    return {
        "id": row.id,
        "robot": row.robot,
        "version": row.version,
        "job": job_of(session, row.id),
        "result": row.result,
    }


def _page(session: Session, **query: Any) -> tuple[list[dict[str, Any]], int]:
    items, total = list_results(session, "identify", **query)
    return [_item(session, int(item["id"])) for item in items], total


_SUBMIT_DOC = """\
Queue an identification (``bioplan identify``) from stored logs of one uploaded robot;
on success the identified robot is stored as ``version`` (its nominal files with the
identified sidecar), ready for plans and simulations. A log too short to identify from is a
422, a built-in robot or a taken name a 409; nothing is stored for a refused request."""

add_result_routes(
    identifications,
    ResultRoutes(
        kind="identify",
        noun="identification",
        plural="identifications",
        response_model=IdentificationResultOut,
        filters={"robot": Annotated[str | None, Query(pattern=ROBOT_NAME)]},
        page=_page,
        item=_item,
        submit=_submit,
        request=IdentifyRequest,
        docs={"submit": _SUBMIT_DOC, "list": "Identifications, newest first."},
    ),
)
