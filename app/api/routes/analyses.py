"""Analyses: submit (202 + job), list, fetch (``app.api.routes._results``), and the human
template."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query
from sqlalchemy.orm import Session

from app.api.deps import SessionDep
from app.api.result_models import AnalysisResultOut, HumanTemplateOut
from app.api.routes._common import PROBLEM_RESPONSES, IdPath
from app.api.routes._results import ResultRoutes, add_result_routes
from app.api.schemas import AnalysisRequest
from app.services import Services
from app.services.job_views import not_finished
from app.services.recording_views import analysis_summary
from app.services.recordings import analysis_params
from app.services.results import get_result_row, job_of

router = APIRouter(prefix="/api/analyses", tags=["analyses"], responses=PROBLEM_RESPONSES)


def _submit(body: AnalysisRequest, session: Session, services: Services) -> dict[str, object]:
    params = analysis_params(session, body.model_dump(mode="json"))
    return services.jobs.submit(
        kind="analysis", params=params, resource={"recording_id": body.recording_id}
    )


def _item(session: Session, analysis_id: int) -> dict[str, object]:
    row = get_result_row(session, "analysis", analysis_id)
    return {
        "id": row.id,
        "recording_id": row.recording_id,
        "job": job_of(session, row.id),
        "result": row.result,
        "template": row.template,
    }


def _summarised(session: Session, item: dict[str, object]) -> dict[str, object]:
    result = item["result"]
    return {**item, "summary": analysis_summary(result if isinstance(result, dict) else None)}


_SUBMIT_DOC = """Queue an analysis of a stored recording; poll the job or follow its events.

Options left out take the recording's (its EMG rate, muscle map, excluded channels,
session mode, load); the job's ``params`` are the options it runs with. 409 while the
recording's video is being turned into pose (the problem's ``job``: that pose job)."""
_LIST_DOC = """Analyses, newest first; filter by job state and by recording. Each finished one has a
``summary``: where its template came from (``is_paper_default``), lifts, every warning."""


add_result_routes(
    router,
    ResultRoutes(
        kind="analysis",
        plural="analyses",
        response_model=AnalysisResultOut,
        filters={
            "recording_id": Annotated[
                int | None,
                Query(ge=1, le=2**31 - 1, description="only this recording's analyses"),
            ]
        },
        item=_item,
        shape=_summarised,
        submit=_submit,
        request=AnalysisRequest,
        docs={"submit": _SUBMIT_DOC, "list": _LIST_DOC},
    ),
)


@router.get(
    "/{analysis_id:int}/template",
    response_model=HumanTemplateOut,
    response_model_exclude_unset=True,  # the stored JSON as it is: no keys added as null
)
def get_template(session: SessionDep, analysis_id: IdPath) -> dict[str, object]:
    """The HumanTemplate JSON (what ``bioplan analyze --out`` writes; ``plan --template``)."""
    row = get_result_row(session, "analysis", analysis_id)
    if row.template is None:
        raise not_finished(session, row.id, f"analysis {analysis_id}", lacks="no template yet")
    template: dict[str, object] = row.template
    return template
