"""The content-addressed file store."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from app.db.blobs import BlobStore


def test_files_are_stored_by_sha256_not_name(tmp_path: Path) -> None:
    store = BlobStore(tmp_path)
    data = b"time,emg\n0,1\n"
    sha = store.put(data)
    assert sha == hashlib.sha256(data).hexdigest()
    assert store.path(sha) == tmp_path / sha[:2] / sha
    assert store.get(sha) == data
    assert list(store.hashes()) == [sha]
    assert store.put(data) == sha  # idempotent
    assert len(list(tmp_path.rglob("*"))) == 2  # one folder, one file


def test_temporaries_and_missing_files(tmp_path: Path) -> None:
    store = BlobStore(tmp_path)
    sha = store.put(b"x")
    (tmp_path / sha[:2] / ".half-written.tmp").write_bytes(b"partial")
    assert store.remove_temporaries() == 1
    assert list(store.hashes()) == [sha]
    store.delete(sha)
    assert not store.exists(sha)
    with pytest.raises(FileNotFoundError, match="missing"):
        store.get(sha)
    with pytest.raises(ValueError, match="SHA-256"):
        store.path("../../etc/passwd")


def test_detached_blobs_come_back_unless_their_deletion_was_committed(tmp_path: Path) -> None:
    """A deletion moves its blobs aside before committing; a crash in between must not lose a
    blob that rows still refer to (the next start puts it back) nor keep one they do not."""
    store = BlobStore(tmp_path)
    kept, dropped = store.put(b"still referenced"), store.put(b"deleted")
    moved = store.detach({kept, dropped})
    assert not store.exists(kept) and not store.exists(dropped) and len(moved) == 2
    store.recover_detached({kept})  # the next start, after a crash before the commit
    assert store.exists(kept) and store.get(kept) == b"still referenced"
    assert not store.exists(dropped) and list(tmp_path.glob("*/.*")) == []
    moved = store.detach({kept})
    store.restore(moved)  # the commit failed: all back
    assert store.get(kept) == b"still referenced"
