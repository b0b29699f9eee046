"""Storing an uploaded recording session: parse every file, then store all of them or none."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from sqlalchemy.orm import Session

from app.db import crud
from app.db.blobs import BlobStore
from app.db.models import RecordingSession
from app.errors import BioPlanError
from app.jobs.tasks import parse_recording
from app.services.errors import ServiceError


def parse_upload(name: str, data: bytes, options: dict[str, Any]) -> crud.ParsedFile:
    """Read one uploaded file (format detected from its content).

    Args:
        name: the user's file name (a base name; kept as metadata only).
        data: its bytes.
        options: reader overrides (``rate, emg_rate, muscle_map, image_size, frame_rate,
            format``), None values left out.

    Raises:
        ServiceError: the file is empty, unreadable or has no channels (``file`` names it).
    """
    if not data:
        raise ServiceError(f"{name}: the file is empty", file=name)
    try:
        out = parse_recording(data, name, options)
    except BioPlanError as exc:  # RecordingError: bad input, named
        text = str(exc)
        raise ServiceError(text if name in text else f"{name}: {text}", file=name) from None
    if not out["channels"]:
        raise ServiceError(f"{name}: no channels found", file=name)
    return crud.ParsedFile(
        name=name,
        data=data,
        format=out["format"],
        metadata=out["metadata"],
        channels=out["channels"],
    )


def store_recording(
    *,
    session: Session,
    blobs: BlobStore,
    files: Sequence[tuple[str, bytes]],
    meta: dict[str, Any],
    options: dict[str, Any],
) -> RecordingSession:
    """Parse every file, then store the session in one transaction (all files or none).

    Args:
        files: (base name, bytes) of each uploaded file.
        meta: ``subject, task, load_kg, notes``.
        options: reader overrides, stored with the session so an analysis rereads the raw
            bytes the same way.

    Returns:
        The stored session with its files and channels loaded.

    Raises:
        ServiceError: no file, or one of them cannot be read (nothing is stored).
    """
    if not files:
        raise ServiceError("at least one file is required", field="files")
    parsed = [parse_upload(name, data, options) for name, data in files]
    rec = crud.create_recording(
        session=session, blobs=blobs, meta={**meta, "options": options}, files=parsed
    )
    loaded = crud.get_recording(session=session, recording_id=rec.id)
    if loaded is None:  # pragma: no cover - deleted between two statements of this request
        raise ServiceError(f"recording {rec.id} was deleted while it was stored")
    return loaded
