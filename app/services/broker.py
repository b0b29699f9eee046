"""Fan-out of job updates to Server-Sent-Events subscribers (thread -> asyncio bridge), and the
caps on open event streams (:class:`StreamLimits`).

A stream costs the server a socket, a subscription and a database read every few seconds, and
it never ends by itself: without caps, 1,100 idle streams from one client took every file
descriptor and every request timed out. So open streams are counted, in all and per client
address, and refused beyond ``BIOPLAN_MAX_STREAMS`` / ``BIOPLAN_MAX_STREAMS_PER_CLIENT``; a
stream with nothing to report for ``BIOPLAN_STREAM_IDLE_S`` ends (the page's ``EventSource``
reconnects by itself); and :meth:`JobBroker.close_all` ends every stream at once when the
server stops, so the shutdown does not wait for them.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import threading
import time
from collections import defaultdict
from dataclasses import dataclass, field

logger = logging.getLogger(__name__)

#: What a subscription's queue receives when the server stops: the stream ends.
_CLOSED: dict[str, object] = {"__closed__": True}

#: The subscription key of a subscriber to every job's updates (job ids start at 1).
ALL_JOBS = 0


class Subscription:
    """A subscriber's queue of job updates, bound to the event loop that created it."""

    def __init__(self, broker: JobBroker, job_id: int) -> None:
        self.broker = broker
        self.job_id = job_id
        self.loop = asyncio.get_running_loop()
        self.queue: asyncio.Queue[dict[str, object]] = asyncio.Queue(maxsize=1000)
        #: True once the server stops: the stream ends at once.
        self.closed = False

    def put(self, update: dict[str, object]) -> None:
        """Called on the loop's thread; drops the oldest update when a slow client lags."""
        if update is _CLOSED:
            self.closed = True
        if self.queue.full():
            self.queue.get_nowait()
        self.queue.put_nowait(update)

    async def get(self, timeout: float) -> dict[str, object] | None:
        """The next update, or None after ``timeout`` seconds or once :attr:`closed`."""
        if self.closed:
            return None
        try:
            update = await asyncio.wait_for(self.queue.get(), timeout)
        except TimeoutError:
            return None
        return None if update is _CLOSED else update

    def close(self) -> None:
        self.broker.unsubscribe(self)


class JobBroker:
    """Publishes job updates (JSON-ready dicts) from any thread to asyncio subscribers."""

    def __init__(self) -> None:
        self._subs: dict[int, set[Subscription]] = defaultdict(set)
        self._lock = threading.Lock()
        self.closing = False

    def subscribe(self, job_id: int) -> Subscription:
        """Must be called from a running event loop (the SSE endpoint); ``ALL_JOBS`` receives
        every job's updates. Once the broker is closing, the subscription is born closed."""
        sub = Subscription(self, job_id)
        with self._lock:
            self._subs[job_id].add(sub)
            if self.closing:
                sub.closed = True
        return sub

    def close_all(self) -> int:
        """End every open stream now and every later one at once (the server stops); any
        thread. Returns how many subscriptions were told."""
        with self._lock:
            self.closing = True
            subs = [sub for group in self._subs.values() for sub in group]
        for sub in subs:
            with contextlib.suppress(RuntimeError):  # its loop has closed: nothing to end
                sub.loop.call_soon_threadsafe(sub.put, _CLOSED)
        return len(subs)

    def unsubscribe(self, sub: Subscription) -> None:
        with self._lock:
            subs = self._subs.get(sub.job_id)
            if subs is not None:
                subs.discard(sub)
                if not subs:
                    del self._subs[sub.job_id]

    def publish(self, job_id: int, update: dict[str, object]) -> None:
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


class StreamRefused(Exception):
    """An event stream over a cap; ``detail`` names the cap, ``retry_after`` [s]."""

    def __init__(self, detail: str, retry_after: int) -> None:
        super().__init__(detail)
        self.detail = detail
        self.retry_after = retry_after


@dataclass
class StreamTicket:
    """One open event stream's place under the caps; :meth:`release` once it ends (again is
    harmless)."""

    limits: StreamLimits
    client: str
    released: bool = False

    def release(self) -> None:
        if not self.released:
            self.released = True
            self.limits._release(self.client)


@dataclass
class LogThrottle:
    """Logs a recurring condition once, then at most once per ``every`` seconds with the count
    of those not logged meanwhile (a flood of refusals must not flood the log)."""

    every: float = 60.0
    _next: float = 0.0
    _quiet: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def due(self) -> int | None:
        """None: stay quiet now; else log now, mentioning this many suppressed since."""
        now = time.monotonic()
        with self._lock:
            if now < self._next:
                self._quiet += 1
                return None
            quiet, self._quiet, self._next = self._quiet, 0, now + self.every
            return quiet


class StreamLimits:
    """Caps on open event streams, in all and per client address.

    Args:
        total: streams open at once on the server (``BIOPLAN_MAX_STREAMS``).
        per_client: streams open at once from one client address
            (``BIOPLAN_MAX_STREAMS_PER_CLIENT``; behind a reverse proxy every client is the
            proxy's address).
        idle_s: seconds a stream stays open with nothing to report (``BIOPLAN_STREAM_IDLE_S``).
    """

    def __init__(self, *, total: int = 64, per_client: int = 8, idle_s: float = 300.0) -> None:
        self.total = total
        self.per_client = per_client
        self.idle_s = idle_s
        self._open: dict[str, int] = {}
        self._count = 0
        self._lock = threading.Lock()
        self._log = LogThrottle()

    @property
    def retry_after(self) -> int:
        """Seconds a refused client is told to wait: idle streams end within ``idle_s``."""
        return max(1, min(30, math.ceil(self.idle_s)))

    def open(self, client: str) -> StreamTicket:
        """A place for one more stream from ``client``.

        Raises:
            StreamRefused: the server's or the client's cap is reached.
        """
        with self._lock:
            mine = self._open.get(client, 0)
            if mine >= self.per_client:
                refusal = (
                    f"too many open event streams from this client ({mine}, the limit is "
                    f"{self.per_client}: BIOPLAN_MAX_STREAMS_PER_CLIENT); close one (another "
                    "tab) or retry later"
                )
            elif self._count >= self.total:
                refusal = (
                    f"too many open event streams on this server ({self._count}, the limit is "
                    f"{self.total}: BIOPLAN_MAX_STREAMS); retry later"
                )
            else:
                self._open[client] = mine + 1
                self._count += 1
                return StreamTicket(self, client)
        quiet = self._log.due()
        if quiet is not None:
            more = f" ({quiet} more refused since the last report)" if quiet else ""
            logger.warning("event stream from %s refused: %s%s", client, refusal, more)
        raise StreamRefused(refusal, self.retry_after)

    def _release(self, client: str) -> None:
        with self._lock:
            self._count -= 1
            left = self._open.get(client, 0) - 1
            if left > 0:
                self._open[client] = left
            else:
                self._open.pop(client, None)

    def counts(self) -> dict[str, int]:
        """``open`` streams and ``clients`` with one, for health and tests."""
        with self._lock:
            return {"open": self._count, "clients": len(self._open)}
