"""The array helpers the analysis modules share."""

from __future__ import annotations

import numpy as np
import pytest

from app.analysis._checks import true_runs


def _runs_by_loop(mask: list[bool]) -> list[list[int]]:
    """[start, stop) of every run of True, walking the mask one sample at a time."""
    runs: list[list[int]] = []
    for i, value in enumerate(mask):
        if value and (i == 0 or not mask[i - 1]):
            runs.append([i, i + 1])
        elif value:
            runs[-1][1] = i + 1
    return runs


@pytest.mark.parametrize("n", [0, 1, 2, 7, 200])
def test_true_runs_match_a_sample_by_sample_walk(n: int) -> None:
    mask = (np.random.default_rng(n).random(n) < 0.5).tolist()
    got = true_runs(np.array(mask, dtype=bool))
    assert got.shape == (len(_runs_by_loop(mask)), 2)
    assert got.tolist() == _runs_by_loop(mask)


def test_true_runs_at_the_edges() -> None:
    assert true_runs(np.ones(4, dtype=bool)).tolist() == [[0, 4]]
    assert true_runs(np.zeros(4, dtype=bool)).tolist() == []
    assert true_runs([True, False, False, True]).tolist() == [[0, 1], [3, 4]]
