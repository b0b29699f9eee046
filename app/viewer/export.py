"""Exports of a comparison that open without the server.

``scene_html``: viser's own scene serializer records the comparison scene and a loop of the
animation; ``StateSerializer.as_html`` wraps it with viser's single-file client into one HTML
file (WebGL, no network). ``report_html``: the curves and the metrics table as one HTML file with
Plotly.js inlined from the installed ``plotly`` package.
"""

from __future__ import annotations

import html
import math
import re
from typing import Any

import numpy as np

from app.names import METRICS
from app.names import PHASES as PHASE_INFO
from app.viewer.comparison import LABELS, PHASES, Comparison
from app.viewer.framing import FOV
from app.viewer.scene import (
    COLORS,
    ComparisonScene,
    Layout,
    PreparedComparison,
    configure_lighting,
    rgb,
)

#: Frames per second of the recorded animation (a 1 s plan records 30 poses).
EXPORT_FPS = 30.0
#: The largest number of animation frames an export records.
MAX_FRAMES = 900


def scene_html(
    prepared: PreparedComparison, *, fps: float = EXPORT_FPS, layout: Layout = "ghost"
) -> str:
    """A self-contained HTML file with the 3-D scene and a recorded loop of both motions.

    A private viser server (loopback, a free port, no clients) holds the scene while it is
    recorded; it is stopped before this returns.

    Args:
        prepared: the comparison.
        fps: animation frames per second of trajectory time.
        layout: ``"ghost"`` or ``"side_by_side"``.
    """
    import viser

    if not 1.0 <= fps <= 120.0:
        raise ValueError(f"export fps must lie in [1, 120], got {fps}")
    c = prepared.comparison
    frames = int(min(MAX_FRAMES, max(2, math.ceil(c.duration * fps) + 1)))
    times = np.linspace(float(c.t[0]), float(c.t[-1]), frames)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        server.scene.set_up_direction("+z")
        configure_lighting(server.scene)
        scene = ComparisonScene(server, prepared, layout=layout)
        position, look_at = scene.camera()
        server.initial_camera.fov = FOV  # the framing's field of view
        server.initial_camera.position = position
        server.initial_camera.look_at = look_at
        server.initial_camera.up = (0.0, 0.0, 1.0)
        serializer = server.get_scene_serializer()
        dt = 1.0 / fps
        for t in times:
            scene.show(c.index_at(float(t)))
            serializer.insert_sleep(dt)
        serializer.insert_sleep(0.6)  # hold the last pose before the loop restarts
        page: str = serializer.as_html()
    finally:
        server.stop()
    title = f"<title>{html.escape(c.title)} — BioPlan</title>"
    if re.search(r"<title>.*?</title>", page, flags=re.S):
        return re.sub(r"<title>.*?</title>", lambda _: title, page, count=1, flags=re.S)
    return page.replace("<head>", f"<head>{title}", 1)


def _metric_rows(result: dict[str, Any]) -> list[tuple[str, Any, Any, Any]]:
    std, opt = result.get("standard", {}), result.get("optimized", {})
    pct = result.get("improvement_pct", {})
    return [(k, std.get(k), opt.get(k), pct.get(k)) for k in std if k in opt]


def _fmt(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, list):
        return ", ".join(_fmt(v) for v in value)
    if isinstance(value, float):
        return f"{value:.4g}"
    return html.escape(str(value))


#: Units of the metrics and of the floors in a result.
UNITS = {
    **{m.name: m.unit for m in METRICS.values()},
    "delta_potential": "J",
    "min_peak_power": "W",
}
#: How the trajectories are called in the report.
TRAJECTORY_NAMES = {"standard": "standard quintic", "optimized": "bio-inspired"}


