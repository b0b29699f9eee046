"""Sweeps: submit (202 + job), list, fetch results (``app.api.routes._results``)."""

from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy.orm import Session

from app.api.routes._common import PROBLEM_RESPONSES
from app.api.routes._results import ResultRoutes, add_result_routes
from app.api.schemas import SweepRequest
from app.services import Services

router = APIRouter(prefix="/api/sweeps", tags=["sweeps"], responses=PROBLEM_RESPONSES)


def _submit(body: SweepRequest, session: Session, services: Services) -> dict[str, object]:
    services.robots.joints(session, body.robot)  # UnknownRobotError: 404 naming the field
    return services.jobs.submit(
        kind="sweep", params=body.model_dump(mode="json"), resource={"robot": body.robot}
    )


add_result_routes(
    router,
    ResultRoutes(
        kind="sweep",
        submit=_submit,
        request=SweepRequest,
        docs={"submit": "Queue a sweep (``bioplan sweep``); progress is reported per grid cell."},
    ),
)
