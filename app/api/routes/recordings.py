"""Recordings: upload (multipart: recordings, BIDS sidecars, videos), list, detail, changes
(``PATCH``: metadata, session mode, reader options, excluded channels, then a rerun), signals
for plotting, raw files, a video's skeleton frames and pose extraction, delete."""

from __future__ import annotations

import contextlib
import json
import re
from typing import Annotated, get_args

from fastapi import APIRouter, File, Form, Path, Query, Request, Response, UploadFile
from pydantic import Field, TypeAdapter
from sqlalchemy.orm import Session
from starlette.concurrency import run_in_threadpool

from app.api.deps import ServicesDep, SessionDep, WriteAccess
from app.api.errors import ApiError
from app.api.routes._common import (
    MAX_POINTS,
    PROBLEM_RESPONSES,
    IdPath,
    IsoDateTimeQuery,
    file_answer,
    upload_name,
    utc,
)
from app.api.schemas import (
    EMG_RATE_MIN_HZ,
    IMAGE_SIZE,
    RATE_MAX_HZ,
    Page,
    ReaderFormat,
    RecordingDetail,
    RecordingPatch,
    RecordingSummary,
    SessionMode,
    Signals,
    Site,
    SkeletonFrames,
    blank_label_is_none,
)
from app.services import (
    ConflictError,
    Services,
    check_data_quota,
    job_to_dict,
    store_recording,
)
from app.services.recording_views import recording_detail, signals
from app.services.recordings import (
    active_pose_jobs,
    is_video_upload,
    pose_environment_problem,
    raw_file,
    rerun_params,
    skeleton_frame,
    skeleton_frame_list,
    skeleton_jpeg,
    update_recording,
    videos_without_pose,
)
from app.services.recordings import (
    delete_recording as delete_stored,
)
from app.services.recordings import (
    get_recording as get_stored,
)
from app.services.recordings import (
    list_recordings as list_stored,
)

router = APIRouter(prefix="/api/recordings", tags=["recordings"], responses=PROBLEM_RESPONSES)

_SITES: set[str] = {*get_args(Site), "none"}


def _muscle_map(text: str | None) -> dict[str, str] | None:
    if text is None or not text.strip():
        return None
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ApiError(
            422,
            f'muscle_map must be a JSON object such as {{"Biceps.EMG4": "biceps"}}: {exc.msg}',
            field="muscle_map",
        ) from None
    if not isinstance(value, dict) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in value.items()
    ):
        raise ApiError(422, "muscle_map must map channel labels to site names", field="muscle_map")
    bad = sorted(v for v in value.values() if v not in _SITES)
    if bad:
        raise ApiError(
            422,
            f"muscle_map names unknown sites {bad} (expected {sorted(_SITES)})",
            field="muscle_map",
        )
    return value


def _image_size(text: str | None) -> tuple[int, int] | None:
    """``WIDTHxHEIGHT`` as two ints; the schema states the same ``IMAGE_SIZE`` pattern."""
    if text is None or not text.strip():
        return None
    if re.fullmatch(IMAGE_SIZE, text) is None:
        raise ApiError(
            422,
            f"image_size must be WIDTHxHEIGHT in pixels (1 to 99999 each), got {text!r}",
            field="image_size",
        )
    w, h = text.lower().split("x")
    return int(w), int(h)


_UploadFiles = Annotated[
    list[UploadFile],
    File(
        min_length=1,
        description="recording files (format detected from content), BIDS sidecars of an"
        " EDF (<stem>_channels.tsv, <stem>_emg.json), videos (mp4, mov, avi)",
    ),
]
_SessionForm = Annotated[
    SessionMode,
    Form(
        alias="session",
        description="separate: trials on their own clocks (default); together: recorded at"
        " the same time (e.g. an EMG file and the video of the same lifts)",
    ),
]
_MuscleMapForm = Annotated[
    str | None,
    Form(description='JSON object: channel label -> site, e.g. {"Biceps.EMG4": "biceps"}'),
]
_ImageSizeForm = Annotated[
    str | None,
    Form(
        json_schema_extra={"pattern": IMAGE_SIZE},  # checked by _image_size, in words
        description="WIDTHxHEIGHT [px] for normalised landmarks",
    ),
]


