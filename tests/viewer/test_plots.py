"""The uPlot power panel data: curves, the time cursor."""

from __future__ import annotations

import numpy as np
import pytest

from app.viewer.comparison import Comparison
from app.viewer.plots import power_plot


@pytest.mark.parametrize("t_now", [0.0, 0.3137, 0.5, 1.0, 7.0])
def test_cursor_and_interpolated_curves(plan_comparison: Comparison, t_now: float) -> None:
    c = plan_comparison
    t, std, opt, cursor = power_plot(c, t_now, points=100)
    assert len(t) == len(std) == len(opt) == len(cursor) == 103
    assert np.all(np.diff(t) >= 0)  # uPlot needs sorted x (duplicates allowed)
    spike = np.flatnonzero(cursor)
    assert len(spike) == 1 and cursor[spike[0]] == 1.0
    now = min(t_now, float(c.t[-1]))
    assert t[spike[0] - 1] == t[spike[0]] == t[spike[0] + 1] == pytest.approx(now)
    # Elsewhere the curves are the stored power; at the cursor, interpolated.
    assert std[spike[0]] == pytest.approx(np.interp(now, c.t, c.power["standard"]), rel=1e-2)
    assert opt[spike[0]] == pytest.approx(np.interp(now, c.t, c.power["optimized"]), rel=1e-2)
    assert np.max(std) == pytest.approx(np.max(c.power["standard"]), rel=0.02)
