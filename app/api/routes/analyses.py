"""Analyses: submit (202 + job), list, fetch the result and the human template."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Response

from app.api.deps import JobsDep, SessionDep, WriteAccess
from app.api.errors import ApiError
from app.api.routes._common import PROBLEM_RESPONSES, IdPath
from app.api.schemas import AnalysisOut, AnalysisRequest, Job, JobState, Page
from app.services.recording_views import analysis_summary
from app.services.recordings import analysis_params
from app.services.results import get_result_row, job_of, list_results

router = APIRouter(prefix="/api/analyses", tags=["analyses"], responses=PROBLEM_RESPONSES)


@router.post("", status_code=202, response_model=Job, dependencies=[WriteAccess])
def submit_analysis(
    body: AnalysisRequest, session: SessionDep, jobs: JobsDep, response: Response
) -> dict[str, Any]:
    """Queue an analysis of a stored recording; poll the job or follow its events.

    Options left out take the recording's (its EMG rate, muscle map, excluded channels,
    session mode, load); the job's ``params`` are the options it runs with. 409 while the
    recording's video is being turned into pose (the problem's ``job``: that pose job).
    """
    params = analysis_params(session, body.model_dump(mode="json"))
    job = jobs.submit(kind="analysis", params=params, resource={"recording_id": body.recording_id})
    response.headers["Location"] = job["result_url"]
    return job


@router.get("", response_model=Page[AnalysisOut])
def list_analyses(
    session: SessionDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
    state: JobState | None = None,
    recording_id: Annotated[
        int | None, Query(ge=1, le=2**31 - 1, description="only this recording's analyses")
    ] = None,
) -> dict[str, Any]:
    """Analyses, newest first; filter by job state and by recording. Each finished one has a
    ``summary``: where its template came from (``is_paper_default``), lifts, every warning."""
    items, total = list_results(
        session,
        "analysis",
        limit=limit,
        offset=offset,
        state=state,
        recording_id=recording_id,
    )
    for item in items:
        item["summary"] = analysis_summary(item["result"])
    return {"items": items, "total": total, "limit": limit, "offset": offset}


@router.get("/{analysis_id:int}", response_model=AnalysisOut)
def get_analysis(session: SessionDep, analysis_id: IdPath) -> dict[str, Any]:
    row = get_result_row(session, "analysis", analysis_id)
    return {
        "id": row.id,
        "recording_id": row.recording_id,
        "job": job_of(session, row.id),
        "summary": analysis_summary(row.result),
        "result": row.result,
        "template": row.template,
    }


@router.get("/{analysis_id:int}/template", response_model=dict[str, Any])
def get_template(session: SessionDep, analysis_id: IdPath) -> dict[str, Any]:
    """The HumanTemplate JSON (what ``bioplan analyze --out`` writes; ``plan --template``)."""
    row = get_result_row(session, "analysis", analysis_id)
    if row.template is None:
        state = job_of(session, row.id)["state"]
        raise ApiError(409, f"analysis {analysis_id} has no template yet (job state {state})")
    template: dict[str, Any] = row.template
    return template
