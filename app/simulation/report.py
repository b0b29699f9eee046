"""The demo report: the paper's figures and numbers, reproduced and measured.

``write_demo_report`` writes a folder with ``index.html`` (interactive Plotly figures, plotly.js
copied once from the installed ``plotly`` package, so the report opens offline) and
``results.json`` (every number shown). Figures follow the paper:

* Fig. 5: velocity profiles of the classical point-to-point curves (normalised).
* Fig. 6: the quintic polynomial trajectory (position, velocity, acceleration).
* Fig. 7: standard vs bio-optimised trajectories with power and cumulative-energy curves, the
  A/B/C phases shaded, for both built-in robots.

and a table puts the measured savings beside the paper's claims (12 % energy on the 2-link arm,
48.4 % lower peak of the energy-consumption curve on the 6-DOF robot) with the conditions.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

ProgressCallback = Callable[[float, str], None]

#: Paper claims: (robot, metric, claimed saving [%], what the paper measured).
PAPER_CLAIMS: tuple[tuple[str, str, float, str], ...] = (
    ("human_arm_2dof", "abs_work", 12.0, "energy consumption, 2-link model (MATLAB)"),
    ("curtain_wall_6dof", "peak_power", 48.4, "peak of the energy-consumption curve (ADAMS)"),
)

PHASE_COLOURS = {"A": "rgba(46, 139, 87, 0.10)", "B": "rgba(255, 165, 0, 0.14)"}
PHASE_COLOURS["C"] = "rgba(70, 130, 180, 0.10)"


@dataclass(frozen=True)
class DemoCase:
    """One planned comparison shown in the report."""

    robot: str
    objective: str
    duration: float
    payload: float


DEFAULT_CASES = (
    DemoCase("human_arm_2dof", "abs_work", 1.0, 12.0),
    DemoCase("curtain_wall_6dof", "peak_power", 1.0, 4.0),
)


def _figure_html(fig: Any) -> str:
    return str(fig.to_html(full_html=False, include_plotlyjs=False))


def phase_shapes(t_ab: float, t_bc: float, t_end: float) -> list[dict[str, Any]]:
    """Plotly layout shapes shading phases A, B and C over time [s]."""
    spans = (("A", 0.0, t_ab), ("B", t_ab, t_bc), ("C", t_bc, t_end))
    shapes = []
    for label, x0, x1 in spans:
        if not (math.isfinite(x0) and math.isfinite(x1)) or x1 <= x0:
            continue
        shapes.append(
            {
                "type": "rect",
                "xref": "x",
                "yref": "paper",
                "x0": x0,
                "x1": x1,
                "y0": 0,
                "y1": 1,
                "fillcolor": PHASE_COLOURS[label],
                "line": {"width": 0},
                "layer": "below",
                "label": {"text": label, "textposition": "top center"},
            }
        )
    return shapes


def figure_classical_profiles(duration: float = 1.0) -> Any:
    """Fig. 5: normalised velocity of the classical profiles for a unit stroke."""
    import plotly.graph_objects as go

    from app.planning.profiles import CLASSICAL_PROFILES

    fig = go.Figure()
    for name, make in CLASSICAL_PROFILES.items():
        tr = make(np.zeros(1), np.ones(1), duration, n_samples=501)
        fig.add_trace(go.Scatter(x=tr.t / duration, y=tr.qd[:, 0] * duration, name=name))
    fig.update_layout(
        title="Fig. 5 - velocity profiles of the classical curves (unit stroke, unit time)",
        xaxis_title="normalised time t/T",
        yaxis_title="normalised velocity q̇·T/Δq",
        height=420,
    )
    return fig


def figure_quintic(duration: float = 1.0, stroke_deg: float = 150.0) -> Any:
    """Fig. 6: the quintic polynomial trajectory of the elbow's curl."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    from app.planning.profiles import quintic

    tr = quintic(np.zeros(1), np.radians([stroke_deg]), duration, n_samples=501)
    fig = make_subplots(rows=1, cols=3, subplot_titles=("position", "velocity", "acceleration"))
    for col, (y, unit) in enumerate(
        ((tr.q, "deg"), (tr.qd, "deg/s"), (tr.qdd, "deg/s²")), start=1
    ):
        fig.add_trace(go.Scatter(x=tr.t, y=np.degrees(y[:, 0]), showlegend=False), row=1, col=col)
        fig.update_yaxes(title_text=unit, row=1, col=col)
        fig.update_xaxes(title_text="t [s]", row=1, col=col)
    fig.update_layout(
        title=f"Fig. 6 - quintic trajectory, 0 -> {stroke_deg:g} deg in {duration:g} s",
        height=360,
    )
    return fig


