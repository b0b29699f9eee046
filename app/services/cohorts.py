"""Cohorts in the service: which stored recordings a comparison takes (explicit groups, or the
recordings grouped by their condition), its job's input, and its result as a table.

A request is checked against the stored data before anything is queued: a recording that does
not exist is a 404 naming the field (``groups.<name>.<i>``, ``recording_ids.<i>``); a
recording in two groups, or ``groups`` beside ``group_by``/``recording_ids``, a 422 naming the
field; a recording without a condition, without anything to analyse, or fewer than two
conditions a 409. Each recording file is one measured recording (trials on their own clocks);
a session recorded ``together`` over several files is refused (409): a cohort measures one
file at a time.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db import crud
from app.db.blobs import BlobStore
from app.db.models import RecordingFile, RecordingSession
from app.services.errors import ConflictError, NotFoundError, ServiceError
from app.services.recordings import file_read_options, sidecars_of

__all__ = ["cohort_csv", "cohort_params", "cohort_payload"]


def _recording_files(rec: RecordingSession) -> list[RecordingFile]:
    return [f for f in rec.files if f.role == "recording"]


def _check_usable(session: Session, rec: RecordingSession, field: str) -> None:
    """Refuse (409) a recording a cohort cannot measure, naming the request's field."""
    from app.services.job_views import job_to_dict

    pending = next(
        (
            j
            for j in crud.pose_jobs(session=session, recording_id=rec.id).values()
            if j.state in ("queued", "running")
        ),
        None,
    )
    if pending is not None:
        raise ConflictError(
            f"{field}: recording {rec.id}'s video is being turned into pose (job {pending.id});"
            " compare it once that job succeeded",
            field=field,
            job=job_to_dict(pending),
        )
    files = _recording_files(rec)
    if not files:
        raise ConflictError(
            f"{field}: recording {rec.id} has nothing to measure (no recording file; a video"
            " needs its pose landmarks first)",
            field=field,
        )
    if rec.session_mode == "together" and len(files) > 1:
        raise ConflictError(
            f"{field}: recording {rec.id} holds {len(files)} files recorded together; a cohort"
            " measures one file per recording (upload each trial as its own recording, or set"
            " the session to separate trials)",
            field=field,
        )


def _get(session: Session, recording_id: int, field: str) -> RecordingSession:
    rec = crud.get_recording(session=session, recording_id=recording_id)
    if rec is None:
        raise NotFoundError(f"{field}: recording {recording_id} does not exist", field=field)
    return rec


def _explicit(session: Session, groups: dict[str, list[int]]) -> dict[str, list[int]]:
    seen: dict[int, str] = {}
    for name in groups:
        if not name.strip():
            raise ServiceError(
                f"groups: a group is named {name!r} (expected a name, not blanks)", field="groups"
            )
    for name, ids in groups.items():
        for i, rid in enumerate(ids):
            field = f"groups.{name}.{i}"
            if rid in seen:
                where = "twice in group" if seen[rid] == name else "in groups"
                both = repr(name) if seen[rid] == name else f"{seen[rid]!r} and {name!r}"
                raise ServiceError(
                    f"{field}: recording {rid} is {where} {both} (expected each recording in"
                    " one group, once)",
                    field="groups",
                )
            seen[rid] = name
    for name, ids in groups.items():
        for i, rid in enumerate(ids):
            field = f"groups.{name}.{i}"
            _check_usable(session, _get(session, rid, field), field)
    return {name: list(ids) for name, ids in groups.items()}


def _by_condition(
    session: Session, recording_ids: Sequence[int] | None
) -> tuple[dict[str, list[int]], list[int]]:
    """Groups by condition, and the recordings left out (no condition; only when every
    recording is taken)."""
    groups: dict[str, list[int]] = {}
    left_out: list[int] = []
    if recording_ids is not None:
        for i, rid in enumerate(recording_ids):
            field = f"recording_ids.{i}"
            rec = _get(session, rid, field)
            if not rec.condition:
                raise ConflictError(
                    f"{field}: recording {rid} has no condition (set one: PATCH"
                    f" /api/recordings/{rid} with condition, or give groups)",
                    field=field,
                )
            _check_usable(session, rec, field)
            groups.setdefault(rec.condition, []).append(rid)
    else:
        for rec in session.scalars(select(RecordingSession).order_by(RecordingSession.id)):
            if not rec.condition:
                left_out.append(rec.id)
                continue
            _check_usable(session, rec, "group_by")
            groups.setdefault(rec.condition, []).append(rec.id)
    if len(groups) < 2:
        found = ", ".join(repr(c) for c in groups) or "none"
        raise ConflictError(
            f"group_by: a cohort needs recordings of at least two conditions, found {found}"
            " (set conditions with PATCH /api/recordings/{id}, or give groups)",
            field="group_by",
        )
    return groups, left_out


