"""Content-addressed file store: uploaded bytes kept under their SHA-256, never their file name.

Layout: ``<root>/<sha[:2]>/<sha>``. A file is written to a temporary name in the same folder,
flushed to disk and renamed, so a reader never sees half a file. Database rows that refer to a
blob are committed after the blob is in place; a crash in between leaves an unreferenced blob,
which :func:`app.db.crud.collect_garbage` removes at the next start.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import re
import tempfile
import threading
from collections.abc import Iterable, Iterator
from pathlib import Path

_SHA256 = re.compile(r"^[0-9a-f]{64}$")
_DETACHED = ".deleted"  # suffix of a blob moved aside by a deletion not yet committed

logger = logging.getLogger(__name__)


class BlobStore:
    """Files by SHA-256 under ``root``.

    ``lock`` serialises "write blobs + commit rows" against "find unreferenced blobs + delete",
    so deleting one recording cannot remove a blob that a concurrent upload is about to use.
    """

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.root.mkdir(parents=True, exist_ok=True)
        self.lock = threading.RLock()

    @staticmethod
    def digest(data: bytes) -> str:
        return hashlib.sha256(data).hexdigest()

    def path(self, sha256: str) -> Path:
        if not _SHA256.match(sha256):
            raise ValueError(f"not a SHA-256 hex digest: {sha256!r}")
        return self.root / sha256[:2] / sha256

    def put(self, data: bytes) -> str:
        """Store ``data`` (idempotent) and return its SHA-256."""
        sha = self.digest(data)
        target = self.path(sha)
        if target.is_file() and target.stat().st_size == len(data):
            return sha
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=".", suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, target)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return sha

    def get(self, sha256: str) -> bytes:
        try:
            return self.path(sha256).read_bytes()
        except FileNotFoundError:
            raise FileNotFoundError(f"stored file {sha256} is missing from {self.root}") from None

    def exists(self, sha256: str) -> bool:
        return self.path(sha256).is_file()

    def delete(self, sha256: str) -> None:
        self.path(sha256).unlink(missing_ok=True)

    def detach(self, hashes: Iterable[str]) -> list[tuple[Path, Path]]:
        """Move blobs aside, all or none, before the rows that refer to them are deleted.

        Returns:
            (blob, moved-aside name) pairs, for :meth:`restore` (the deletion was not committed)
            or :meth:`purge` (it was).

        Raises:
            OSError: one could not be moved (a read-only or failing disk); those already moved
                are put back first, so nothing has changed.
        """
        moved: list[tuple[Path, Path]] = []
        try:
            for sha in sorted(hashes):
                blob = self.path(sha)
                if blob.is_file():
                    aside = blob.with_name(f".{sha}{_DETACHED}")
                    os.replace(blob, aside)
                    moved.append((blob, aside))
        except OSError:
            self.restore(moved)
            raise
        return moved

    @staticmethod
    def restore(moved: list[tuple[Path, Path]]) -> None:
        """Put detached blobs back (their rows' deletion was rolled back)."""
        for blob, aside in reversed(moved):
            with contextlib.suppress(FileNotFoundError):
                os.replace(aside, blob)

    @staticmethod
    def purge(moved: list[tuple[Path, Path]]) -> None:
        """Remove detached blobs for good (their rows' deletion is committed); one that cannot
        be removed now is removed by :meth:`recover_detached` at the next start."""
        for _, aside in moved:
            try:
                aside.unlink(missing_ok=True)
            except OSError as exc:
                logger.warning("%s left for the next start's clean-up: %s", aside.name, exc)

    def recover_detached(self, referenced: set[str]) -> None:
        """After a crash between detach and commit: put back the blobs rows still refer to,
        remove the others."""
        for aside in self.root.glob(f"*/.*{_DETACHED}"):
            sha = aside.name[1 : -len(_DETACHED)]
            if sha in referenced and _SHA256.match(sha):
                os.replace(aside, self.path(sha))
            else:
                aside.unlink(missing_ok=True)

    def hashes(self) -> Iterator[str]:
        """SHA-256 of every stored blob."""
        for sub in self.root.iterdir():
            if sub.is_dir() and len(sub.name) == 2:
                for f in sub.iterdir():
                    if _SHA256.match(f.name):
                        yield f.name

    def remove_temporaries(self) -> int:
        """Delete half-written temporaries left by a crash; returns how many."""
        n = 0
        for tmp in self.root.glob("*/.*.tmp"):
            tmp.unlink(missing_ok=True)
            n += 1
        return n