def figure_comparison(result: Any, title: str) -> Any:
    """Fig. 7: standard vs optimised elbow motion, power and cumulative energy, phases shaded."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    arrays = result.arrays()
    t = arrays["t"]
    e = result.elbow_joint
    panels = (
        ("elbow angle [deg]", "q", True),
        ("elbow velocity [deg/s]", "qd", True),
        ("elbow acceleration [deg/s²]", "qdd", True),
        ("total |power| Σ|τ·ω| [W]", "power", False),
        ("cumulative |work| [J]", "energy", False),
    )
    fig = make_subplots(rows=len(panels), cols=1, shared_xaxes=True, vertical_spacing=0.03)
    styles = {"standard": {"color": "#555", "dash": "dash"}, "optimized": {"color": "#d62728"}}
    for row, (label, key, per_joint) in enumerate(panels, start=1):
        for which in ("standard", "optimized"):
            y = arrays[f"{which}_{key}"]
            y = np.degrees(y[:, e]) if per_joint else y
            fig.add_trace(
                go.Scatter(
                    x=t,
                    y=y,
                    name=which,
                    line=styles[which],
                    showlegend=row == 1,
                    legendgroup=which,
                ),
                row=row,
                col=1,
            )
        fig.update_yaxes(title_text=label, row=row, col=1)
    t_ab, t_bc = result.phase_times("optimized")
    for shape in phase_shapes(t_ab, t_bc, float(t[-1])):
        fig.add_shape(**{k: v for k, v in shape.items() if k not in ("xref", "yref")},
                      xref="x", yref="paper")
    fig.update_xaxes(title_text="t [s]", row=len(panels), col=1)
    fig.update_layout(title=title, height=1100)
    return fig


def _improvement_rows(results: dict[str, Any]) -> list[dict[str, Any]]:
    rows = []
    for robot, metric, claim, what in PAPER_CLAIMS:
        res = results.get(robot)
        if res is None:
            continue
        measured = res.improvement_pct[metric]
        rows.append(
            {
                "robot": robot,
                "metric": metric,
                "paper_claim_pct": claim,
                "paper_measure": what,
                "measured_pct": measured,
                "conditions": (
                    f"{res.duration:g} s, payload {res.payload_mass:g} kg, PSO objective "
                    f"{res.objective}, elbow velocity peak at {res.optimized.peak_velocity_angle_deg:.1f}"
                    f" deg, seed {res.optimizer.seed}"
                ),
            }
        )
    return rows


def _table(headers: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _metrics_table(res: Any) -> str:
    names = ["tau_sq", "abs_work", "pos_work", "electrical_energy", "peak_power"]
    std, opt, imp = res.standard.metrics.to_dict(), res.optimized.metrics.to_dict(), res.improvement_pct
    rows = [
        [n, f"{std[n]:.4g}", f"{opt[n]:.4g}", f"{imp[n]:+.1f} %" if math.isfinite(imp[n]) else "-"]
        for n in names
    ]
    rows.append(
        [
            "peak_torque (per joint) [Nm]",
            ", ".join(f"{v:.1f}" for v in std["peak_torque"]),
            ", ".join(f"{v:.1f}" for v in opt["peak_torque"]),
            "",
        ]
    )
    rows.append(["floor: delta_potential [J]", f"{res.floors.delta_potential:.4g}", "", ""])
    rows.append(["floor: min_peak_power [W]", f"{res.floors.min_peak_power:.4g}", "", ""])
    return _table(["metric", "standard quintic", "bio-optimised", "saving"], rows)


_CSS = """
body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:4px 10px;
text-align:right}th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}
.note{color:#555;font-size:0.95em}
"""


def write_demo_report(
    out_dir: Path,
    *,
    seed: int = 0,
    cases: tuple[DemoCase, ...] = DEFAULT_CASES,
    particles: int = 40,
    iterations: int = 100,
    progress: ProgressCallback | None = None,
) -> Path:
    """Plan every demo case and write the report folder; returns the path of index.html."""
    import plotly.offline

    from app.planning.planner import plan
    from app.planning.robots import load_robot

    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "plotly.min.js").write_text(plotly.offline.get_plotlyjs(), encoding="utf-8")
    results: dict[str, Any] = {}
    sections: list[str] = []
    for i, case in enumerate(cases):
        if progress is not None:
            progress(i / len(cases), f"planning {case.robot}")
        robot = load_robot(case.robot, payload=case.payload)
        res = plan(
            robot,
            duration=case.duration,
            objective=case.objective,
            seed=seed,
            particles=particles,
            iterations=iterations,
        )
        results[case.robot] = res
        title = (
            f"Fig. 7 - {case.robot}: standard vs bio-optimised ({case.duration:g} s, "
            f"{case.payload:g} kg, objective {case.objective})"
        )
        sections.append(
            f"<h2>{html.escape(case.robot)}</h2>"
            + _metrics_table(res)
            + _figure_html(figure_comparison(res, title))
        )
    claims = _improvement_rows(results)
    claim_table = _table(
        ["robot", "metric", "paper", "measured", "conditions"],
        [
            [
                c["robot"],
                f"{c['metric']} ({c['paper_measure']})",
                f"{c['paper_claim_pct']:.1f} %",
                f"{c['measured_pct']:.1f} %",
                c["conditions"],
            ]
            for c in claims
        ],
    )
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>BioPlan demo report</title>
<script src="plotly.min.js"></script><style>{_CSS}</style></head><body>
<h1>BioPlan demo report</h1>
<p class="note">Reproduces the figures of Liu et al., "Trajectory Planning of a Curtain Wall
Installation Robot Based on Biomimetic Mechanisms", with BioPlan's own dynamics and optimiser.
Savings are 100·(standard − optimised)/standard; negative means the bio-inspired plan costs more.
They depend on the metric, the duration and the payload: see <code>bioplan sweep</code>.</p>
<h2>Paper claims vs measured</h2>{claim_table}
{_figure_html(figure_classical_profiles())}
{_figure_html(figure_quintic())}
{"".join(sections)}
</body></html>"""
    index = out_dir / "index.html"
    index.write_text(page, encoding="utf-8")
    summary = {
        "claims": claims,
        "results": {name: res.to_dict() for name, res in results.items()},
    }
    (out_dir / "results.json").write_text(
        json.dumps(summary, indent=2, default=float), encoding="utf-8"
    )
    if progress is not None:
        progress(1.0, "report written")
    return index
