"""Untrusted HDF5 bytes (MAT 7.3 uploads) read without following anything out of them.

An HDF5 file may point outside itself: a dataset may keep its raw data in external files
(``create_dataset(..., external=[(path, offset, size)])``), a virtual dataset maps datasets of
other files, and an external link names an object in another file. Followed on the server, any
of them turns an upload into a read of a server file (``/etc/passwd``, the database,
``/proc/self/environ`` with the API token) whose bytes come back as a channel's samples.

Every HDF5 reader walks its file through these helpers, which look at each link *before* it is
followed (h5py never opens another file) and at each dataset's storage before it is read:

- :func:`children` yields a group's members; hard links are opened, soft links are resolved
  here one name at a time inside the file (so a soft link into an external link is refused too,
  and a soft link loop ends after :data:`MAX_SOFT_HOPS`), external and user-defined links are
  refused;
- :func:`check_dataset` refuses a dataset with external storage or a virtual layout;
- :class:`Visits` refuses hard links back to an enclosing group and caps the objects visited;
- :func:`deref` follows an object or region reference (MATLAB cell arrays): references are
  addresses inside the same file, and what they reach goes through the same checks.

Each refusal is a :class:`~app.errors.BioPlanError` naming the object's path in the file; the
reader adds the file name.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import Any

from app.errors import BioPlanError

__all__ = [
    "MAX_OBJECTS",
    "MAX_SOFT_HOPS",
    "Visits",
    "check_dataset",
    "children",
    "deref",
    "open_bytes",
]

#: Soft links followed in a row before the chain is taken for a loop.
MAX_SOFT_HOPS = 16
#: Objects (groups and datasets, counted on every visit) one file may lead a reader through:
#: a recording has tens; hard links that fan out reach millions from a few KB.
MAX_OBJECTS = 100_000

_WHY = "only data inside the uploaded file is read"


def shown(path: tuple[str, ...] | str) -> str:
    """An object's path as the messages show it: ``/rec/emg``."""
    text = path if isinstance(path, str) else "/".join(path)
    return "/" + text.lstrip("/")


def open_bytes(data: bytes) -> Any:
    """An ``h5py.File`` reading ``data`` from memory (no path: relative links resolve nowhere)."""
    import h5py

    return h5py.File(io.BytesIO(data), "r")


def check_dataset(dset: Any, path: tuple[str, ...] | str) -> None:
    """Refuse a dataset whose data is not inside the file: external storage or virtual layout.

    Only the dataset's creation properties are read, never its data.
    """
    import h5py

    plist = dset.id.get_create_plist()
    external = plist.get_external_count() > 0
    virtual = plist.get_layout() == h5py.h5d.VIRTUAL
    if not (external or virtual):
        return
    where = f"dataset {shown(path)!r}"
    stored = dset.name  # where it is in the file, when reached through a reference or link
    if stored and shown(stored) != shown(path):
        where += f" (stored at {shown(stored)!r})"
    if external:
        raise BioPlanError(f"{where} keeps its data in an external file: {_WHY}")
    raise BioPlanError(f"{where} is a virtual dataset mapping other datasets: {_WHY}")


def _open_link(group: Any, name: bytes, path: str, hops: int) -> Any:
    """The object ``name`` in ``group`` names, checking the link before following it."""
    import h5py

    kind = group.id.links.get_info(name).type
    if kind == h5py.h5l.TYPE_HARD:
        return group[name]
    if kind == h5py.h5l.TYPE_SOFT:
        target = group.id.links.get_val(name)
        return _resolve_soft(group, target, path, hops + 1)
    what = f"{'soft link ' if hops else ''}{shown(path)!r} {'leads to' if hops else 'is'}"
    if kind == h5py.h5l.TYPE_EXTERNAL:
        raise BioPlanError(f"{what} an external link to another file: {_WHY}")
    raise BioPlanError(f"{what} a user-defined link (type {kind}): {_WHY}")


def _resolve_soft(group: Any, target: bytes, path: str, hops: int) -> Any:
    """A soft link's target, one name at a time from the root or from the link's group."""
    import h5py

    if hops > MAX_SOFT_HOPS:
        raise BioPlanError(
            f"soft link {shown(path)!r} leads through more than {MAX_SOFT_HOPS} soft links (a loop)"
        )
    node = group.file if target.startswith(b"/") else group
    for name in target.split(b"/"):
        if name in (b"", b"."):
            continue
        if not isinstance(node, h5py.Group) or not node.id.links.exists(name):
            raise BioPlanError(
                f"soft link {shown(path)!r} points at "
                f"{target.decode('utf-8', 'replace')!r}, which is not in the file"
            )
        node = _open_link(node, name, path, hops)
    return node


def children(group: Any, path: tuple[str, ...]) -> Iterator[tuple[str, Any]]:
    """``(name, object)`` for each member of ``group``, every link checked before it is
    followed (module docstring); ``path`` is the group's path, for messages."""
    for raw in list(group.id):
        name = raw.decode("utf-8", "replace")
        yield name, _open_link(group, raw, "/".join((*path, name)), 0)


def deref(f: Any, ref: Any) -> Any:
    """The object a reference stored in ``f`` points at, or None when the reference is null,
    dangling or of another kind. Check what comes back like any other object.

    Only h5py's object and region references are followed: addresses inside this file. Any
    other value (a string would be looked up as a path, through links) is never dereferenced.
    """
    import h5py

    if not isinstance(ref, h5py.Reference | h5py.RegionReference) or not ref:
        return None
    try:
        return f[ref]
    except (ValueError, KeyError, TypeError):
        return None


class Visits:
    """Groups being walked (a hard link back to one of them is a loop) and objects visited."""

    def __init__(self, limit: int | None = None) -> None:
        self.limit = MAX_OBJECTS if limit is None else limit
        self.count = 0
        self._open: list[Any] = []

    def enter(self, node: Any, path: tuple[str, ...]) -> None:
        """Count ``node``; for a group, refuse it when it encloses itself, then mark it open
        (call :meth:`leave` when done with its members)."""
        import h5py

        self.count += 1
        if self.count > self.limit:
            raise BioPlanError(
                f"more than {self.limit} objects reached (at {shown(path)!r}): links fan out or"
                " loop (a damaged or hostile file)"
            )
        if isinstance(node, h5py.Group):
            if any(node.id == g.id for g in self._open):
                raise BioPlanError(f"{shown(path)!r} links back to a group that encloses it")
            self._open.append(node)

    def leave(self) -> None:
        self._open.pop()
