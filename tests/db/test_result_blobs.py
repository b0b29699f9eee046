"""Security finding 10 (iii): a result too large for its row (91.7 MB of JSON) is kept in the
file store, the row holding a reference that loads read back transparently; the start-up
clean-up keeps its file; downgrading past the migration puts it back into the row."""

from __future__ import annotations

from pathlib import Path

import pytest
from sqlalchemy import text

from app.db import crud
from app.db.blobs import BlobStore
from app.db.models import Plan
from app.db.session import downgrade, make_engine, make_sessionmaker, upgrade

BIG = {"motion": {"methods": {"quintic": {"q": [[float(i)] * 6 for i in range(500)]}}}}


def _store(db_url: str, blobs: BlobStore, inline_bytes: int) -> tuple[int, str]:
    upgrade(db_url)
    engine = make_engine(db_url)
    sessions = make_sessionmaker(engine)
    sessions.configure(info={crud.BLOBS_KEY: blobs})
    try:
        with sessions() as session:
            job = crud.create_job(
                session=session, kind="plan", params={}, resource={"robot": "ur5"}
            )
            job_id = job.id
            assert crud.store_result(
                session=session,
                job_id=job_id,
                kind="plan",
                result=BIG,
                blobs=blobs,
                inline_bytes=inline_bytes,
            )
        with engine.connect() as conn:
            raw = conn.execute(text("SELECT result FROM plans WHERE id = :i"), {"i": job_id})
            stored = str(raw.scalar())
        with sessions() as session:  # read back as if it were in the row
            row = session.get(Plan, job_id)
            assert row is not None and row.result == BIG
            assert not session.dirty  # reading it back changed nothing
            assert crud.collect_garbage(session=session, blobs=blobs) == 0
        return job_id, stored
    finally:
        engine.dispose()


def test_a_large_result_goes_to_the_file_store_and_comes_back(db_url: str, tmp_path: Path) -> None:
    blobs = BlobStore(tmp_path / "blobs")
    _, stored = _store(db_url, blobs, inline_bytes=1024)
    assert "$result_blob" in stored and len(stored) < 200
    assert len(list(blobs.hashes())) == 1


def test_a_small_result_stays_in_its_row(db_url: str, tmp_path: Path) -> None:
    blobs = BlobStore(tmp_path / "blobs")
    _, stored = _store(db_url, blobs, inline_bytes=10**8)
    assert "$result_blob" not in stored
    assert list(blobs.hashes()) == []


def test_downgrade_puts_the_result_back_into_its_row(
    db_url: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    data = tmp_path / "data"
    blobs = BlobStore(data / "blobs")
    job_id, _ = _store(db_url, blobs, inline_bytes=1024)
    monkeypatch.setenv("BIOPLAN_DATA_DIR", str(data))
    downgrade(db_url, "0006_labels")
    engine = make_engine(db_url)
    try:
        with make_sessionmaker(engine)() as session:
            row = session.get(Plan, job_id)
            assert row is not None and row.result == BIG
    finally:
        engine.dispose()
