"""Database functions: uploads are all-or-nothing, deletions cascade, orphans are collected."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db import crud
from app.db.arrays import decode_array
from app.db.blobs import BlobStore
from app.db.models import Analysis, ChannelRecord, JobRecord, RecordingFile, RecordingSession
from app.db.session import make_engine, make_sessionmaker, upgrade


@pytest.fixture
def db(db_url: str, tmp_path: Path) -> Iterator[tuple[Session, BlobStore]]:
    upgrade(db_url)
    engine = make_engine(db_url)
    with make_sessionmaker(engine)() as session:
        yield session, BlobStore(tmp_path / "blobs")
    engine.dispose()


def _file(name: str, data: bytes, n: int = 100, fmt: str | None = "test_csv") -> crud.ParsedFile:
    t = np.arange(n) / 1000.0
    return crud.ParsedFile(
        name=name,
        data=data,
        format=fmt,  # type: ignore[arg-type]  # None: to make the database refuse the row
        metadata={"rows": n},
        channels=[
            {"name": "emg", "kind": "emg", "unit": "V", "rate": 1000.0,
             "data": np.sin(2 * np.pi * 5 * t), "site": "biceps"},
            {"name": "wrist", "kind": "landmark", "unit": "norm", "rate": 30.0,
             "data": np.tile(t[:, None], (1, 3)), "confidence": np.ones(n)},
        ],
    )  # fmt: skip


def _count(session: Session, model: type) -> int:
    return int(session.scalar(select(func.count()).select_from(model)) or 0)


def test_upload_stores_files_channels_and_arrays(db: tuple[Session, BlobStore]) -> None:
    session, blobs = db
    rec = crud.create_recording(
        session=session,
        blobs=blobs,
        meta={"subject": "s01", "task": "curl", "load_kg": 12.0, "options": {"emg_rate": 1000}},
        files=[_file("a.csv", b"a,b\n1,2\n"), _file("b.csv", b"c,d\n3,4\n", n=50)],
    )
    loaded = crud.get_recording(session=session, recording_id=rec.id)
    assert loaded is not None
    assert [f.original_name for f in loaded.files] == ["a.csv", "b.csv"]
    assert [len(f.channels) for f in loaded.files] == [2, 2]
    assert loaded.files[0].channels[1].dims == 3
    chans = crud.get_channels(session=session, recording_id=rec.id)
    t = np.arange(100) / 1000.0
    np.testing.assert_array_equal(decode_array(chans[0].data), np.sin(2 * np.pi * 5 * t))
    assert blobs.get(loaded.files[1].sha256) == b"c,d\n3,4\n"


def test_failed_upload_leaves_nothing(db: tuple[Session, BlobStore]) -> None:
    session, blobs = db
    # The second file has no format: the database refuses it (NOT NULL) mid-transaction.
    with pytest.raises(IntegrityError):
        crud.create_recording(
            session=session,
            blobs=blobs,
            meta={"subject": "s02"},
            files=[_file("good.csv", b"good"), _file("bad.csv", b"bad", fmt=None)],
        )
    session.rollback()
    for model in (RecordingSession, RecordingFile, ChannelRecord):
        assert _count(session, model) == 0
    # Blobs written before the failed commit are orphans; the start-up sweep removes them.
    assert len(list(blobs.hashes())) == 2
    assert crud.collect_garbage(session=session, blobs=blobs) == 2
    assert list(blobs.hashes()) == []


def test_crash_at_commit_leaves_only_collectable_blobs(
    db: tuple[Session, BlobStore], monkeypatch: pytest.MonkeyPatch
) -> None:
    session, blobs = db

    def crash() -> None:
        raise RuntimeError("simulated crash at commit")

    monkeypatch.setattr(session, "commit", crash)
    with pytest.raises(RuntimeError, match="simulated"):
        crud.create_recording(session=session, blobs=blobs, meta={}, files=[_file("a", b"xyz")])
    monkeypatch.undo()
    assert _count(session, RecordingSession) == 0
    assert len(list(blobs.hashes())) == 1
    assert crud.collect_garbage(session=session, blobs=blobs) == 1
    assert list(blobs.hashes()) == []


def test_delete_cascades_and_keeps_shared_blobs(db: tuple[Session, BlobStore]) -> None:
    session, blobs = db
    same = b"identical bytes in two sessions"
    r1 = crud.create_recording(session=session, blobs=blobs, meta={}, files=[_file("x", same)])
    r2 = crud.create_recording(session=session, blobs=blobs, meta={}, files=[_file("y", same)])
    job = crud.create_job(
        session=session, kind="analysis", params={}, resource={"recording_id": r1.id}
    )
    assert crud.delete_recording(session=session, blobs=blobs, recording_id=r1.id)
    assert _count(session, ChannelRecord) == 2  # only r2's
    assert list(blobs.hashes()) == [BlobStore.digest(same)]  # still used by r2
    analysis = session.get(Analysis, job.id, populate_existing=True)
    assert analysis is not None and analysis.recording_id is None  # ON DELETE SET NULL
    assert crud.delete_recording(session=session, blobs=blobs, recording_id=r2.id)
    assert list(blobs.hashes()) == []
    assert not crud.delete_recording(session=session, blobs=blobs, recording_id=r2.id)


def test_list_filters_and_pages(db: tuple[Session, BlobStore]) -> None:
    session, blobs = db
    for i in range(5):
        crud.create_recording(
            session=session,
            blobs=blobs,
            meta={"subject": f"s{i % 2}", "task": "curl", "notes": f"trial {i}"},
            files=[_file(f"f{i}.csv", f"{i}".encode())],
        )
    items, total = crud.list_recordings(session=session, limit=2, offset=0)
    assert total == 5 and len(items) == 2
    assert items[0].id > items[1].id  # newest first
    items, total = crud.list_recordings(session=session, subject="s1")
    assert total == 2 and {r.subject for r in items} == {"s1"}
    items, total = crud.list_recordings(session=session, q="TRIAL 3")
    assert total == 1 and items[0].notes == "trial 3"
    items, total = crud.list_recordings(session=session, format="nope")
    assert total == 0
    # The summaries (narrow columns) page and filter exactly as the ORM listing does.
    pages: list[dict[str, Any]] = [
        {"limit": 2, "offset": 1},
        {"subject": "s0"},
        {"q": "trial 4"},
        {"task": "x"},
    ]
    for page in pages:
        rows, n = crud.list_recordings(session=session, **page)
        summaries, n_summary = crud.list_recording_summaries(session=session, **page)
        assert [r["id"] for r in summaries] == [r.id for r in rows] and n_summary == n
        assert all(r["file_names"] == [f"f{int(r['notes'][-1])}.csv"] for r in summaries)


def test_job_and_pose_lists_filter_page_and_count(db: tuple[Session, BlobStore]) -> None:
    session, blobs = db
    rec = crud.create_recording(session=session, blobs=blobs, meta={}, files=[_file("a", b"a")])
    made = []  # (id, kind, state, recording) in creation order
    for i in range(8):
        kind = ("plan", "pose", "analysis")[i % 3]
        resource = (
            {"robot": "ur5"} if kind == "plan" else {"recording_id": rec.id if i < 5 else None}
        )
        job = crud.create_job(session=session, kind=kind, params={}, resource=resource)
        state = "succeeded" if i % 2 else "queued"
        crud.update_job(session=session, job_id=job.id, only_if_active=False, state=state)
        made.append((job.id, kind, state, resource.get("recording_id")))
    newest = made[::-1]
    for kind, state in [(None, None), ("pose", None), (None, "queued"), ("plan", "succeeded")]:
        want = [i for i, k, st, _ in newest if kind in (None, k) and state in (None, st)]
        jobs, total = crud.list_jobs(session=session, kind=kind, state=state, limit=2, offset=1)
        assert [j.id for j in jobs] == want[1:3] and total == len(want)
    for state, rid in [(None, None), ("queued", None), (None, rec.id), ("succeeded", rec.id)]:
        want = [
            i for i, k, st, r in newest if k == "pose" and state in (None, st) and rid in (None, r)
        ]
        rows, total = crud.list_pose_extractions(session=session, state=state, recording_id=rid)
        assert [row.id for row, job in rows] == want and total == len(want)
        assert all(row.id == job.id for row, job in rows)


def test_result_is_not_stored_for_a_cancelled_job(db: tuple[Session, BlobStore]) -> None:
    session, _ = db
    job = crud.create_job(session=session, kind="plan", params={}, resource={"robot": "r"})
    assert crud.update_job(session=session, job_id=job.id, state="cancelled")
    assert not crud.store_result(session=session, job_id=job.id, kind="plan", result={"a": 1})
    assert not crud.update_job(session=session, job_id=job.id, state="running")
    row = session.get(JobRecord, job.id, populate_existing=True)
    assert row is not None and row.state == "cancelled"
