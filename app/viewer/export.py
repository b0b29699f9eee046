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
from app.planning.energy import FLOOR_NOTES
from app.viewer.comparison import (
    PHASES,
    Comparison,
    floor_state,
    floor_tolerance,
    template_provenance,
    trajectory_colour,
    trajectory_label,
)
from app.viewer.framing import FOV
from app.viewer.scene import (
    ComparisonScene,
    Layout,
    PreparedComparison,
    configure_lighting,
    no_human_text,
    rgb,
)

#: Frames per second of the recorded animation (a 1 s plan records 30 poses).
EXPORT_FPS = 30.0
#: The largest number of animation frames an export records.
MAX_FRAMES = 900


def scene_html(
    prepared: PreparedComparison, *, fps: float = EXPORT_FPS, layout: Layout = "side_by_side"
) -> str:
    """A self-contained HTML file with the 3-D scene and a recorded loop of both motions.

    A private viser server (loopback, a free port, no clients) holds the scene while it is
    recorded; it is stopped before this returns.

    Args:
        prepared: the comparison.
        fps: animation frames per second of trajectory time.
        layout: ``"side_by_side"`` (default: the two robots apart, as the live viewer first
            shows them, ``PreparedComparison.slot_offsets``) or ``"ghost"`` (overlaid).
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


def _fmt(value: Any, digits: int = 4) -> str:
    """A number as the page prints it (``–`` for none); anything else as escaped text."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int | float):
        v = float(value)
        if not math.isfinite(v):
            return "–"
        return f"{v:.{digits}g}"
    return html.escape(str(value))


#: The floor keys older results used (named after the physics only).
LEGACY_FLOOR_KEYS = {"abs_work": "delta_potential", "pos_work": "delta_potential",
                     "peak_power": "min_peak_power"}  # fmt: skip


def _methods(result: dict[str, Any], planned: tuple[str, ...]) -> dict[str, dict[str, Any]]:
    """method -> its result, in the comparison's order (older results: quintic and paper)."""
    methods = result.get("methods") or {}
    if methods:
        order = [m for m in planned if m in methods] + [m for m in methods if m not in planned]
        return {m: dict(methods[m] or {}) for m in order}
    out = {"quintic": dict(result.get("standard") or {})}
    if result.get("optimized"):
        out["paper"] = {**result["optimized"], "improvement_pct": result.get("improvement_pct")}
    return out


def _floor_of(floors: dict[str, Any], metric: str) -> float | None:
    info = METRICS[metric]
    if info.floor is None:
        return None
    for key in (metric, info.floor, LEGACY_FLOOR_KEYS.get(metric)):
        if key and floors.get(key) is not None:
            return float(floors[key])
    return None


def _metric_cell(
    name: str, side: dict[str, Any], metric: str, floor: float | None, tolerance: float
) -> str:
    """One value with its change against the quintic and its place against the floor."""
    value = side.get(metric)
    if value is None:
        return '<td class="muted">not modelled</td>'
    change = None if name == "quintic" else (side.get("improvement_pct") or {}).get(metric)
    state = floor_state(float(value), floor, tolerance)
    out = _fmt(value)
    if isinstance(change, int | float) and math.isfinite(change):
        out += f'<div class="small">{change:+.1f} %</div>'
    if state == "below":
        out += '<div class="small worse">below floor!</div>'
    elif state == "at":
        out += '<div class="small muted">at the floor</div>'
    return f'<td class="{"below-floor" if state == "below" else ""}">{out}</td>'


def _metrics_table(c: Comparison) -> str:
    """Every planned method's metrics, changes, floors, shares and peak-velocity angles."""
    result = c.result
    methods = _methods(result, c.methods)
    floors = result.get("floors") or {}
    notes = result.get("floor_notes") or FLOOR_NOTES
    tolerance = floor_tolerance(c.kind)
    heads = "".join(f"<th>{html.escape(trajectory_label(m))}</th>" for m in methods)
    rows = []
    for metric in (m for m in METRICS.values() if not m.per_joint):
        floor = _floor_of(floors, metric.name)
        cells = "".join(
            _metric_cell(name, side, metric.name, floor, tolerance)
            for name, side in methods.items()
        )
        floor_text = (
            "no floor"
            if floor is None
            else f'{_fmt(floor)}<div class="small">{html.escape(str(notes.get(metric.name)))}</div>'
        )
        rows.append(
            f'<tr><td>{html.escape(metric.name)}<div class="small">{html.escape(metric.formula)}'
            f"</div></td><td>{html.escape(metric.unit)}</td>{cells}<td>{floor_text}</td></tr>"
        )
    shares = result.get("share_of_achievable_pct") or {}
    objective = html.escape(str((result.get("conditions") or {}).get("objective", "the objective")))
    share_cells = "".join(
        f"<td>{'–' if shares.get(m) is None else f'{float(shares[m]):.1f} %'}</td>" for m in methods
    )
    rows.append(
        '<tr><td>share of the achievable saving<div class="small">(quintic − method) / '
        f"(quintic − bound) on {objective}</div></td><td>%</td>{share_cells}<td></td></tr>"
    )
    angle_cells = "".join(
        f"<td>{_fmt(s.get('peak_velocity_angle_deg'), 3)}</td>" for s in methods.values()
    )
    rows.append(f"<tr><td>elbow peak-velocity angle</td><td>°</td>{angle_cells}<td></td></tr>")
    if any(s.get("human_likeness") is not None for s in methods.values()):
        cells = "".join(f"<td>{_fmt(s.get('human_likeness'), 3)}</td>" for s in methods.values())
        rows.append(
            f"<tr><td>human-likeness (0 = the template's shape)</td><td></td>{cells}<td></td></tr>"
        )
    return (
        '<div class="wrap"><table id="metrics"><thead><tr><th>metric</th><th>unit</th>'
        f"{heads}<th>physical floor</th></tr></thead><tbody>{''.join(rows)}</tbody></table></div>"
    )


