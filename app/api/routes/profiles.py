"""Profiles: classical point-to-point profiles, minimum torque change and the planning methods on
one task (``bioplan profiles``): submit (202 + job), list, fetch (``app.api.routes._results``)."""

from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy.orm import Session

from app.api.errors import ApiError
from app.api.routes._common import PROBLEM_RESPONSES
from app.api.routes._results import ROBOT_FILTER, ResultRoutes, add_result_routes
from app.api.schemas import ProfilesRequest, left_out
from app.services import Services

router = APIRouter(prefix="/api/profiles", tags=["profiles"], responses=PROBLEM_RESPONSES)


def _submit(body: ProfilesRequest, session: Session, services: Services) -> dict[str, object]:
    joints = services.robots.joints(session, body.robot)  # UnknownRobotError: 404 naming the field
    for name in ("start_deg", "goal_deg"):
        angles = getattr(body, name)
        if angles is not None and len(angles) != len(joints):
            raise ApiError(
                422, f"{name} needs {len(joints)} angles for {body.robot}, got {len(angles)}",
                field=name,
            )  # fmt: skip
    return services.jobs.submit(
        kind="profiles",
        params=body.model_dump(mode="json"),
        resource={"robot": body.robot},
        left_out=left_out(body),
    )


add_result_routes(
    router,
    ResultRoutes(
        kind="profiles",
        plural="profiles",
        filters={"robot": ROBOT_FILTER},
        submit=_submit,
        request=ProfilesRequest,
        docs={"submit": "Queue a profiles comparison; the result is ``bioplan profiles --json``."},
    ),
)