def _read_uploads(services: Services, files: list[UploadFile]) -> list[tuple[str, bytes]]:
    """(checked file name, content) of every upload; a 4xx when together they would take the
    data directory over its quota."""
    uploads = [
        (upload_name(f.filename, f"upload-{i + 1}", field="files"), f.file.read())
        for i, f in enumerate(files)
    ]
    settings = services.settings
    check_data_quota(
        settings.data_dir,
        int(settings.data_quota_mb * 1024 * 1024),
        uploads[0][0] if uploads else "files",
        sum(len(data) for _, data in uploads),
        what=f"{len(uploads)} file(s)",
    )
    return uploads


@router.post(
    "",
    status_code=201,
    response_model=RecordingDetail,
    dependencies=[WriteAccess],
    summary="Upload a recording session (one or more files)",
)
def upload_recording(
    services: ServicesDep,
    session: SessionDep,
    files: _UploadFiles,
    subject: Annotated[str | None, Form(max_length=200)] = None,
    task: Annotated[str | None, Form(max_length=200)] = None,
    load_kg: Annotated[float | None, Form(ge=0, le=100, description="load lifted [kg]")] = None,
    notes: Annotated[str | None, Form(max_length=10000)] = None,
    label: Annotated[
        str | None, Form(max_length=200, description="a short name for the session")
    ] = None,
    condition: Annotated[
        str | None,
        Form(max_length=100, description="the experimental condition (a cohort groups by it)"),
    ] = None,
    session_mode: _SessionForm = "separate",
    muscle_map: _MuscleMapForm = None,
    rate: Annotated[
        float | None, Form(ge=1, le=RATE_MAX_HZ, description="rate of files that state none [Hz]")
    ] = None,
    emg_rate: Annotated[
        float | None, Form(ge=EMG_RATE_MIN_HZ, le=RATE_MAX_HZ, description="true EMG rate [Hz]")
    ] = None,
    image_size: _ImageSizeForm = None,
    frame_rate: Annotated[float | None, Form(gt=0, le=1e4, description="video [fps]")] = None,
    format: Annotated[
        ReaderFormat | None, Form(description="reader to use instead of detecting it")
    ] = None,
) -> dict[str, object]:
    """Parse and store every file in one transaction: all of them, or none when one fails.

    Videos are checked here (container, video track, stated duration within the server's
    limit) and stored; a pose job per video then extracts the landmarks (``pose_jobs``), and
    the recording is analysed when they are stored.
    """
    options = {
        "rate": rate,
        "emg_rate": emg_rate,
        "muscle_map": _muscle_map(muscle_map),
        "image_size": _image_size(image_size),
        "frame_rate": frame_rate,
        "format": format,
    }
    uploads = _read_uploads(services, files)
    videos = sum(is_video_upload(name, data) for name, data in uploads)
    if videos:
        _require_pose_environment(services)
        services.jobs.check_room(videos)  # a full queue refuses before anything is stored
    with services.parse_slots:  # a bounded number parse at once; reads keep their threads
        rec = store_recording(
            session=session,
            blobs=services.blobs,
            files=uploads,
            meta={
                "subject": subject,
                "task": task,
                "load_kg": load_kg,
                "notes": notes,
                "label": blank_label_is_none(label),
                "condition": blank_label_is_none(condition),
            },
            options={k: v for k, v in options.items() if v is not None},
            session_mode=session_mode,
            max_video_seconds=services.settings.max_video_seconds,
        )
    services.recordings_cache.invalidate()
    pose = _submit_pose(services, rec.id, [f.id for f in videos_without_pose(rec)])
    return _detail(session, rec.id, pose_jobs=pose)


def _require_pose_environment(services: Services) -> None:
    """Refuse a video at once when this server cannot turn it into pose (local jobs run here;
    Dask workers have their own environment and report it in the job)."""
    if services.settings.executor != "local":
        return
    problem = pose_environment_problem()
    if problem is not None:
        raise ApiError(503, f"videos cannot be turned into pose on this server: {problem}")


