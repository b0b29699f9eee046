"""Static Plotly figures of a cohort: per measure a box plot per group with every recording
drawn as a point, and an onset-order diagram (mean onset latency per muscle and group, with the
most common activation order). Written like :func:`app.analysis.write_analysis_plots`:
self-contained HTML pages next to one local copy of plotly.js (no CDN).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from app.analysis.cohort import ORDER_SEP, CohortResult

#: One colour per muscle in the onset-order diagram (cycled).
MUSCLE_COLORS = ("#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2")


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._")[:60] or "measure"


def _measure_figure(result: CohortResult, measure: str) -> Any:
    import plotly.graph_objects as go

    fig = go.Figure()
    for name in result.groups:
        members = [r for r in result.recordings if r.group == name]
        shown = [r for r in members if r.values.get(measure) is not None]
        fig.add_trace(
            go.Box(
                y=[r.values[measure] for r in shown],
                name=f"{name} (n={len(shown)})",
                text=[f"{r.source} (subject {r.subject})" for r in shown],
                boxpoints="all",
                jitter=0.4,
                pointpos=0.0,
                hoverinfo="y+text",
            )
        )
    tests = [t for t in result.tests if t.measure == measure]
    notes = [
        f"{t.groups[0]} vs {t.groups[1]}: "
        + (
            f"not tested ({t.skipped})"
            if t.skipped
            else f"{t.test} p={t.p:.3g}, adj. p={t.p_adjusted:.3g}, {t.effect_name}="
            + ("-" if t.effect is None else f"{t.effect:.2f}")
        )
        for t in tests
    ]
    unit = result.units.get(measure, "")
    fig.update_layout(
        title=f"{measure} [{unit}] by group<br><sup>{'<br>'.join(notes)}</sup>",
        yaxis_title=f"{measure} [{unit}]",
        showlegend=False,
        margin={"t": 80 + 18 * len(notes)},
    )
    return fig


def _onset_figure(result: CohortResult) -> Any:
    import plotly.graph_objects as go

    muscles = sorted({m for g in result.groups.values() for m in g.activation_order.mean_onset_s})
    groups = list(result.groups)
    fig = go.Figure()
    for k, muscle in enumerate(muscles):
        xs, ys, sds = [], [], []
        for name in groups:
            s = result.groups[name].measures.get(f"onset_{muscle}_s")
            if s is None or s.mean is None:
                continue
            xs.append(s.mean)
            ys.append(name)
            sds.append(s.sd or 0.0)
        fig.add_trace(
            go.Scatter(
                x=xs,
                y=ys,
                mode="markers+text",
                name=muscle,
                text=[muscle] * len(xs),
                textposition="top center",
                marker={"size": 14, "color": MUSCLE_COLORS[k % len(MUSCLE_COLORS)]},
                error_x={"type": "data", "array": sds, "visible": True},
            )
        )
    labels = []
    for name, g in result.groups.items():
        o = g.activation_order
        labels.append(
            f"{name}: {ORDER_SEP.join(o.most_common)} in {o.count}/{o.n} recordings"
            if o.most_common
            else f"{name}: no activation order"
        )
    fig.add_vline(x=0.0, line={"color": "#555", "dash": "dash", "width": 1})
    fig.update_layout(
        title="Onset order: mean onset latency per muscle (+- SD) relative to the lift start"
        f"<br><sup>{'<br>'.join(labels)}</sup>",
        xaxis_title="onset latency [s] (negative: before the lift starts)",
        yaxis={"categoryorder": "array", "categoryarray": groups[::-1]},
        height=200 + 90 * len(groups),
        margin={"t": 90 + 18 * len(labels)},
    )
    return fig


def write_cohort_plots(result: CohortResult, out_dir: str | Path) -> list[Path]:
    """Write the cohort figures as HTML into ``out_dir`` (created if needed).

    ``cohort_<measure>.html`` per measure (a box per group with every recording as a point, the
    tests in the subtitle) and ``cohort_onset_order.html`` (the onset-order diagram), then
    ``plotly.min.js`` once, referenced by every page.

    Returns:
        The files written (HTML pages, then plotly.min.js).
    """
    import plotly.io as pio

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = [(f"cohort_{_slug(m)}.html", _measure_figure(result, m)) for m in result.units]
    figures.append(("cohort_onset_order.html", _onset_figure(result)))
    written: list[Path] = []
    for name, fig in figures:
        path = out / name
        pio.write_html(fig, str(path), include_plotlyjs="directory", full_html=True)
        written.append(path)
    bundle = out / "plotly.min.js"
    if bundle.exists():
        written.append(bundle)
    return written
