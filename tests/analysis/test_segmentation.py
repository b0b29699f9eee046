"""Lifts and phases: closed-form curls, gaps, and the Noraxon curls from EMG alone."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from app.analysis.emg import emg_envelope
from app.analysis.segmentation import Lift, detect_emg_lifts, detect_lifts, split_phases
from tests.analysis._data import noraxon_mat

BASE, AMP, DUR = np.deg2rad(10.0), np.deg2rad(130.0), 2.0  # rest angle, curl range, curl time
STARTS = (1.0, 4.5, 8.0, 11.5)


def _curls(rate: float = 100.0, seconds: float = 15.0) -> tuple[NDArray[np.float64], ...]:
    """Raised-cosine curls: 10 deg -> 140 deg -> 10 deg over DUR seconds, rest between."""
    t = np.arange(int(seconds * rate)) / rate
    y = np.full_like(t, BASE)
    for t0 in STARTS:
        m = (t >= t0) & (t <= t0 + DUR)
        y[m] = BASE + AMP * (1 - np.cos(2 * np.pi * (t[m] - t0) / DUR)) / 2
    return t, y


def _time_at(level: float, t0: float, rising: bool) -> float:
    """Closed-form time where the raised cosine of the curl starting at t0 reaches ``level``."""
    phase = np.arccos(1 - 2 * (level - BASE) / AMP) / (2 * np.pi) * DUR
    return t0 + (phase if rising else DUR - phase)


#: Speed of the raised cosine: AMP pi / DUR sin(2 pi tau), so it is 5 % of its peak at
#: tau = asin(0.05) / (2 pi) after the start and before the top (and mirrored on the way down).
SLOW = DUR * np.arcsin(0.05) / (2 * np.pi)


def test_lifts_of_raised_cosine_curls() -> None:
    t, y = _curls()
    lifts = detect_lifts(y, t)
    assert len(lifts) == len(STARTS)
    for lift, t0 in zip(lifts, STARTS, strict=True):
        assert lift.source == "angle"
        # Boundaries where the speed is 5 % of its peak (one 10 ms sample of slack).
        assert lift.start == pytest.approx(t0 + SLOW, abs=0.011)
        assert lift.top == pytest.approx(t0 + DUR / 2 - SLOW, abs=0.011)
        assert lift.eccentric[0] == pytest.approx(t0 + DUR / 2 + SLOW, abs=0.011)
        assert lift.end == pytest.approx(t0 + DUR - SLOW, abs=0.011)
        assert lift.top_angle == pytest.approx(BASE + AMP, abs=np.deg2rad(0.1))
        # The old rule (within 5 % of the amplitude of rest) started when the elbow already
        # moved at about 44 % of its peak speed; the speed rule starts 0.13 s earlier.
        assert lift.start < _time_at(BASE + 0.05 * AMP, t0, True) - 0.1


def test_a_hold_at_the_top_is_its_own_part_not_phase_c() -> None:
    """A curl that rises in 1 s, holds 1.5 s at 140 deg and lowers in 1 s: the top is the
    first arrival (t0 + 1 s, less the 5 %-speed margin), lowering starts after the hold, and
    concentric C ends at the top while eccentric C starts at the lowering."""
    rate, t0, rise, hold = 200.0, 1.0, 1.0, 1.5
    t = np.arange(int(6 * rate)) / rate
    up = np.clip((t - t0) / rise, 0, 1)
    down = np.clip((t - t0 - rise - hold) / rise, 0, 1)
    y = BASE + AMP * ((1 - np.cos(np.pi * up)) / 2 - (1 - np.cos(np.pi * down)) / 2)
    (lift,) = detect_lifts(y, t)
    margin = rise * np.arcsin(0.05) / np.pi  # half-cosine speed: 5 % of peak
    assert lift.top == pytest.approx(t0 + rise - margin, abs=0.006)
    assert lift.hold[1] == pytest.approx(t0 + rise + hold + margin, abs=0.006)
    assert lift.hold[1] - lift.hold[0] > hold
    phases = split_phases(y, t, lift)
    conc_c = next(p for p in phases if p.part == "concentric" and p.name == "C")
    ecc_c = next(p for p in phases if p.part == "eccentric" and p.name == "C")
    assert conc_c.end == lift.top
    assert ecc_c.start == lift.hold[1]
    assert all(p.end <= lift.top or p.start >= lift.hold[1] for p in phases)


def test_noise_and_small_wiggles_do_not_make_lifts() -> None:
    t, y = _curls()
    rng = np.random.default_rng(0)
    noisy = y + np.deg2rad(1.0) * rng.standard_normal(len(t))
    noisy[(t > 13.8) & (t < 14.3)] += np.deg2rad(15.0)  # a fidget, not a lift
    assert len(detect_lifts(noisy, t)) == len(STARTS)


def test_a_lift_cut_by_a_gap_is_not_counted() -> None:
    t, y = _curls()
    y = y.copy()
    y[(t > 5.0) & (t < 5.8)] = np.nan  # inside the second curl
    lifts = detect_lifts(y, t)
    assert [round(lift.top, 1) for lift in lifts] == [2.0, 9.0, 12.5]


def test_phases_by_elbow_angle_match_closed_form_crossings() -> None:
    t, y = _curls(rate=1000.0)
    lift = detect_lifts(y, t)[0]
    b1, b2 = np.deg2rad(40.0), np.deg2rad(90.0)
    phases = split_phases(y, t, lift, bounds=(b1, b2))
    assert [(p.part, p.name) for p in phases] == [
        ("concentric", "A"),
        ("concentric", "B"),
        ("concentric", "C"),
        ("eccentric", "C"),
        ("eccentric", "B"),
        ("eccentric", "A"),
    ]
    t0 = STARTS[0]
    expected = [
        _time_at(b1, t0, True),
        _time_at(b2, t0, True),
        lift.top,
        _time_at(b2, t0, False),
        _time_at(b1, t0, False),
    ]
    got = [p.end for p in phases[:-1]]
    np.testing.assert_allclose(got, expected, atol=1e-4)
    assert phases[0].start == lift.start
    assert phases[-1].end == lift.end


def test_lift_starting_above_the_first_bound_has_no_phase_a() -> None:
    t, y = _curls()
    y = y + np.deg2rad(40.0)  # rests at 50 deg
    lift = detect_lifts(y, t)[0]
    names = [(p.part, p.name) for p in split_phases(y, t, lift)]
    assert ("concentric", "A") not in names
    assert names[0] == ("concentric", "B")


def _bursts(rate: float, tops: list[float]) -> NDArray[np.float64]:
    rng = np.random.default_rng(1)
    t = np.arange(int(20 * rate)) / rate
    gain = 0.05 + sum(np.exp(-(((t - c) / 0.5) ** 2)) for c in tops)
    return np.asarray(gain * rng.standard_normal(len(t)))


def test_emg_lifts_of_synthetic_bursts() -> None:
    rate = 1000.0
    tops = [3.0, 7.5, 12.0, 16.0]
    env = emg_envelope(_bursts(rate, tops), rate)
    lifts = detect_emg_lifts(env, rate, start=10.0)
    assert [lift.source for lift in lifts] == ["emg"] * 4
    np.testing.assert_allclose([lift.top for lift in lifts], np.add(tops, 10.0), atol=0.1)
    for lift in lifts:
        assert lift.start < lift.top < lift.end


@pytest.mark.parametrize("name", ["NT-01", "SP-01"])
def test_noraxon_curls_give_ten_lifts_from_emg_alone(name: str) -> None:
    x, rate = noraxon_mat(name)
    lifts = detect_emg_lifts(emg_envelope(x, rate), rate)
    assert len(lifts) == 10
    # Protocol: each repetition at least 2 s with a pause; bursts do not overlap.
    starts = np.array([lift.start for lift in lifts])
    ends = np.array([lift.end for lift in lifts])
    assert np.all(starts[1:] > ends[:-1])
    assert np.all(np.diff([lift.top for lift in lifts]) > 3.0)


def test_lift_properties() -> None:
    lift = Lift(start=1.0, top=2.0, end=3.5, source="angle")
    assert lift.concentric == (1.0, 2.0)
    assert lift.eccentric == (2.0, 3.5)
    assert lift.duration == 2.5