def _submit_pose(
    services: Services, recording_id: int, video_ids: list[int]
) -> list[dict[str, object]]:
    """One pose-extraction job per video (file ids)."""
    return [
        services.jobs.submit(
            kind="pose",
            params={"recording_id": recording_id, "video_file_id": file_id},
            resource={"recording_id": recording_id, "video_file_id": file_id},
            bounded=False,  # the request was admitted (check_room) before it stored anything
        )
        for file_id in video_ids
    ]


def _detail(session: Session, recording_id: int, **extra: object) -> dict[str, object]:
    # A fresh read: jobs started by this request were written by other sessions.
    session.commit()
    rec = get_stored(session, recording_id)
    return {**recording_detail(session, rec), **extra}


_PAGE = TypeAdapter(Page[RecordingSummary])


@router.get("", response_model=Page[RecordingSummary])
async def list_recordings(
    services: ServicesDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
    subject: Annotated[str | None, Query(max_length=200)] = None,
    task: Annotated[str | None, Query(max_length=200)] = None,
    format: Annotated[str | None, Query(max_length=64)] = None,
    q: Annotated[str | None, Query(max_length=200, description="text in names/notes")] = None,
    created_after: IsoDateTimeQuery = None,
    created_before: IsoDateTimeQuery = None,
) -> Response:
    """Recording sessions, newest first. Pages are cached until the next upload or delete."""
    after, before = utc(created_after, "created_after"), utc(created_before, "created_before")
    key = (limit, offset, subject, task, format, q, after, before)
    cache = services.recordings_cache
    body = cache.get(key)
    if body is None:
        version = cache.version

        def compute() -> bytes:
            with services.sessions() as session:
                items, total = list_stored(
                    session,
                    limit=limit,
                    offset=offset,
                    subject=subject,
                    task=task,
                    format=format,
                    q=q,
                    created_after=after,
                    created_before=before,
                )
            page = {"items": items, "total": total, "limit": limit, "offset": offset}
            return _PAGE.dump_json(_PAGE.validate_python(page))

        body = await run_in_threadpool(compute)
        cache.put(key, version, body)
    return Response(body, media_type="application/json")


@router.get("/{recording_id:int}", response_model=RecordingDetail)
def get_recording(session: SessionDep, recording_id: IdPath) -> dict[str, object]:
    """Files (role, warnings, rate check, a video's pose extraction) and channels (flat,
    excluded), the session mode and the options in use."""
    return recording_detail(session, get_stored(session, recording_id))


@router.patch(
    "/{recording_id:int}",
    response_model=RecordingDetail,
    dependencies=[WriteAccess],
    summary="Change a recording and rerun its analysis",
)
def patch_recording(
    services: ServicesDep, session: SessionDep, recording_id: IdPath, body: RecordingPatch
) -> dict[str, object]:
    """Change metadata, the session mode, reader options (the files are read again from their
    stored bytes: muscle map, EMG rate...) and excluded channels; with ``analyse`` (default),
    queue an analysis with these settings (``analysis_job``). Earlier analyses are kept."""
    changes = body.model_dump(mode="json", exclude_unset=True, exclude={"analyse"})
    if body.analyse:
        services.jobs.check_room()  # a full queue refuses before the change is stored
    update_recording(
        session=session, blobs=services.blobs, recording_id=recording_id, changes=changes
    )
    services.recordings_cache.invalidate()
    job = None
    if body.analyse:
        params = rerun_params(session, recording_id)
        job = services.jobs.submit(
            kind="analysis",
            params=params,
            resource={"recording_id": recording_id},
            bounded=False,  # admitted by check_room before the change was stored
        )
    return _detail(session, recording_id, analysis_job=job)


