"""The robot cache: URDF/MJCF files written for non-default subjects and converted models,
content-addressed and bounded (least recently used files go first)."""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
import time
from pathlib import Path

__all__ = ["CACHE_MAX_FILES", "cache_dir", "prune_cache", "write_cached"]

#: Files kept in the robot cache (two per distinct subject); older ones are deleted first.
CACHE_MAX_FILES = 200


def cache_root() -> Path:
    """BioPlan's cache folder: ``$BIOPLAN_CACHE_DIR``, else ``$XDG_CACHE_HOME/bioplan``, else
    ``~/.cache/bioplan`` (not created here)."""
    env = os.environ.get("BIOPLAN_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return Path(xdg) / "bioplan" if xdg else Path.home() / ".cache" / "bioplan"


def cache_dir() -> Path:
    """Where URDF/MJCF files of non-default subjects are written (never next to the package):
    ``robots`` in :func:`cache_root`; if that is not writable, a per-user folder under the
    system temporary directory.
    """
    path = cache_root() / "robots"
    try:
        path.mkdir(parents=True, exist_ok=True)
        if os.access(path, os.W_OK):
            return path
    except OSError:
        pass
    fallback = Path(tempfile.gettempdir()) / f"bioplan-{os.getuid()}" / "robots"
    fallback.mkdir(parents=True, exist_ok=True)
    return fallback


def write_cached(text: str, stem: str, suffix: str) -> Path:
    """Write ``text`` under a content-addressed name, atomically (no half-written file)."""
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    path = cache_dir() / f"{stem}-{digest}{suffix}"
    if path.is_file() and path.read_text() == text:
        _touch(path)  # recently used: pruned last
        return path
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=suffix)
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    _touch(path)
    prune_cache(path.parent, keep=CACHE_MAX_FILES, spare=path)
    return path


def _touch(path: Path) -> None:
    # The file system's own clock is coarse (milliseconds): files written together would tie.
    now = time.time_ns()
    with contextlib.suppress(OSError):
        os.utime(path, ns=(now, now))


def prune_cache(folder: Path, *, keep: int, spare: Path | None = None) -> int:
    """Delete the least recently used files of ``folder`` beyond the newest ``keep``.

    Every distinct subject (body mass, height) writes two files: without a bound the cache
    grows for ever. ``spare`` (the file just written) is never deleted. Returns how many went.
    """
    entries = []
    for path in folder.iterdir():
        with contextlib.suppress(OSError):  # another process may prune at the same time
            if path.is_file() and not path.name.startswith(".tmp-") and path != spare:
                entries.append((path.stat().st_mtime_ns, path))
    entries.sort(reverse=True)
    removed = 0
    for _, path in entries[max(keep - 1, 0) :]:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
            removed += 1
    return removed
