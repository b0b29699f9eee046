"""The playback clock on a fake time source, and the player thread."""

from __future__ import annotations

import threading
import time

import pytest

from app.viewer.playback import PlaybackClock, Player


class FakeTime:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_play_pause_seek_speed() -> None:
    wall = FakeTime()
    clock = PlaybackClock(2.0, hold=0.5, now=wall)
    assert clock.time() == 0.0 and not clock.playing
    wall.now += 5.0
    assert clock.time() == 0.0  # paused: wall time does not move it
    clock.play()
    wall.now += 0.75
    assert clock.time() == pytest.approx(0.75)
    clock.set_speed(2.0)
    wall.now += 0.25
    assert clock.time() == pytest.approx(1.25)
    clock.pause()
    wall.now += 3.0
    assert clock.time() == pytest.approx(1.25)
    clock.seek(0.4)
    assert clock.time() == pytest.approx(0.4)
    clock.seek(-3.0)
    assert clock.time() == 0.0
    clock.seek(9.0)
    assert clock.time() == 2.0


def test_loop_holds_the_last_pose_then_starts_over() -> None:
    wall = FakeTime()
    clock = PlaybackClock(1.0, hold=0.5, now=wall)
    clock.play()
    wall.now += 1.2  # inside the hold
    assert clock.time() == 1.0
    wall.now += 0.4  # 1.6 s: the next loop, 0.1 s in
    assert clock.time() == pytest.approx(0.1)
    # At double speed the hold lasts the same wall-clock time.
    clock.set_speed(2.0)
    clock.seek(0.0)
    wall.now += 0.5 + 0.25  # end after 0.5 s, hold 0.5 s, not over yet
    assert clock.time() == 1.0
    wall.now += 0.3
    assert clock.time() == pytest.approx(0.1)


def test_without_loop_it_stops_at_the_end_and_play_restarts() -> None:
    wall = FakeTime()
    clock = PlaybackClock(1.0, loop=False, now=wall)
    clock.play()
    wall.now += 5.0
    assert clock.time() == 1.0
    clock.pause()
    clock.play()
    assert clock.time() == 1.0  # no loop: stays at the end


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="duration must be > 0"):
        PlaybackClock(0.0)
    with pytest.raises(ValueError, match=r"speed must lie in \(0, 10\]"):
        PlaybackClock(1.0, speed=-1.0)
    with pytest.raises(ValueError, match="player rate"):
        Player(fps=0.5)


def test_player_ticks_at_its_rate_and_drops_a_failing_session() -> None:
    player = Player(fps=100.0)
    ticks = {"ok": 0}
    failed = threading.Event()

    def ok() -> None:
        ticks["ok"] += 1

    def broken() -> None:
        failed.set()
        raise RuntimeError("boom")

    player.add(1, ok)
    player.add(2, broken)
    player.start()
    try:
        time.sleep(0.5)
    finally:
        player.stop()
    assert failed.is_set()
    assert len(player) == 1  # the broken one was removed, the other kept
    # 100 fps for 0.5 s: about 50 ticks (loose: the machine is shared).
    assert 15 <= ticks["ok"] <= 60


def test_tick_stats_rate_ignores_pauses() -> None:
    from app.viewer.playback import TickStats

    stats = TickStats()
    t = 0.0
    for loop in range(3):
        for _ in range(40):
            t += 0.02  # 50 frames per second while moving
            stats.frame(t)
        t += 0.6 * (loop + 1)  # the hold at the end of each loop sends nothing
    assert stats.frames == 120
    assert stats.fps() == pytest.approx(50.0)
    assert TickStats().fps() == 0.0
