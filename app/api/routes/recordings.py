"""Recordings: upload (multipart), list, detail, signals for plotting, raw files, delete."""

from __future__ import annotations

import json
from datetime import datetime
from pathlib import PurePosixPath
from typing import Annotated, Any, get_args

import numpy as np
from fastapi import APIRouter, File, Form, Query, Response, UploadFile
from pydantic import Field, TypeAdapter
from starlette.concurrency import run_in_threadpool

from app.analysis.downsample import minmax_downsample
from app.api.deps import ServicesDep, SessionDep, WriteAccess
from app.api.errors import ApiError
from app.api.routes._common import PROBLEM_RESPONSES, IdPath, utc
from app.api.schemas import Page, RecordingDetail, RecordingSummary, Signals, Site
from app.db import crud
from app.db.arrays import decode_array
from app.db.models import RecordingFile, RecordingSession
from app.services import store_recording

router = APIRouter(prefix="/api/recordings", tags=["recordings"], responses=PROBLEM_RESPONSES)

_SITES: set[str] = set(get_args(Site))


def _summary(rec: RecordingSession) -> dict[str, Any]:
    return {
        "id": rec.id,
        "subject": rec.subject,
        "task": rec.task,
        "load_kg": rec.load_kg,
        "notes": rec.notes,
        "created_at": rec.created_at,
        "n_files": len(rec.files),
        "formats": sorted({f.format for f in rec.files}),
        "file_names": [f.original_name for f in rec.files],
    }


def _detail(rec: RecordingSession) -> dict[str, Any]:
    out = _summary(rec)
    out["options"] = rec.options
    out["files"] = [
        {
            "id": f.id,
            "original_name": f.original_name,
            "format": f.format,
            "size": f.size,
            "sha256": f.sha256,
            "metadata": f.file_metadata,
            "channels": [
                {
                    "id": c.id,
                    "name": c.name,
                    "kind": c.kind,
                    "unit": c.unit,
                    "rate": c.rate,
                    "start": c.start,
                    "site": c.site,
                    "n_samples": c.n_samples,
                    "dims": c.dims,
                    "duration": c.n_samples / c.rate if c.rate > 0 else 0.0,
                }
                for c in f.channels
            ],
        }
        for f in rec.files
    ]
    return out


