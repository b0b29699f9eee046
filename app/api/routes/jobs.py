"""Jobs: status, progress as Server-Sent Events, cancel.

Every event stream is counted under the caps of ``app.services.broker.StreamLimits`` (in all and
per client address; beyond them 429 with ``Retry-After``), ends after ``BIOPLAN_STREAM_IDLE_S``
without a change to report (keep-alive comments do not count: the browser's ``EventSource``
reconnects by itself and gets a fresh snapshot) and ends at once when the server stops.
"""

from __future__ import annotations

import time
from collections.abc import AsyncIterator, Callable
from typing import Annotated, TypeVar

from fastapi import APIRouter, Query, Request
from fastapi.responses import StreamingResponse
from pydantic import BaseModel, Field
from starlette.concurrency import run_in_threadpool
from starlette.types import Receive, Scope, Send

from app.api.deps import JobsDep, ServicesDep, SessionDep, WriteAccess
from app.api.errors import ApiError
from app.api.routes._common import PROBLEM_RESPONSES, IdPath
from app.api.schemas import Job, JobKind, JobState, JobSummary, Page, Problem
from app.names import TERMINAL_JOB_STATES
from app.services import ALL_JOBS, Services, Subscription, job_summary
from app.services.broker import StreamRefused, StreamTicket
from app.services.results import job_page

T = TypeVar("T")

router = APIRouter(prefix="/api/jobs", tags=["jobs"], responses=PROBLEM_RESPONSES)
#: Streams about many jobs at once (the dashboard's job drawer).
events_router = APIRouter(prefix="/api/events", tags=["jobs"], responses=PROBLEM_RESPONSES)

#: Seconds between database re-reads while waiting for updates (catches anything missed).
RESYNC_SECONDS = 2.0
#: Seconds between keep-alive comments on a quiet stream.
KEEPALIVE_SECONDS = 15.0
#: What a stream says before it ends for being idle (a comment: the page ignores it).
IDLE_END = ": idle: nothing changed for {:g} s; reconnect for a fresh snapshot\n\n"

#: The 429 of a refused stream, in the OpenAPI document.
STREAM_REFUSED: dict[int | str, dict[str, object]] = {
    429: {
        "description": "Too many open event streams (BIOPLAN_MAX_STREAMS or "
        "BIOPLAN_MAX_STREAMS_PER_CLIENT); `Retry-After` says when to try again",
        "content": {"application/problem+json": {"schema": Problem.model_json_schema()}},
    }
}


@router.get("", response_model=Page[Job])
def list_jobs(
    session: SessionDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
    kind: JobKind | None = None,
    state: JobState | None = None,
) -> dict[str, object]:
    items, total = job_page(session, limit=limit, offset=offset, kind=kind, state=state)
    return {
        "items": items,
        "total": total,
        "limit": limit,
        "offset": offset,
    }


@router.get("/{job_id:int}", response_model=Job)
def get_job(jobs: JobsDep, job_id: IdPath) -> dict[str, object]:
    """A job: state, structured progress (``stage``, ``done`` of ``of``, ``best``), timings."""
    return jobs.get(job_id)


@router.post("/{job_id:int}/cancel", response_model=Job, dependencies=[WriteAccess])
def cancel_job(jobs: JobsDep, job_id: IdPath) -> dict[str, object]:
    """Cancel a queued or running job (a running one is stopped); 409 when it already ended."""
    return jobs.cancel(job_id)


class JobLog(BaseModel):
    """A job's log: the science packages' records at INFO and above (``app.logs``)."""

    job_id: int
    state: JobState
    complete: bool = Field(
        description="the job ended and this is all of its log; while it is queued or running "
        "the log is not here yet (a running job's lines arrive with its end)"
    )
    lines: list[str] = Field(
        description="oldest first, one record each ('HH:MM:SS LEVEL logger: message'); the "
        "last 500 lines and at most 64 kB (a first line says how many were left out); "
        "folders cut from paths"
    )


@router.get("/{job_id:int}/log", response_model=JobLog)
def get_job_log(jobs: JobsDep, job_id: IdPath) -> dict[str, object]:
    """What the job's science said while it ran: methods, solve times, channels, failures."""
    return jobs.log(job_id)


def _open_stream(request: Request, services: Services) -> StreamTicket:
    """A place under the stream caps for this client, or a 429 problem."""
    client = request.client.host if request.client is not None else "unknown"
    try:
        return services.streams.open(client)
    except StreamRefused as exc:
        raise ApiError(
            429,
            exc.detail,
            title="Too Many Requests",
            # Closed at once: a client opening streams in a loop must not keep a descriptor
            # per refusal for the keep-alive time.
            headers={"Retry-After": str(exc.retry_after), "Connection": "close"},
        ) from None


async def _subscribed(
    services: Services, ticket: StreamTicket, key: int, read: Callable[..., T], *args: object
) -> tuple[Subscription, T]:
    """Subscribe to ``key``'s updates, then read the snapshot (so no update is lost); the
    ticket is released when either fails."""
    try:
        sub = services.broker.subscribe(key)
    except BaseException:
        ticket.release()
        raise
    try:
        return sub, await run_in_threadpool(read, *args)
    except BaseException:
        sub.close()
        ticket.release()
        raise


