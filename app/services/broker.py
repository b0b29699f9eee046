"""Fan-out of job updates to Server-Sent-Events subscribers (thread -> asyncio bridge)."""

from __future__ import annotations

import asyncio
import threading
from collections import defaultdict
from typing import Any

#: The subscription key of a subscriber to every job's updates (job ids start at 1).
ALL_JOBS = 0


class Subscription:
    """A subscriber's queue of job updates, bound to the event loop that created it."""

    def __init__(self, broker: JobBroker, job_id: int) -> None:
        self.broker = broker
        self.job_id = job_id
        self.loop = asyncio.get_running_loop()
        self.queue: asyncio.Queue[dict[str, Any]] = asyncio.Queue(maxsize=1000)

    def put(self, update: dict[str, Any]) -> None:
        """Called on the loop's thread; drops the oldest update when a slow client lags."""
        if self.queue.full():
            self.queue.get_nowait()
        self.queue.put_nowait(update)

    async def get(self, timeout: float) -> dict[str, Any] | None:
        try:
            return await asyncio.wait_for(self.queue.get(), timeout)
        except TimeoutError:
            return None

    def close(self) -> None:
        self.broker.unsubscribe(self)


class JobBroker:
    """Publishes job updates (JSON-ready dicts) from any thread to asyncio subscribers."""

    def __init__(self) -> None:
        self._subs: dict[int, set[Subscription]] = defaultdict(set)
        self._lock = threading.Lock()

    def subscribe(self, job_id: int) -> Subscription:
        """Must be called from a running event loop (the SSE endpoint); ``ALL_JOBS`` receives
        every job's updates."""
        sub = Subscription(self, job_id)
        with self._lock:
            self._subs[job_id].add(sub)
        return sub

    def unsubscribe(self, sub: Subscription) -> None:
        with self._lock:
            subs = self._subs.get(sub.job_id)
            if subs is not None:
                subs.discard(sub)
                if not subs:
                    del self._subs[sub.job_id]

    def publish(self, job_id: int, update: dict[str, Any]) -> None:
        with self._lock:
            subs = list(self._subs.get(job_id, ())) + list(self._subs.get(ALL_JOBS, ()))
        for sub in subs:
            try:
                sub.loop.call_soon_threadsafe(sub.put, update)
            except RuntimeError:  # the subscriber's loop has closed
                self.unsubscribe(sub)

    def subscribers(self, job_id: int) -> int:
        """Subscribers that receive this job's updates (its own and those of every job)."""
        with self._lock:
            return len(self._subs.get(job_id, ())) + len(self._subs.get(ALL_JOBS, ()))
