"""Playback: a clock per viewer tab and one thread that advances every playing tab.

The clock is plain arithmetic on a monotonic time source (so it is testable without sleeping);
the ``Player`` thread ticks at a fixed rate and calls each registered session's ``tick``. One
thread for all tabs keeps the cost flat: a tick only assigns precomputed poses.
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

logger = logging.getLogger(__name__)

#: Seconds the last pose is held before a looping playback starts over.
END_HOLD = 0.6
SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0)


class PlaybackClock:
    """Trajectory time [s] as a function of wall-clock time, with play, pause, seek and speed.

    Args:
        duration: length of the trajectory [s] (> 0).
        speed: playback rate (1 = real time).
        loop: start over after the end (holding the last pose for ``hold`` s).
        hold: pause at the end of each loop [s of wall-clock time at speed 1].
        now: the time source [s] (``time.monotonic`` by default).
    """

    def __init__(
        self,
        duration: float,
        *,
        speed: float = 1.0,
        loop: bool = True,
        hold: float = END_HOLD,
        now: Callable[[], float] = time.monotonic,
    ) -> None:
        if not duration > 0.0:
            raise ValueError(f"playback duration must be > 0 s, got {duration}")
        self.duration = float(duration)
        self.loop = loop
        self.hold = max(float(hold), 0.0)
        self._now = now
        self._speed = _check_speed(speed)
        self._playing = False
        self._origin = 0.0  # trajectory time at the wall-clock instant _since
        self._since = now()

    @property
    def playing(self) -> bool:
        return self._playing

    @property
    def speed(self) -> float:
        return self._speed

    def _elapsed(self) -> float:
        return self._origin + (self._now() - self._since) * self._speed

    def time(self) -> float:
        """The trajectory time now [s], in [0, duration]."""
        if not self._playing:
            return min(max(self._origin, 0.0), self.duration)
        t = self._elapsed()
        if not self.loop:
            return min(t, self.duration)
        cycle = self.duration + self.hold * self._speed
        return min(t % cycle, self.duration)

    def _rebase(self) -> None:
        self._origin = self.time()
        self._since = self._now()

    def play(self) -> None:
        if self._playing:
            return
        if self._origin >= self.duration and self.loop:
            self._origin = 0.0  # play again from the start after running to the end
        self._since = self._now()
        self._playing = True

    def pause(self) -> None:
        if not self._playing:
            return
        self._rebase()
        self._playing = False

    def seek(self, t: float) -> None:
        """Jump to trajectory time ``t`` [s] (clamped), keeping the play state."""
        self._origin = min(max(float(t), 0.0), self.duration)
        self._since = self._now()

    def set_speed(self, speed: float) -> None:
        self._rebase()
        self._speed = _check_speed(speed)


def _check_speed(speed: float) -> float:
    speed = float(speed)
    if not 0.0 < speed <= 10.0:
        raise ValueError(f"playback speed must lie in (0, 10], got {speed}")
    return speed


@dataclass
class TickStats:
    """How often a session's poses were sent (``/api/viewer/sessions``, the benchmark).

    ``fps`` is the rate while the robots move: one over the median interval between the last
    frames (pauses and the hold at the end of a loop do not count).
    """

    frames: int = 0
    times: deque[float] = field(default_factory=lambda: deque(maxlen=121))

    def frame(self, now: float | None = None) -> None:
        self.frames += 1
        self.times.append(time.monotonic() if now is None else now)

    def fps(self) -> float:
        if len(self.times) < 3:
            return 0.0
        gaps = sorted(b - a for a, b in itertools.pairwise(self.times))
        median = gaps[len(gaps) // 2]
        return 1.0 / median if median > 0 else 0.0


class Player:
    """One thread that calls every registered callback at ``fps`` until stopped.

    Args:
        fps: ticks per second.
    """

    def __init__(self, fps: float = 60.0) -> None:
        if not 1.0 <= fps <= 240.0:
            raise ValueError(f"player rate must lie in [1, 240] fps, got {fps}")
        self.period = 1.0 / fps
        self._callbacks: dict[int, Callable[[], None]] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def add(self, key: int, callback: Callable[[], None]) -> None:
        with self._lock:
            self._callbacks[key] = callback

    def remove(self, key: int) -> None:
        with self._lock:
            self._callbacks.pop(key, None)

    def __len__(self) -> int:
        with self._lock:
            return len(self._callbacks)

    def start(self) -> None:
        if self._thread is not None:
            return
        self._thread = threading.Thread(target=self._run, name="bioplan-viewer-player")
        self._thread.daemon = True
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None

    def _run(self) -> None:
        next_tick = time.monotonic()
        while not self._stop.is_set():
            with self._lock:
                callbacks = list(self._callbacks.items())
            for key, callback in callbacks:
                try:
                    callback()
                except Exception:  # one broken tab must not stop the others
                    logger.exception("viewer session %s failed to update; dropping it", key)
                    self.remove(key)
            if not callbacks:
                # No tab open: wake rarely instead of 60 times a second.
                self._stop.wait(0.2)
                next_tick = time.monotonic()
                continue
            next_tick += self.period
            delay = next_tick - time.monotonic()
            if delay < 0:
                # Fell behind (slow machine): skip the missed ticks instead of bursting.
                next_tick = time.monotonic()
                delay = 0.0
            self._stop.wait(delay)
