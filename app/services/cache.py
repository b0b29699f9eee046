"""A cache of serialized responses that every write drops (exact: one process writes)."""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Hashable


class ResponseCache:
    """Serialized responses of frequent list requests, dropped whenever the data changes.

    Exact because this process is the only writer of the database: every write calls
    :meth:`invalidate` after its commit, and a response computed while a write happened is not
    stored (the version it was computed at is stale).

    Args:
        maxsize: responses kept, least recently used dropped first.
    """

    def __init__(self, maxsize: int = 512) -> None:
        self.maxsize = maxsize
        self.version = 0
        self._items: OrderedDict[Hashable, tuple[int, bytes]] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: Hashable) -> bytes | None:
        with self._lock:
            hit = self._items.get(key)
            if hit is None or hit[0] != self.version:
                return None
            self._items.move_to_end(key)
            return hit[1]

    def put(self, key: Hashable, version: int, body: bytes) -> None:
        with self._lock:
            if version != self.version:
                return
            self._items[key] = (version, body)
            self._items.move_to_end(key)
            while len(self._items) > self.maxsize:
                self._items.popitem(last=False)

    def invalidate(self) -> None:
        with self._lock:
            self.version += 1
            self._items.clear()
