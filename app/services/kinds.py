"""The job-kind registry: one record per kind, read by the job service, the runner's tasks,
storage and the routers.

Each layer holds its own part, keyed by the kind's name (``app.kinds``): the name and URL
segment in the kernel, the task function in ``app.jobs.tasks.TASKS``, the result table in
``app.db.models.RESULT_MODELS``. The record here joins them with what only the service layer
can do: build the task's payload from the stored request (files from the file store, a robot's
spec, an analysis's template) and store the task's output. A test checks that every kind has
every part. The API's request models are the routers' (``app.api``), which the service layer
does not import.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy.orm import Session

from app.db import crud
from app.db.blobs import BlobStore
from app.db.models import RESULT_MODELS, Analysis, JobRecord, ResultModel
from app.jobs.tasks import TASKS, JobResult, Payload, TaskFn
from app.kinds import JOB_KINDS, JobKindInfo
from app.services import cohorts, recordings, robot_logs
from app.services.errors import found
from app.services.job_views import not_finished
from app.services.robots import RobotCatalog


@dataclass(frozen=True)
class KindContext:
    """What payload builders and result stores may use besides the session.

    Attributes:
        blobs: the file store.
        robots: built-in and uploaded robots.
        max_video_seconds: longest video a pose job reads [s].
        scratch_dir: folder for pose jobs' temporary copies of videos (None: the system's).
        inline_result_bytes: largest result JSON kept in its row (None: always).
    """

    blobs: BlobStore
    robots: RobotCatalog
    max_video_seconds: float
    scratch_dir: Path | None = None
    inline_result_bytes: int | None = None


@dataclass(frozen=True)
class Stored:
    """What storing a job's output did.

    Attributes:
        error: why it was not stored (the job fails with it), or None.
        analyse_recording: a recording to analyse now (its video became pose), or None.
    """

    error: str | None = None
    analyse_recording: int | None = None


#: ``(session, context, params) -> payload``: a task's input from the request stored with it.
PayloadBuilder = Callable[[Session, KindContext, dict[str, object]], Payload]
#: ``(session, context, job, output) -> Stored``: keep a task's output.
ResultStore = Callable[[Session, KindContext, JobRecord, JobResult], Stored]


@dataclass(frozen=True)
class JobKind:
    """Everything the service knows of one job kind.

    Attributes:
        info: name and URL segment (``app.kinds``).
        task: the job function (``app.jobs.tasks``).
        result_model: the result table (``app.db.models``).
        payload: builds the task's input from the stored request.
        store: keeps the task's output.
    """

    info: JobKindInfo
    task: TaskFn
    result_model: type[ResultModel]
    payload: PayloadBuilder
    store: ResultStore

    @property
    def name(self) -> str:
        return self.info.name

    @property
    def path(self) -> str:
        return self.info.path


def analysis_template(session: Session, analysis_id: int) -> dict[str, object]:
    """The human template of a finished analysis.

    Raises:
        NotFoundError: no such analysis.
        ConflictError: it has no template (yet).
    """
    row = found(session.get(Analysis, analysis_id), f"analysis {analysis_id}")
    if row.template is None:
        raise not_finished(session, analysis_id, f"analysis {analysis_id}", lacks="no template yet")
    return row.template


# payloads ------------------------------------------------------------------------------------


def _robot_payload(info: JobKindInfo) -> PayloadBuilder:
    """The payload of a kind whose request names a robot: the request with the robot's spec
    and (kinds that take one) the named analysis's human template."""

    def build(session: Session, ctx: KindContext, params: dict[str, Any]) -> Payload:
        payload = dict(params)
        payload["robot"] = ctx.robots.spec(session, params["robot"])
        if info.template and params.get("template_analysis_id") is not None:
            payload["template"] = analysis_template(session, params["template_analysis_id"])
        payload.pop("template_analysis_id", None)
        return payload

    return build


def _analysis_payload(session: Session, ctx: KindContext, params: dict[str, object]) -> Payload:
    return recordings.analysis_payload(session, ctx.blobs, params)


def _pose_payload(session: Session, ctx: KindContext, params: dict[str, object]) -> Payload:
    scratch = None if ctx.scratch_dir is None else str(ctx.scratch_dir)
    return recordings.pose_payload(
        session, ctx.blobs, params, max_seconds=ctx.max_video_seconds, scratch_dir=scratch
    )


def _cohort_payload(session: Session, ctx: KindContext, params: dict[str, object]) -> Payload:
    return cohorts.cohort_payload(session, ctx.blobs, params)


def _identify_payload(session: Session, ctx: KindContext, params: dict[str, object]) -> Payload:
    return robot_logs.identify_payload(session, ctx.blobs, ctx.robots, params)


# results -------------------------------------------------------------------------------------


def _store_result(session: Session, ctx: KindContext, job: JobRecord, out: JobResult) -> Stored:
    """A result row of the job's kind (large results go to the file store)."""
    crud.store_result(
        session=session,
        job_id=job.id,
        kind=job.kind,
        result=out["result"],
        arrays=out.get("arrays"),
        template=out.get("template"),
        blobs=ctx.blobs,
        inline_bytes=ctx.inline_result_bytes,
    )
    return Stored()


def _store_pose(session: Session, ctx: KindContext, job: JobRecord, out: JobResult) -> Stored:
    """The landmarks as a recording file of the video's session, then its analysis."""
    if recordings.store_pose(session, ctx.blobs, job.id, dict(out)):
        return Stored(analyse_recording=int(job.params["recording_id"]))
    # cancelled meanwhile (left as it is) or its video deleted
    return Stored(error="its video was deleted before the landmarks were stored")


def _store_identification(
    session: Session, ctx: KindContext, job: JobRecord, out: JobResult
) -> Stored:
    """The identification and the robot version carrying its sidecar."""
    why = robot_logs.store_identification(
        session, ctx.blobs, ctx.robots, job.id, dict(out), inline_bytes=ctx.inline_result_bytes
    )
    return Stored() if why is None else Stored(error=f"not stored: {why}")


def _kind(
    name: str, payload: PayloadBuilder | None = None, store: ResultStore = _store_result
) -> JobKind:
    info = JOB_KINDS[name]
    return JobKind(
        info=info,
        task=TASKS[name],
        result_model=RESULT_MODELS[name],
        payload=payload or _robot_payload(info),
        store=store,
    )


#: Every job kind's record, by name (the order of ``app.kinds.JOB_KINDS``).
KINDS: dict[str, JobKind] = {
    k.name: k
    for k in (
        _kind("analysis", _analysis_payload),
        _kind("pose", _pose_payload, _store_pose),
        _kind("plan"),
        _kind("simulation"),
        _kind("sweep"),
        _kind("profiles"),
        _kind("cohort", _cohort_payload),
        _kind("identify", _identify_payload, _store_identification),
        _kind("front"),
    )
}
