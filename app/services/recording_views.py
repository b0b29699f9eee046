"""What the API shows of stored recordings and their analyses (plain JSON-ready dicts).

A recording's detail names each file's role, its reader warnings (flat channels, rates...), an
implausible EMG rate with the one request that fixes it, a video's container and pose
extraction, and marks channels that are flat or excluded, so a page can show all of it without
running anything. An analysis' summary says where its template came from (lifts or the paper's
default) and carries every warning, also when no lift was found. Signals are decoded and
min/max-downsampled here for plotting.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from app.analysis.downsample import minmax_downsample
from app.db import crud
from app.db.arrays import decode_array
from app.db.models import JobRecord, PoseExtraction, RecordingFile, RecordingSession
from app.planning.human_template import HumanTemplate
from app.services.errors import NotFoundError
from app.services.jobs import job_to_dict
from app.services.recordings import get_recording


def summary(rec: RecordingSession) -> dict[str, object]:
    """The list's fields of a recording (the files the user uploaded)."""
    uploaded = [f for f in rec.files if not (f.role == "recording" and f.parent_id is not None)]
    return {
        "id": rec.id,
        "subject": rec.subject,
        "task": rec.task,
        "load_kg": rec.load_kg,
        "notes": rec.notes,
        "label": rec.label,
        "condition": rec.condition,
        "created_at": rec.created_at,
        "n_files": len(uploaded),
        "formats": sorted({f.format for f in uploaded}),
        "file_names": [f.original_name for f in uploaded],
        "session": rec.session_mode,
    }


def rate_check(rec: RecordingSession, f: RecordingFile) -> dict[str, object] | None:
    """The reader's verdict on a file's EMG rate, with the request that applies the fix."""
    check = f.file_metadata.get("rate_check")
    if not isinstance(check, dict):
        return None
    return {
        "file": f.original_name,
        **check,
        "rerun": {
            "method": "PATCH",
            "url": f"/api/recordings/{rec.id}",
            "json": {"emg_rate": check["suggested_rate_hz"]},
        },
    }


def _channels(f: RecordingFile, excluded: set[str]) -> list[dict[str, object]]:
    flat = {str(n) for n in f.file_metadata.get("flat_channels", [])}
    return [
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
            "flat": c.name in flat,
            "excluded": c.name.lower() in excluded,
        }
        for c in f.channels
    ]


def _pose(
    f: RecordingFile,
    jobs: Mapping[int, JobRecord],
    results: Mapping[int, dict[str, object] | None],
) -> dict[str, object] | None:
    """The pose extraction of video file ``f``: its newest job and that job's result."""
    job = jobs.get(f.id)
    if f.role != "video" or job is None:
        return None
    return {"job": job_to_dict(job), "result": results.get(job.id)}


def recording_detail(session: Session, rec: RecordingSession) -> dict[str, object]:
    """The JSON of ``GET /api/recordings/{id}`` (``app.api.schemas.RecordingDetail``)."""
    excluded = {str(n).lower() for n in rec.options.get("exclude_channels", [])}
    jobs = crud.pose_jobs(session=session, recording_id=rec.id)
    results = {
        j.id: (row.result if (row := session.get(PoseExtraction, j.id)) is not None else None)
        for j in jobs.values()
    }
    files: list[dict[str, object]] = []
    checks: list[dict[str, object]] = []
    warnings: list[str] = []
    for f in rec.files:
        video = f.file_metadata.get("video") if f.role == "video" else None
        said = [str(w) for w in f.file_metadata.get("warnings", [])]
        check = rate_check(rec, f)
        if check is not None:
            checks.append(check)
        warnings += [f"{f.original_name}: {w}" for w in said]
        files.append(
            {
                "id": f.id,
                "original_name": f.original_name,
                "format": f.format,
                "size": f.size,
                "sha256": f.sha256,
                "metadata": f.file_metadata,
                "role": f.role,
                "parent_id": f.parent_id,
                "warnings": said,
                "rate_check": check,
                "video": video,
                "pose": _pose(f, jobs, results),
                "channels": _channels(f, excluded),
            }
        )
    has_frames = any(f.role == "video" for f in rec.files) and bool(
        crud.skeleton_frames(session=session, recording_id=rec.id)
    )
    return {
        **summary(rec),
        "options": rec.options,
        "updated_at": rec.updated_at,
        "rate_check": checks[0] if checks else None,
        "warnings": warnings,
        "frames_url": f"/api/recordings/{rec.id}/frames" if has_frames else None,
        "files": files,
        "pose_jobs": [],
    }


def analysis_summary(result: Mapping[str, Any] | None) -> dict[str, object] | None:
    """Template origin, lifts and every warning of a finished analysis (None before)."""
    if result is None:
        return None
    template = result["template"]
    files = [
        {
            "file": f["source"],
            "format": f["format"],
            "lifts": len(f["lifts"]),
            "lifts_with_kinematics": sum(
                1
                for x in f["lifts"]
                if x.get("kinematics_rejected") is None
                and x.get("peak_velocity_range_fraction") is not None
            ),
            "warnings": list(f["warnings"]),
            "rate_check": f.get("rate_check"),
        }
        for f in result["files"]
    ]
    return {
        "n_lifts": int(result["n_lifts"]),
        "template_source": str(template["source"]),
        "is_paper_default": HumanTemplate.from_dict(template).is_paper_default,
        "template_lifts": int(template["n_lifts"]),
        "peak_velocity_angle_deg": float(template["peak_velocity_angle_deg"]),
        "session": result["settings"].get("session", "separate"),
        "files": files,
        "warnings": list(result["warnings"])
        + [f"{f['file']}: {w}" for f in files for w in f["warnings"]],
        "settings": result["settings"],
    }


def signals(
    session: Session,
    recording_id: int,
    *,
    channel_ids: list[int] | None,
    names: list[str] | None,
    points: int,
    t0: float | None = None,
    t1: float | None = None,
) -> dict[str, object]:
    """A recording's signals for plotting, min/max-downsampled to at most ``points`` samples
    per series, within ``[t0, t1]`` [s] when given.

    Returns ``{"recording_id", "points", "channels"}``; each channel has its id, name, file,
    kind, unit, ``n_samples`` (stored), ``n_points`` (returned) and ``series`` (one per column
    of a multi-column channel: ``label`` value or x/y/z/w, ``t`` [s], ``y``; non-finite
    samples as NaN).

    Raises:
        NotFoundError: no such recording, or channel ids or names it does not have.
    """
    get_recording(session, recording_id)  # NotFoundError when there is none
    chans = crud.get_channels(session=session, recording_id=recording_id, channel_ids=channel_ids)
    if channel_ids:
        missing = sorted(set(channel_ids) - {c.id for c in chans})
        if missing:
            raise NotFoundError(f"recording {recording_id} has no channels {missing}")
    if names:
        chans = [c for c in chans if c.name in set(names)]
        missing_names = sorted(set(names) - {c.name for c in chans})
        if missing_names:
            raise NotFoundError(f"recording {recording_id} has no channels named {missing_names}")
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
