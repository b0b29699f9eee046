"""Min/max downsampling against a brute-force reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from app.analysis.downsample import minmax_downsample


def brute_force(y: np.ndarray, points: int) -> set[float]:
    """Per bucket (same bucketing), the min and max of the valid samples, by plain loops."""
    buckets = points // 2
    size = -(-len(y) // buckets)
    out = set()
    for b in range(buckets):
        vals = [v for v in y[b * size : (b + 1) * size] if not np.isnan(v)]
        if vals:
            out |= {min(vals), max(vals)}
    return out


values = hnp.arrays(
    np.float64,
    st.integers(1, 400),
    elements=st.one_of(st.floats(-1e6, 1e6), st.just(float("nan"))),
)


@settings(max_examples=200, deadline=None)
@given(y=values, points=st.integers(2, 60))
def test_matches_brute_force(y: np.ndarray, points: int) -> None:
    t = np.arange(len(y)) * 0.01
    ts, ys = minmax_downsample(t, y, points)
    assert len(ts) == len(ys) <= max(points, 0)
    assert np.all(np.diff(ts) > 0)  # time order, no duplicates
    assert not np.isnan(ys).any()
    np.testing.assert_array_equal(ys, y[np.round(ts / 0.01).astype(int)])  # real samples
    valid = y[~np.isnan(y)]
    if len(y) <= points:
        np.testing.assert_array_equal(ys, valid)
    else:
        assert set(ys.tolist()) == brute_force(y, points)
    if valid.size:
        assert ys.max() == valid.max() and ys.min() == valid.min()


def test_spike_survives_heavy_decimation() -> None:
    t = np.linspace(0, 10, 1_000_001)
    y = np.sin(t)
    y[123_457] = 50.0
    ts, ys = minmax_downsample(t, y, 100)
    assert len(ys) <= 100 and ys.max() == 50.0 and ts[ys.argmax()] == t[123_457]


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="points"):
        minmax_downsample(np.zeros(3), np.zeros(3), 1)
    with pytest.raises(ValueError, match="equal length"):
        minmax_downsample(np.zeros(3), np.zeros(4), 10)
