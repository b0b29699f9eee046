"""Plot data for the viewer's uPlot panel: the power curves with a moving time cursor."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from app.viewer.comparison import Comparison

FloatArray = NDArray[np.float64]

#: Samples of each power curve in the panel (a 300 px wide plot needs no more).
PLOT_POINTS = 240


def power_plot(
    comparison: Comparison,
    t_now: float,
    *,
    points: int = PLOT_POINTS,
    labels: tuple[str, str] = ("standard", "optimized"),
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """uPlot data: time, two trajectories' power [W], and a time cursor at ``t_now``.

    ``labels`` names the two trajectories (the solid and the ghost robot's; default the
    standard and the optimised one).

    uPlot draws one x array for all series and viser sends plain float arrays (no gaps), so the
    cursor is a series on its own 0-1 scale that is 0 everywhere except for a spike to 1 at
    ``t_now``: three samples at ``t_now`` (0, 1, 0) are inserted into the curves, which are
    interpolated there. The spike draws as a vertical line; the rest lies on the x axis.

    Returns:
        (t, first, second, cursor), each (points + 3,) at most.
    """
    c = comparison
    idx = np.unique(np.linspace(0, len(c.t) - 1, min(points, len(c.t))).round().astype(int))
    t = c.t[idx]
    std = c.power[labels[0]][idx]
    opt = c.power[labels[1]][idx]
    now = float(min(max(t_now, t[0]), t[-1]))
    k = int(np.searchsorted(t, now))
    at_std = float(np.interp(now, t, std))
    at_opt = float(np.interp(now, t, opt))
    t_out = np.concatenate([t[:k], [now, now, now], t[k:]])
    std_out = np.concatenate([std[:k], [at_std] * 3, std[k:]])
    opt_out = np.concatenate([opt[:k], [at_opt] * 3, opt[k:]])
    cursor = np.zeros(t_out.shape)
    cursor[k + 1] = 1.0
    return t_out, std_out, opt_out, cursor
