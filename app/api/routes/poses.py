"""Pose extractions: the jobs that turn an uploaded video into landmarks (read only; a video
upload or ``POST /api/recordings/{id}/pose`` starts them, ``POST /api/jobs/{id}/cancel`` stops
one and its worker); the list and get routes are made by ``app.api.routes._results``."""

from __future__ import annotations

from typing import Annotated, Any, Protocol

from fastapi import APIRouter, Query
from sqlalchemy.orm import Session

from app.api.result_models import PoseResultOut
from app.api.routes._common import PROBLEM_RESPONSES
from app.api.routes._results import ResultRoutes, add_result_routes
from app.services.results import get_result_row, job_of, pose_page

router = APIRouter(prefix="/api/poses", tags=["recordings"], responses=PROBLEM_RESPONSES)


class _PoseRow(Protocol):
    """What the routes read of a stored pose extraction."""

    @property
    def id(self) -> int: ...

    @property
    def recording_id(self) -> int | None: ...

    @property
    def video_file_id(self) -> int | None: ...

    @property
    def result(self) -> object: ...


def _out(row: _PoseRow, job: dict[str, object]) -> dict[str, object]:
    return {
        "id": row.id,
        "recording_id": row.recording_id,
        "video_file_id": row.video_file_id,
        "job": job,
        "result": row.result,
    }


def _page(session: Session, **query: Any) -> tuple[list[dict[str, Any]], int]:
    rows, total = pose_page(session, **query)
    return [_out(row, job) for row, job in rows], total


def _item(session: Session, pose_id: int) -> dict[str, object]:
    row = get_result_row(session, "pose", pose_id)
    return _out(row, job_of(session, row.id))


_GET_DOC = """A pose job and, once it succeeded: frames, frames with a person, fps, image size,
warnings, the landmarks file's id and how many skeleton frames were kept."""


add_result_routes(
    router,
    ResultRoutes(
        kind="pose",
        response_model=PoseResultOut,
        filters={
            "recording_id": Annotated[
                int | None, Query(ge=1, le=2**31 - 1, description="only this recording's")
            ]
        },
        page=_page,
        item=_item,
        docs={
            "list": "Pose extractions, newest first; filter by job state and by recording.",
            "get": _GET_DOC,
        },
    ),
)
