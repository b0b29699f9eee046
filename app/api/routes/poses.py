"""Pose extractions: the jobs that turn an uploaded video into landmarks (read only; a video
upload or ``POST /api/recordings/{id}/pose`` starts them, ``POST /api/jobs/{id}/cancel`` stops
one and its worker); the list and get routes are made by ``app.api.routes._results``."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query
from sqlalchemy.orm import Session

from app.api.routes._common import PROBLEM_RESPONSES
from app.api.routes._results import ResultRoutes, add_result_routes
from app.api.schemas import PoseOut
from app.services.results import get_result_row, job_of, pose_page

router = APIRouter(prefix="/api/poses", tags=["recordings"], responses=PROBLEM_RESPONSES)


def _out(row: Any, job: dict[str, Any]) -> dict[str, Any]:
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


def _item(session: Session, pose_id: int) -> dict[str, Any]:
    row = get_result_row(session, "pose", pose_id)
    return _out(row, job_of(session, row.id))


_GET_DOC = """A pose job and, once it succeeded: frames, frames with a person, fps, image size,
warnings, the landmarks file's id and how many skeleton frames were kept."""


add_result_routes(
    router,
    ResultRoutes(
        kind="pose",
        response_model=PoseOut,
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