class _EventStream(StreamingResponse):
    """A stream that gives back its place under the caps and its subscription however it ends
    (even when the client leaves before the first byte, and the generator never starts)."""

    def __init__(self, events: AsyncIterator[str], ticket: StreamTicket, sub: Subscription) -> None:
        super().__init__(
            events,
            media_type="text/event-stream",
            headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
        )
        self.ticket = ticket
        self.sub = sub

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        try:
            await super().__call__(scope, receive, send)
        finally:
            self.sub.close()
            self.ticket.release()


class _Idle:
    """When a stream last had something to report, and its keep-alive rhythm."""

    def __init__(self, idle_s: float) -> None:
        self.idle_s = idle_s
        self.changed = self.kept = time.monotonic()

    def change(self) -> None:
        self.changed = self.kept = time.monotonic()

    def expired(self) -> bool:
        return time.monotonic() - self.changed >= self.idle_s

    def keepalive(self) -> bool:
        """True when a keep-alive comment is due (it does not count as a change)."""
        now = time.monotonic()
        if now - self.kept >= KEEPALIVE_SECONDS:
            self.kept = now
            return True
        return False


def _same(a: dict[str, object], b: dict[str, object]) -> bool:
    """Nothing a client shows changed between two reads of a job."""
    keys = ("state", "progress", "stage", "done", "best", "message")
    return all(a[k] == b[k] for k in keys)


def _sse(event: str, data: dict[str, object], model: type[Job | JobSummary] = Job) -> str:
    return f"event: {event}\ndata: {model.model_validate(data).model_dump_json()}\n\n"


@router.get(
    "/{job_id:int}/events",
    response_class=StreamingResponse,
    responses={
        200: {
            "description": "`event: progress` with the job as JSON on every update, then one "
            "`event: done` when it ends. A stream with nothing new for BIOPLAN_STREAM_IDLE_S "
            "ends early (reconnect: the first event is the job as it is now), as every stream "
            "does when the server stops.",
            "content": {"text/event-stream": {}},
        },
        **STREAM_REFUSED,
    },
)
async def job_events(request: Request, services: ServicesDep, job_id: IdPath) -> StreamingResponse:
    """Progress as Server-Sent Events until the job succeeds, fails or is cancelled."""
    ticket = _open_stream(request, services)
    sub, snapshot = await _subscribed(services, ticket, job_id, services.jobs.get, job_id)
    idle = _Idle(services.streams.idle_s)

    async def stream() -> AsyncIterator[str]:
        last = snapshot
        yield _sse("progress", last)
        while last["state"] not in TERMINAL_JOB_STATES:
            update = await sub.get(RESYNC_SECONDS)
            if sub.closed:
                return
            if update is None:
                if await request.is_disconnected():
                    return
                update = await run_in_threadpool(services.jobs.find, job_id)
                if update is None:
                    return
                if _same(update, last):
                    if idle.expired():
                        yield IDLE_END.format(idle.idle_s)
                        return
                    if idle.keepalive():
                        yield ": keep-alive\n\n"
                    continue
            idle.change()
            last = update
            yield _sse("progress", last)
        yield _sse("done", last)

    return _EventStream(stream(), ticket, sub)


def _sse_summaries(event: str, jobs: list[dict[str, object]]) -> str:
    data = ",".join(JobSummary.model_validate(job).model_dump_json() for job in jobs)
    return f"event: {event}\ndata: [{data}]\n\n"


@events_router.get(
    "/jobs",
    response_class=StreamingResponse,
    responses={
        200: {
            "description": "`event: jobs` first: a JSON array of the newest `recent` jobs and "
            "every active one (JobSummary, newest first); then `event: job` with one JobSummary "
            "on every change of any job (new, progress, state). The stream stays open while "
            "something changes; after BIOPLAN_STREAM_IDLE_S without a change it ends "
            "(reconnect: the first event is the list as it is now), as every stream does when "
            "the server stops.",
            "content": {"text/event-stream": {}},
        },
        **STREAM_REFUSED,
    },
)
async def all_job_events(
    request: Request,
    services: ServicesDep,
    recent: Annotated[int, Query(ge=1, le=200, description="finished jobs listed first")] = 20,
) -> StreamingResponse:
    """Every job's changes as Server-Sent Events: what the dashboard's job drawer follows."""
    ticket = _open_stream(request, services)
    sub, snapshot = await _subscribed(services, ticket, ALL_JOBS, services.jobs.recent, recent)
    idle = _Idle(services.streams.idle_s)

    async def stream() -> AsyncIterator[str]:
        shown = {job["id"]: job for job in snapshot}
        yield _sse_summaries("jobs", snapshot)
        while True:
            update = await sub.get(RESYNC_SECONDS)
            if sub.closed:
                return
            if update is not None:
                updates = [job_summary(update)]
            else:
                if await request.is_disconnected():
                    return
                # Catch what no event told (another process's jobs, a dropped update).
                active = [i for i, j in shown.items() if j["state"] not in TERMINAL_JOB_STATES]
                fresh = await run_in_threadpool(services.jobs.recent, 1, active)
                updates = [j for j in fresh if j["id"] not in shown or not _same(j, shown[j["id"]])]
            for job in reversed(updates):  # oldest first
                idle.change()
                shown[job["id"]] = job
                yield _sse("job", job, JobSummary)
            if not updates:
                if idle.expired():
                    yield IDLE_END.format(idle.idle_s)
                    return
                if idle.keepalive():
                    yield ": keep-alive\n\n"

    return _EventStream(stream(), ticket, sub)
