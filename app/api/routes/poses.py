"""Pose extractions: the jobs that turn an uploaded video into landmarks (read only; a video
upload or ``POST /api/recordings/{id}/pose`` starts them, ``POST /api/jobs/{id}/cancel`` stops
one and its worker)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query

from app.api.deps import SessionDep
from app.api.routes._common import PROBLEM_RESPONSES, IdPath
from app.api.schemas import JobState, Page, PoseOut
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


@router.get("", response_model=Page[PoseOut])
def list_poses(
    session: SessionDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
    state: JobState | None = None,
    recording_id: Annotated[
        int | None, Query(ge=1, le=2**31 - 1, description="only this recording's")
    ] = None,
) -> dict[str, Any]:
    """Pose extractions, newest first; filter by job state and by recording."""
    rows, total = pose_page(
        session, limit=limit, offset=offset, state=state, recording_id=recording_id
    )
    items = [_out(row, job) for row, job in rows]
    return {"items": items, "total": total, "limit": limit, "offset": offset}


@router.get("/{pose_id:int}", response_model=PoseOut)
def get_pose(session: SessionDep, pose_id: IdPath) -> dict[str, Any]:
    """A pose job and, once it succeeded: frames, frames with a person, fps, image size,
    warnings, the landmarks file's id and how many skeleton frames were kept."""
    row = get_result_row(session, "pose", pose_id)
    return _out(row, job_of(session, row.id))