def _torque_table(c: Comparison) -> str:
    """Peak torque per joint and method [Nm]."""
    methods = _methods(c.result, c.methods)
    heads = "".join(f"<th>{html.escape(j)}</th>" for j in c.joint_names)
    rows = "".join(
        f"<tr><td>{html.escape(trajectory_label(m))}</td>"
        + "".join(f"<td>{_fmt(v)}</td>" for v in (side.get("peak_torque") or []))
        + "</tr>"
        for m, side in methods.items()
    )
    return (
        '<div class="wrap"><table id="peak-torque"><thead><tr><th>peak torque [Nm]</th>'
        f"{heads}</tr></thead><tbody>{rows}</tbody></table></div>"
    )


def _curves_figure(c: Comparison) -> Any:
    """Power, energy, and the elbow's velocity, torque, flexion and acceleration: every
    planned method in each of six panels (older results: the standard and optimised pair)."""
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
        for label in c.choices:
            trace = go.Scatter(
                x=c.t,
                y=data[label],
                name=trajectory_label(label),
                legendgroup=label,
                showlegend=row == 1 and col == 1,
                line={"color": trajectory_colour(label), "width": 2},
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


def _conditions(c: Comparison) -> str:
    """The conditions line: robot, payload, duration, objective, seed (scalars only)."""
    cond = c.result.get("conditions") or {}
    parts = [
        f"{html.escape(str(k))} {_fmt(cond.get(k))}"
        for k in ("robot", "payload", "duration", "objective", "seed")
        if k in cond and not isinstance(cond.get(k), dict | list)
    ]
    return ", ".join(parts)


def _human_section(c: Comparison) -> str:
    """Where the template came from, what its angle is, and the recorded human's note."""
    info = c.template or template_provenance(c.result)
    source, angle = (
        html.escape(str(info.get(k, "")), quote=False) for k in ("source", "angle_text")
    )
    note = html.escape(c.human_note or no_human_text(c), quote=False)
    return (
        f'<p id="template-source"><strong>Human template:</strong> {source}.</p>'
        f'<p class="note" id="template-angle">{angle}.</p>'
        f'<p class="note" id="human-note">{note}.</p>'
    )


def _warnings(c: Comparison) -> str:
    warnings = [str(w) for w in c.result.get("warnings") or []]
    if not warnings:
        return ""
    items = "".join(f"<li>{html.escape(w)}</li>" for w in warnings)
    return f"<h2>Warnings</h2><ul>{items}</ul>"


_REPORT_STYLE = """body { font: 14px/1.45 system-ui, sans-serif; margin: 24px auto;
  max-width: 1100px; color: #1f2328; padding: 0 16px; }
.wrap { max-width: 100%; overflow-x: auto; }
table { border-collapse: collapse; margin: 8px 0 20px; }
th, td { border-bottom: 1px solid #d0d7de; padding: 4px 12px; text-align: right;
  vertical-align: top; }
th:first-child, td:first-child { text-align: left; }
.note, .small, .muted { color: #57606a; }
.small { font-size: 12px; }
.worse { color: #cf222e; font-weight: 600; }"""


def report_html(comparison: Comparison) -> str:
    """A self-contained HTML report of what the Compare page shows: every planned method's
    metrics, changes against the quintic, floors ("no floor" where none), shares of the
    achievable saving and peak torques; the template's provenance and the recorded human's
    note; the curves of every method, phases shaded."""
    c = comparison
    body = _curves_figure(c).to_html(full_html=False, include_plotlyjs=True)
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
<p class="note">{_conditions(c)}. Under each value: its change against the standard quintic,
100 (quintic − method) / quintic; positive means the method uses less. Phases (shaded, the
second method shown): {phase_text}.</p>
{_human_section(c)}
<h2>Metrics</h2>
{_metrics_table(c)}
<p class="note"><strong>Physical floors:</strong> no rest-to-rest motion does less work than
|ΔPE| or has a lower peak power than |ΔPE|/T (loose: the bound is the reference); electrical
energy adds the friction no motion avoids; tau_sq and peak torque have no floor. A value within
{100 * floor_tolerance(c.kind):g} % of its floor (the integration's round-off) is at it.</p>
{_torque_table(c)}
{_warnings(c)}
{body}
</body></html>
"""
