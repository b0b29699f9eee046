"""Static Plotly figures of an analysis: EMG with onsets, joint angles and velocities with the
A/B/C phases shaded. Files are self-contained HTML next to one local copy of plotly.js (no CDN).
Plotly is imported on first use.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.analysis.pipeline import AnalysisResult, RecordingAnalysis

#: Most points drawn per trace; longer signals are reduced to per-bin minima and maxima, which
#: keeps every spike visible.
MAX_POINTS = 20_000
PHASE_COLORS = {
    "A": "rgba(44,160,44,0.15)",
    "B": "rgba(255,127,14,0.18)",
    "C": "rgba(31,119,180,0.15)",
}


def _envelope_decimate(
    t: NDArray[np.float64], x: NDArray[np.float64], max_points: int = MAX_POINTS
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    n = len(t)
    if n <= max_points:
        return t, x
    bins = max_points // 2
    usable = (n // bins) * bins
    tb = t[:usable].reshape(bins, -1)
    xb = x[:usable].reshape(bins, -1)
    lo, hi = np.nanargmin(xb, axis=1), np.nanargmax(xb, axis=1)
    first = np.minimum(lo, hi)
    second = np.maximum(lo, hi)
    rows = np.arange(bins)
    tt = np.stack([tb[rows, first], tb[rows, second]], axis=1).ravel()
    xx = np.stack([xb[rows, first], xb[rows, second]], axis=1).ravel()
    return tt, xx


def _slug(text: str, index: int) -> str:
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._") or "recording"
    return f"{index:02d}_{stem[:60]}"


def _emg_figure(rec: RecordingAnalysis) -> Any:
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    n = len(rec.emg)
    fig = make_subplots(
        rows=n,
        cols=1,
        shared_xaxes=True,
        vertical_spacing=0.04,
        subplot_titles=[f"{m.muscle} ({m.channel})" for m in rec.emg],
    )
    for i, m in enumerate(rec.emg, start=1):
        t, raw = _envelope_decimate(m.t, m.raw - np.mean(m.raw))
        fig.add_trace(
            go.Scatter(x=t, y=raw, name=f"{m.muscle} raw", line={"width": 0.6, "color": "#999"}),
            row=i,
            col=1,
        )
        te, env = _envelope_decimate(m.t, m.envelope)
        fig.add_trace(
            go.Scatter(x=te, y=env, name=f"{m.muscle} envelope", line={"color": "#d62728"}),
            row=i,
            col=1,
        )
        for on, off in m.onsets:
            fig.add_vrect(
                x0=on, x1=off, fillcolor="rgba(214,39,40,0.08)", line_width=0, row=i, col=1
            )
        fig.update_yaxes(title_text=m.unit, row=i, col=1)
    fig.update_xaxes(title_text="time [s]", row=n, col=1)
    fig.update_layout(
        title=f"EMG: {rec.source} (shaded: detected activity)",
        height=260 * n + 120,
        showlegend=False,
    )
    return fig


def _kinematics_figure(rec: RecordingAnalysis) -> Any:
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    assert rec.angles is not None
    a = rec.angles
    t = a.t + rec.offset
    fig = make_subplots(
        rows=2,
        cols=1,
        shared_xaxes=True,
        vertical_spacing=0.06,
        subplot_titles=["joint angles [deg]", "angular velocities [deg/s]"],
    )
    for name, y, color in (("elbow", a.elbow, "#1f77b4"), ("shoulder", a.shoulder, "#ff7f0e")):
        fig.add_trace(
            go.Scatter(x=t, y=np.rad2deg(y), name=f"{name} flexion", line={"color": color}),
            row=1,
            col=1,
        )
    for name, y, color in (
        ("elbow", a.elbow_velocity, "#1f77b4"),
        ("shoulder", a.shoulder_velocity, "#ff7f0e"),
    ):
        fig.add_trace(
            go.Scatter(
                x=t, y=np.rad2deg(y), name=f"{name} velocity", line={"color": color, "dash": "dot"}
            ),
            row=2,
            col=1,
        )
    for report in rec.lifts:
        for stats in report.phases:
            ph = stats.phase
            for row in (1, 2):
                fig.add_vrect(
                    x0=ph.start,
                    x1=ph.end,
                    fillcolor=PHASE_COLORS[ph.name],
                    line_width=0,
                    row=row,
                    col=1,
                )
        fig.add_vline(x=report.lift.top, line={"color": "#555", "dash": "dash", "width": 1})
    for g0, g1 in a.gaps + rec.offset:
        fig.add_vrect(x0=g0, x1=g1, fillcolor="rgba(0,0,0,0.25)", line_width=0)
    fig.update_xaxes(title_text="time [s]", row=2, col=1)
    fig.update_layout(
        title=(
            f"Kinematics: {rec.source} ({a.side} arm; phases A green, B orange, C blue; "
            "gaps dark; dashed: tops)"
        ),
        height=700,
    )
    return fig


def write_analysis_plots(result: AnalysisResult, out_dir: str | Path) -> list[Path]:
    """Write the analysis figures as HTML into ``out_dir`` (created if needed).

    Per recording: ``NN_<source>_emg.html`` (raw EMG and envelope per muscle, detected activity
    shaded) when it has EMG, and ``NN_<source>_kinematics.html`` (elbow and shoulder flexion and
    velocity, phases shaded, gaps dark) when it has pose. ``plotly.min.js`` is written once into
    ``out_dir`` and referenced by every page, so the figures open offline.

    Args:
        result: the analysis.
        out_dir: output folder.

    Returns:
        The files written (HTML pages, then plotly.min.js).
    """
    import plotly.io as pio

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for i, rec in enumerate(result.recordings, start=1):
        stem = _slug(rec.source, i)
        figures = []
        if rec.emg:
            figures.append((f"{stem}_emg.html", _emg_figure(rec)))
        if rec.angles is not None:
            figures.append((f"{stem}_kinematics.html", _kinematics_figure(rec)))
        for name, fig in figures:
            path = out / name
            pio.write_html(fig, str(path), include_plotlyjs="directory", full_html=True)
            written.append(path)
    bundle = out / "plotly.min.js"
    if written and bundle.exists():
        written.append(bundle)
    return written