def _safe_name(name: str | None, index: int) -> str:
    # Only the base name is kept, as metadata; storage is by SHA-256.
    base = PurePosixPath((name or "").replace("\\", "/")).name.strip()
    return base[:255] or f"upload-{index + 1}"


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
    if text is None or not text.strip():
        return None
    w, _, h = text.lower().partition("x")
    try:
        size = (int(w), int(h))
    except ValueError:
        raise ApiError(
            422, f"image_size must be WIDTHxHEIGHT in pixels, got {text!r}", field="image_size"
        ) from None
    if min(size) < 1 or max(size) > 100000:
        raise ApiError(422, f"image_size out of range: {text!r}", field="image_size")
    return size


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
    files: Annotated[
        list[UploadFile], File(description="recording files; the format is detected from content")
    ],
    subject: Annotated[str | None, Form(max_length=200)] = None,
    task: Annotated[str | None, Form(max_length=200)] = None,
    load_kg: Annotated[float | None, Form(ge=0, le=500, description="load lifted [kg]")] = None,
    notes: Annotated[str | None, Form(max_length=10000)] = None,
    muscle_map: Annotated[
        str | None,
        Form(description='JSON object: channel label -> site, e.g. {"Biceps.EMG4": "biceps"}'),
    ] = None,
    rate: Annotated[float | None, Form(gt=0, le=1e6, description="sampling rate [Hz]")] = None,
    emg_rate: Annotated[float | None, Form(gt=0, le=1e6, description="EMG rate [Hz]")] = None,
    image_size: Annotated[
        str | None, Form(description="WIDTHxHEIGHT [px] for normalised landmarks")
    ] = None,
    frame_rate: Annotated[float | None, Form(gt=0, le=1e4, description="video [fps]")] = None,
    format: Annotated[
        str | None,
        Form(max_length=32, description="reader to use instead of detecting it (e.g. c3d)"),
    ] = None,
) -> dict[str, Any]:
    """Parse and store every file in one transaction: all of them, or none when one fails."""
    options = {
        "rate": rate,
        "emg_rate": emg_rate,
        "muscle_map": _muscle_map(muscle_map),
        "image_size": _image_size(image_size),
        "frame_rate": frame_rate,
        "format": format,
    }
    rec = store_recording(
        session=session,
        blobs=services.blobs,
        files=[(_safe_name(f.filename, i), f.file.read()) for i, f in enumerate(files)],
        meta={"subject": subject, "task": task, "load_kg": load_kg, "notes": notes},
        options={k: v for k, v in options.items() if v is not None},
    )
    services.recordings_cache.invalidate()
    return _detail(rec)


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
    created_after: datetime | None = None,
    created_before: datetime | None = None,
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
                items, total = crud.list_recording_summaries(
                    session=session,
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


def _get(session: SessionDep, recording_id: int) -> RecordingSession:
    rec = crud.get_recording(session=session, recording_id=recording_id)
    if rec is None:
        raise ApiError(404, f"recording {recording_id} does not exist")
    return rec


@router.get("/{recording_id}", response_model=RecordingDetail)
def get_recording(session: SessionDep, recording_id: IdPath) -> dict[str, Any]:
    return _detail(_get(session, recording_id))


@router.get("/{recording_id}/signals", response_model=Signals)
def get_signals(
    session: SessionDep,
    recording_id: IdPath,
    channel: Annotated[
        list[Annotated[int, Field(ge=1, le=2**31 - 1)]] | None,
        Query(description="channel ids (default: all channels)"),
    ] = None,
    name: Annotated[list[str] | None, Query(description="channel names")] = None,
    points: Annotated[int, Query(ge=2, le=100000, description="points per series")] = 2000,
    t0: Annotated[float | None, Query(description="window start [s]")] = None,
    t1: Annotated[float | None, Query(description="window end [s]")] = None,
) -> dict[str, Any]:
    """Signals for plotting, min/max-downsampled to at most ``points`` samples per series."""
    _get(session, recording_id)
    chans = crud.get_channels(session=session, recording_id=recording_id, channel_ids=channel)
    if channel:
        missing = sorted(set(channel) - {c.id for c in chans})
        if missing:
            raise ApiError(404, f"recording {recording_id} has no channels {missing}")
    if name:
        chans = [c for c in chans if c.name in set(name)]
        missing_names = sorted(set(name) - {c.name for c in chans})
        if missing_names:
            raise ApiError(404, f"recording {recording_id} has no channels named {missing_names}")
    out = []
    for c in chans:
        data = np.asarray(decode_array(c.data), dtype=np.float64)
        if c.time is not None:
            t = np.asarray(decode_array(c.time), dtype=np.float64)
        else:
            t = c.start + np.arange(c.n_samples, dtype=np.float64) / c.rate
        keep = np.ones(t.shape, dtype=bool)
        if t0 is not None:
            keep &= t >= t0
        if t1 is not None:
            keep &= t <= t1
        columns = data.reshape(data.shape[0], -1)
        labels = ["value"] if columns.shape[1] == 1 else ["x", "y", "z", "w"][: columns.shape[1]]
        if len(labels) < columns.shape[1]:
            labels = [f"c{i}" for i in range(columns.shape[1])]
        series = []
        for j, label in enumerate(labels):
            col = columns[keep, j]
            col = np.where(np.isfinite(col), col, np.nan)
            ts, ys = minmax_downsample(t[keep], col, points)
            series.append({"label": label, "t": ts.tolist(), "y": ys.tolist()})
        out.append(
            {
                "channel_id": c.id,
                "name": c.name,
                "file": c.file.original_name,
                "kind": c.kind,
                "unit": c.unit,
                "n_samples": c.n_samples,
                "n_points": max((len(s["t"]) for s in series), default=0),
                "series": series,
            }
        )
    return {"recording_id": recording_id, "points": points, "channels": out}


@router.get(
    "/{recording_id}/files/{file_id}",
    response_class=Response,
    responses={200: {"content": {"application/octet-stream": {}}, "description": "raw bytes"}},
)
def get_raw_file(
    services: ServicesDep, session: SessionDep, recording_id: IdPath, file_id: IdPath
) -> Response:
    """The uploaded file, byte for byte."""
    f = session.get(RecordingFile, file_id)
    if f is None or f.session_id != recording_id:
        raise ApiError(404, f"recording {recording_id} has no file {file_id}")
    quoted = f.original_name.encode("ascii", "replace").decode().replace('"', "'")
    return Response(
        services.blobs.get(f.sha256),
        media_type="application/octet-stream",
        headers={"Content-Disposition": f'attachment; filename="{quoted}"'},
    )


@router.delete("/{recording_id}", status_code=204, dependencies=[WriteAccess])
def delete_recording(services: ServicesDep, session: SessionDep, recording_id: IdPath) -> Response:
    deleted = crud.delete_recording(
        session=session, blobs=services.blobs, recording_id=recording_id
    )
    services.recordings_cache.invalidate()
    if not deleted:
        raise ApiError(404, f"recording {recording_id} does not exist")
    return Response(status_code=204)
