"""Jobs: status, progress as Server-Sent Events, cancel."""

from __future__ import annotations

from collections.abc import AsyncIterator, Callable
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request
from fastapi.responses import StreamingResponse
from starlette.concurrency import run_in_threadpool

from app.api.deps import JobsDep, ServicesDep, SessionDep, WriteAccess
from app.api.routes._common import PROBLEM_RESPONSES, IdPath
from app.api.schemas import Job, JobKind, JobState, JobSummary, Page
from app.db import crud
from app.names import TERMINAL_JOB_STATES
from app.services import ALL_JOBS, Services, Subscription, job_summary, job_to_dict

router = APIRouter(prefix="/api/jobs", tags=["jobs"], responses=PROBLEM_RESPONSES)
#: Streams about many jobs at once (the dashboard's job drawer).
events_router = APIRouter(prefix="/api/events", tags=["jobs"], responses=PROBLEM_RESPONSES)

#: Seconds between database re-reads while waiting for updates (catches anything missed).
RESYNC_SECONDS = 2.0
#: Seconds between keep-alive comments on a quiet stream.
KEEPALIVE_SECONDS = 15.0


@router.get("", response_model=Page[Job])
def list_jobs(
    session: SessionDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
    kind: JobKind | None = None,
    state: JobState | None = None,
) -> dict[str, Any]:
    items, total = crud.list_jobs(
        session=session, limit=limit, offset=offset, kind=kind, state=state
    )
    return {
        "items": [job_to_dict(j) for j in items],
        "total": total,
        "limit": limit,
        "offset": offset,
    }


@router.get("/{job_id:int}", response_model=Job)
def get_job(jobs: JobsDep, job_id: IdPath) -> dict[str, Any]:
    """A job: state, structured progress (``stage``, ``done`` of ``of``, ``best``), timings."""
    return jobs.get(job_id)


@router.post("/{job_id:int}/cancel", response_model=Job, dependencies=[WriteAccess])
def cancel_job(jobs: JobsDep, job_id: IdPath) -> dict[str, Any]:
    """Cancel a queued or running job (a running one is stopped); 409 when it already ended."""
    return jobs.cancel(job_id)


async def _subscribed(
    services: Services, key: int, read: Callable[..., Any], *args: Any
) -> tuple[Subscription, Any]:
    """Subscribe to ``key``'s updates, then read the snapshot (so no update is lost)."""
    sub = services.broker.subscribe(key)
    try:
        return sub, await run_in_threadpool(read, *args)
    except BaseException:
        sub.close()
        raise


def _event_stream(events: AsyncIterator[str]) -> StreamingResponse:
    return StreamingResponse(
        events,
        media_type="text/event-stream",
        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
    )


def _same(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Nothing a client shows changed between two reads of a job."""
    keys = ("state", "progress", "stage", "done", "best", "message")
    return all(a[k] == b[k] for k in keys)


def _sse(event: str, data: dict[str, Any], model: type[Job | JobSummary] = Job) -> str:
    return f"event: {event}\ndata: {model.model_validate(data).model_dump_json()}\n\n"


@router.get(
    "/{job_id:int}/events",
    response_class=StreamingResponse,
    responses={
        200: {
            "description": "`event: progress` with the job as JSON on every update, then one "
            "`event: done` when it ends",
            "content": {"text/event-stream": {}},
        }
    },
)
async def job_events(request: Request, services: ServicesDep, job_id: IdPath) -> StreamingResponse:
    """Progress as Server-Sent Events until the job succeeds, fails or is cancelled."""
    sub, snapshot = await _subscribed(services, job_id, services.jobs.get, job_id)

    async def stream() -> AsyncIterator[str]:
        last = snapshot
        quiet = 0.0
        try:
            yield _sse("progress", last)
            while last["state"] not in TERMINAL_JOB_STATES:
                update = await sub.get(RESYNC_SECONDS)
                if update is None:
                    if await request.is_disconnected():
                        return
                    update = await run_in_threadpool(services.jobs.find, job_id)
                    if update is None:
                        return
                    if _same(update, last):
                        quiet += RESYNC_SECONDS
                        if quiet >= KEEPALIVE_SECONDS:
                            quiet = 0.0
                            yield ": keep-alive\n\n"
                        continue
                quiet = 0.0
                last = update
                yield _sse("progress", last)
            yield _sse("done", last)
        finally:
            sub.close()

    return _event_stream(stream())


def _sse_summaries(event: str, jobs: list[dict[str, Any]]) -> str:
    data = ",".join(JobSummary.model_validate(job).model_dump_json() for job in jobs)
    return f"event: {event}\ndata: [{data}]\n\n"


@events_router.get(
    "/jobs",
    response_class=StreamingResponse,
    responses={
        200: {
            "description": "`event: jobs` first: a JSON array of the newest `recent` jobs and "
            "every active one (JobSummary, newest first); then `event: job` with one JobSummary "
            "on every change of any job (new, progress, state). The stream stays open.",
            "content": {"text/event-stream": {}},
        }
    },
)
async def all_job_events(
    request: Request,
    services: ServicesDep,
    recent: Annotated[int, Query(ge=1, le=200, description="finished jobs listed first")] = 20,
) -> StreamingResponse:
    """Every job's changes as Server-Sent Events: what the dashboard's job drawer follows."""
    sub, snapshot = await _subscribed(services, ALL_JOBS, services.jobs.recent, recent)

    async def stream() -> AsyncIterator[str]:
        shown = {job["id"]: job for job in snapshot}
        quiet = 0.0
        try:
            yield _sse_summaries("jobs", snapshot)
            while True:
                update = await sub.get(RESYNC_SECONDS)
                if update is not None:
                    updates = [job_summary(update)]
                else:
                    if await request.is_disconnected():
                        return
                    # Catch what no event told (another process's jobs, a dropped update).
                    active = [i for i, j in shown.items() if j["state"] not in TERMINAL_JOB_STATES]
                    fresh = await run_in_threadpool(services.jobs.recent, 1, active)
                    updates = [
                        j for j in fresh if j["id"] not in shown or not _same(j, shown[j["id"]])
                    ]
                for job in reversed(updates):  # oldest first
                    quiet = 0.0
                    shown[job["id"]] = job
                    yield _sse("job", job, JobSummary)
                if not updates:
                    quiet += RESYNC_SECONDS
                    if quiet >= KEEPALIVE_SECONDS:
                        quiet = 0.0
                        yield ": keep-alive\n\n"
        finally:
            sub.close()

    return _event_stream(stream())