def cohort_params(session: Session, request: dict[str, Any]) -> dict[str, Any]:
    """The groups a cohort request compares (resolved to recording ids) and its options.

    Args:
        request: ``CohortRequest`` as JSON (``groups``, ``group_by``, ``recording_ids``,
            ``options``, ``label``).

    Returns:
        ``{"groups": {name: [id, ...]}, "group_by", "recording_ids", "left_out": [ids],
        "options"}``: what the job runs with.

    Raises:
        NotFoundError: a recording that does not exist (``field`` names where).
        ServiceError: a recording in two groups; groups beside group_by or recording_ids.
        ConflictError: a recording without a condition or without anything to measure; fewer
            than two conditions.
    """
    groups = request.get("groups")
    left_out: list[int] = []
    if groups is not None:
        for name in ("group_by", "recording_ids"):
            if request.get(name) is not None:
                raise ServiceError(
                    f"{name}: give groups, or {name} (recordings grouped by condition), not both",
                    field=name,
                )
        resolved = _explicit(session, groups)
    else:
        resolved, left_out = _by_condition(session, request.get("recording_ids"))
    return {
        "groups": resolved,
        "group_by": None if groups is not None else "condition",
        "recording_ids": request.get("recording_ids"),
        "left_out": left_out,
        "options": dict(request.get("options") or {}),
    }


def cohort_payload(session: Session, blobs: BlobStore, params: dict[str, Any]) -> dict[str, Any]:
    """A cohort job's input (``app.jobs.tasks.cohort``): per group, each recording's files
    (bytes, sidecars, reader options), its stored subject and excluded channels.

    Raises:
        NotFoundError: a recording was deleted while the job waited.
    """
    out: dict[str, list[dict[str, object]]] = {}
    for name, ids in params["groups"].items():
        items = []
        for rid in ids:
            rec = crud.get_recording(session=session, recording_id=rid)
            if rec is None:
                raise NotFoundError(f"recording {rid} (group {name!r}) no longer exists")
            options = dict(rec.options)
            files = [
                {
                    "name": f.original_name,
                    "file_id": f.id,
                    "data": blobs.get(f.sha256),
                    "sidecars": sidecars_of(f, rec.files, blobs),
                    "read_options": file_read_options(f, options),
                    "warnings": list(f.file_metadata.get("pose_warnings", [])),
                }
                for f in _recording_files(rec)
            ]
            items.append(
                {
                    "recording_id": rid,
                    "subject": rec.subject,
                    "exclude_channels": list(options.get("exclude_channels") or []),
                    "files": files,
                }
            )
        out[name] = items
    return {"groups": out, "options": dict(params.get("options") or {})}


def _cell(v: object) -> str:
    if v is None:
        return ""
    if isinstance(v, bool) or not isinstance(v, int | float):
        return str(v)
    return str(int(v)) if float(v).is_integer() and abs(v) < 1e15 else repr(float(v))


def cohort_csv(result: dict[str, Any]) -> str:
    """One row per measured recording: its recording id, group, file, subject and every
    measure (empty = missing; why in ``missing``), as ``bioplan cohort --csv`` writes it."""
    from app.analysis.cohort import ORDER_SEP

    names = list(result.get("units") or {})
    ids = result.get("recording_ids") or []
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["recording_id", "group", "source", "subject", "subject_from", *names,
                "activation_order", "missing"])  # fmt: skip
    for i, r in enumerate(result.get("recordings") or []):
        measures = r.get("measures") or {}
        missing = r.get("missing") or {}
        w.writerow(
            [ids[i] if i < len(ids) else "", r.get("group"), r.get("source"), r.get("subject"),
             r.get("subject_from")]
            + [_cell(measures.get(k)) for k in names]
            + [ORDER_SEP.join(r.get("activation_order") or []),
               "; ".join(f"{k}: {v}" for k, v in missing.items())]
        )  # fmt: skip
    return buf.getvalue()


def cohort_option_info() -> list[dict[str, object]]:
    """Every option of a comparison (``CohortOptions``) with its default, help, unit, choices,
    range and JSON type, as ``GET /api/cohorts/options`` lists them."""
    from app.analysis.cohort import CohortOptions
    from app.options import option_specs

    kinds = {float: "number", int: "integer"}
    out = []
    for spec in option_specs(CohortOptions):
        # The page's names for the bounds: low/high exclusive, minimum inclusive.
        out.append(
            {
                "name": spec.name,
                "default": spec.default,
                "help": spec.help,
                "unit": spec.unit,
                "choices": list(spec.choices) if spec.choices is not None else None,
                "low": spec.meta.get("gt"),
                "high": spec.meta.get("lt"),
                "minimum": spec.meta.get("ge"),
                "type": kinds.get(spec.kind, "string"),
            }
        )
    return out