@router.post(
    "/{recording_id:int}/pose",
    status_code=202,
    response_model=RecordingDetail,
    dependencies=[WriteAccess],
    summary="Extract the pose of the recording's videos again",
)
def restart_pose(
    services: ServicesDep, session: SessionDep, recording_id: IdPath
) -> dict[str, object]:
    """A pose job for every video of the recording (after a failure or a cancel; a success
    replaces the landmarks and skeleton frames). 409 while one is queued or running."""
    rec = get_stored(session, recording_id)
    videos = [f.id for f in rec.files if f.role == "video"]
    if not videos:
        raise ApiError(409, f"recording {recording_id} has no video", field="recording_id")
    active = active_pose_jobs(session, recording_id)
    if active:
        raise ConflictError(
            f"the pose of recording {recording_id} is being extracted (job {active[0].id})",
            job=job_to_dict(active[0]),
        )
    _require_pose_environment(services)
    services.jobs.check_room(len(videos))
    return _detail(session, recording_id, pose_jobs=_submit_pose(services, rec.id, videos))


@router.get("/{recording_id:int}/frames", response_model=SkeletonFrames)
def list_frames(session: SessionDep, recording_id: IdPath) -> dict[str, object]:
    """The video frames with the detected skeleton drawn (a few per video), to check the fit."""
    get_stored(session, recording_id)
    return {"recording_id": recording_id, "frames": skeleton_frame_list(session, recording_id)}


@router.get(
    "/{recording_id:int}/frames/{k:int}.jpg", **file_answer("image/jpeg", "the frame (JPEG)")
)
def get_frame(
    request: Request,
    session: SessionDep,
    recording_id: IdPath,
    k: Annotated[int, Path(ge=0, le=10000)],
) -> Response:
    """Frame ``k`` of the list, with the skeleton drawn."""
    get_stored(session, recording_id)
    frame = skeleton_frame(session, recording_id, k)
    etag = f'"{frame.sha256[:32]}"'
    headers = {"ETag": etag, "Cache-Control": "no-cache"}
    if request.headers.get("if-none-match") == etag:
        return Response(status_code=304, headers=headers)
    jpeg = skeleton_jpeg(session, recording_id, k, frame.id)
    return Response(jpeg, media_type="image/jpeg", headers=headers)


@router.get("/{recording_id:int}/signals", response_model=Signals)
def get_signals(
    session: SessionDep,
    recording_id: IdPath,
    channel: Annotated[
        list[Annotated[int, Field(ge=1, le=2**31 - 1)]] | None,
        Query(description="channel ids (default: all channels)"),
    ] = None,
    name: Annotated[list[str] | None, Query(description="channel names")] = None,
    points: Annotated[int, Query(ge=2, le=MAX_POINTS, description="points per series")] = 2000,
    t0: Annotated[float | None, Query(description="window start [s]")] = None,
    t1: Annotated[float | None, Query(description="window end [s]")] = None,
) -> dict[str, object]:
    """Signals for plotting, min/max-downsampled to at most ``points`` samples per series."""
    return signals(
        session, recording_id, channel_ids=channel, names=name, points=points, t0=t0, t1=t1
    )


@router.get(
    "/{recording_id:int}/files/{file_id:int}",
    **file_answer("application/octet-stream", "raw bytes"),
)
def get_raw_file(
    services: ServicesDep, session: SessionDep, recording_id: IdPath, file_id: IdPath
) -> Response:
    """The uploaded file, byte for byte."""
    name, data = raw_file(session, services.blobs, recording_id, file_id)
    quoted = name.encode("ascii", "replace").decode().replace('"', "'")
    return Response(
        data,
        media_type="application/octet-stream",
        headers={"Content-Disposition": f'attachment; filename="{quoted}"'},
    )


@router.delete("/{recording_id:int}", status_code=204, dependencies=[WriteAccess])
def delete_recording(services: ServicesDep, session: SessionDep, recording_id: IdPath) -> Response:
    """Delete a recording with its files, landmarks and skeleton frames; its pose jobs still
    queued or running are cancelled first (their workers stop; nothing of them is stored)."""
    for job in active_pose_jobs(session, recording_id):
        with contextlib.suppress(ConflictError):  # it ended meanwhile
            services.jobs.cancel(job.id)
    try:
        delete_stored(session, services.blobs, recording_id)
    finally:
        services.recordings_cache.invalidate()
    return Response(status_code=204)