def _curves_figure(c: Comparison) -> Any:
    """Power, energy, and the elbow's velocity, torque, flexion and acceleration: both
    trajectories in each of six panels."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    e = c.elbow_joint
    # Plotly.js reads a subset of HTML in titles (links, styles): a joint name is text only.
    elbow = html.escape(c.joint_names[e])
    fig = make_subplots(
        rows=3,
        cols=2,
        subplot_titles=(
            "Mechanical power Σ|τ·ω| [W]",
            "Cumulative energy [J]",
            f"Elbow velocity ({elbow}) [rad/s]",
            f"Elbow torque ({elbow}) [Nm]",
            "Elbow flexion [deg]",
            "Elbow acceleration [rad/s²]",
        ),
        vertical_spacing=0.09,
    )
    series = (
        (1, 1, c.power),
        (1, 2, c.energy),
        (2, 1, {k: v[:, e] for k, v in c.qd.items()}),
        (2, 2, {k: v[:, e] for k, v in c.tau.items()}),
        (3, 1, c.elbow_flexion_deg),
        (3, 2, {k: v[:, e] for k, v in c.qdd.items()}),
    )
    for row, col, data in series:
        for label in LABELS:
            trace = go.Scatter(
                x=c.t,
                y=data[label],
                name=TRAJECTORY_NAMES[label],
                legendgroup=label,
                showlegend=row == 1 and col == 1,
                line={"color": "rgb({},{},{})".format(*COLORS[label]), "width": 2},
            )
            fig.add_trace(trace, row=row, col=col)
    _shade_phases(fig, c)
    fig.update_layout(
        height=980,
        template="plotly_white",
        margin={"l": 60, "r": 20, "t": 60, "b": 40},
        legend={"orientation": "h", "y": 1.05},
    )
    fig.update_xaxes(title_text="t [s]", row=3)
    return fig


def _shade_phases(fig: Any, c: Comparison) -> None:
    """The optimised motion's A/B/C phases, shaded in every panel in their shared colours."""
    t_ab, t_bc = c.phase_times["optimized"]
    edges = [float(c.t[0]), t_ab, t_bc, float(c.t[-1])]
    for phase, x0, x1 in zip(PHASE_INFO, edges[:-1], edges[1:], strict=True):
        if math.isnan(x0) or math.isnan(x1) or x1 <= x0:
            continue
        fig.add_vrect(
            x0=x0,
            x1=x1,
            fillcolor="rgba({},{},{},0.09)".format(*rgb(phase.colour)),
            line_width=0,
            layer="below",
            row="all",
            col="all",
            annotation_text=phase.name,
            annotation_position="top left",
        )


def _tables(result: dict[str, Any]) -> tuple[str, str, str]:
    """The metrics rows, the floors rows and the conditions line of a result, as HTML."""
    rows = "".join(
        f"<tr><td>{html.escape(k)}</td><td>{UNITS.get(k, '')}</td><td>{_fmt(s)}</td>"
        f"<td>{_fmt(o)}</td><td>{_fmt(p)}</td></tr>"
        for k, s, o, p in _metric_rows(result)
    )
    floors = "".join(
        f"<tr><td>{html.escape(k)}</td><td>{UNITS.get(k, '')}</td><td>{_fmt(v)}</td></tr>"
        for k, v in (result.get("floors") or {}).items()
    )
    cond = result.get("conditions") or {}
    conditions = ", ".join(
        f"{html.escape(str(k))} {_fmt(cond.get(k))}"
        for k in ("robot", "payload", "duration", "objective", "seed")
        if k in cond
    )
    return rows, floors, conditions


_REPORT_STYLE = """body { font: 14px/1.45 system-ui, sans-serif; margin: 24px auto;
  max-width: 1100px; color: #1f2328; padding: 0 16px; }
table { border-collapse: collapse; margin: 8px 0 20px; }
th, td { border-bottom: 1px solid #d0d7de; padding: 4px 12px; text-align: right; }
th:first-child, td:first-child { text-align: left; }
.note { color: #57606a; }"""


def report_html(comparison: Comparison) -> str:
    """A self-contained HTML report: metrics with floors and the curves, phases shaded."""
    c = comparison
    body = _curves_figure(c).to_html(full_html=False, include_plotlyjs=True)
    rows, floors, conditions = _tables(c.result)
    phase_text = "; ".join(f"{p}: {html.escape(d)}" for p, d in PHASES.items())
    title = html.escape(c.title)
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<title>{title} — BioPlan report</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>
{_REPORT_STYLE}
</style></head><body>
<h1>{title}</h1>
<p class="note">{conditions}. Improvement = 100 (standard − optimised) / standard: positive
means the bio-inspired plan uses less. Phases (shaded, optimised motion): {phase_text}.</p>
<h2>Metrics</h2>
<table><thead><tr><th>metric</th><th>unit</th><th>standard</th><th>optimised</th>
<th>improvement [%]</th></tr></thead><tbody>{rows}</tbody></table>
<h2>Physical floors</h2>
<table><thead><tr><th>floor</th><th>unit</th><th>value</th></tr></thead>
<tbody>{floors}</tbody></table>
{body}
</body></html>
"""
