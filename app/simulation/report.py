"""The demo report: the paper's figures and numbers, reproduced, simulated and measured.

``write_demo_report`` writes a folder with ``index.html`` (interactive Plotly figures, plotly.js
copied once from the installed ``plotly`` package, so the report opens offline) and
``results.json`` (every number shown). Figures follow the paper:

* Fig. 5: velocity profiles of the classical point-to-point curves (normalised).
* Fig. 6: the quintic polynomial trajectory (position, velocity, acceleration).
* Fig. 7: standard vs bio-optimised planned trajectories with power and cumulative-energy
  curves, the A/B/C phases shaded, for both built-in robots.
* Fig. 10 (the paper validated in ADAMS; here MuJoCo): joint power, total power, electrical
  power and cumulative energy over time *from the tracking simulation*, standard vs optimised,
  phases shaded.
* Heat maps of a small sweep (durations x payloads on the 6-DOF robot): where the bio-inspired
  plan saves, makes no difference or costs more.

A table puts the savings measured in the simulation beside the paper's claims (12 % energy on
the 2-link arm, 48.4 % lower peak of the energy-consumption curve on the 6-DOF robot), with the
conditions.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from app.progress import ProgressFn, report, within

if TYPE_CHECKING:
    from app.simulation.sweep import SimulationResult, SweepResult


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


def _shade_phases(fig: Any, t_ab: float, t_bc: float, t_end: float) -> None:
    """Shade phases A/B/C on every subplot of ``fig`` (times [s])."""
    for shape in phase_shapes(t_ab, t_bc, t_end):
        fig.add_shape(
            **{k: v for k, v in shape.items() if k not in ("xref", "yref")},
            xref="x",
            yref="paper",
        )


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
    panels = ((tr.q, "deg"), (tr.qd, "deg/s"), (tr.qdd, "deg/s²"))
    for col, (y, unit) in enumerate(panels, start=1):
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
    _shade_phases(fig, t_ab, t_bc, float(t[-1]))
    fig.update_xaxes(title_text="t [s]", row=len(panels), col=1)
    fig.update_layout(title=title, height=1100)
    return fig


_STYLES = {"standard": {"color": "#555", "dash": "dash"}, "optimized": {"color": "#d62728"}}


def figure_simulation(sim: SimulationResult, title: str) -> Any:
    """Fig. 10 style, from the MuJoCo simulation: power and cumulative energy over time.

    Panels: power of the elbow and shoulder joints (tau * qd [W]), total |power| (the
    "energy-consumption curve" whose peak the paper reports), electrical bus power, and the
    cumulative |work| and electrical energy [J]; standard (dashed) vs optimised (solid). The
    optimised trajectory's phases are shaded; dotted lines mark the standard's phase bounds.
    """
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    c = sim.conditions
    e = sim.plan.elbow_joint
    names = list(c["joint_names"])
    shoulder = names.index(c["shoulder_joint"])
    panels: list[tuple[str, Callable[[Any], Any]]] = [
        (f"elbow ({names[e]}) power [W]", lambda r: r.joint_power[:, e]),
        (f"shoulder ({names[shoulder]}) power [W]", lambda r: r.joint_power[:, shoulder]),
        ("total |power| Σ|τ·ω| [W]", lambda r: r.power),
        ("electrical bus power [W]", lambda r: r.electrical_power),
        ("cumulative |work| [J]", lambda r: r.energy),
        ("cumulative electrical energy [J]", lambda r: r.electrical_energy),
    ]
    fig = make_subplots(rows=len(panels), cols=1, shared_xaxes=True, vertical_spacing=0.025)
    for row, (label, get) in enumerate(panels, start=1):
        for which, run in (("standard", sim.standard), ("optimized", sim.optimized)):
            fig.add_trace(
                go.Scatter(
                    x=run.t,
                    y=get(run),
                    name=which,
                    line=_STYLES[which],
                    showlegend=row == 1,
                    legendgroup=which,
                ),
                row=row,
                col=1,
            )
        fig.update_yaxes(title_text=label, row=row, col=1)
    for which, run in (("standard", sim.standard), ("optimized", sim.optimized)):
        k = int(np.argmax(run.power))
        fig.add_trace(
            go.Scatter(
                x=[run.t[k]],
                y=[run.power[k]],
                mode="markers+text",
                marker={"color": _STYLES[which]["color"], "size": 9},
                text=[f"peak {run.power[k]:.0f} W"],
                textposition="top center",
                showlegend=False,
            ),
            row=3,
            col=1,
        )
    t_end = float(sim.optimized.t[-1])
    _shade_phases(fig, *sim.phase_times("optimized"), t_end)
    for t_b in sim.phase_times("standard"):
        if math.isfinite(t_b):
            fig.add_vline(x=t_b, line={"color": "#555", "dash": "dot", "width": 1})
    fig.update_xaxes(title_text="t [s]", row=len(panels), col=1)
    fig.update_layout(title=title, height=1250)
    return fig


def figure_sweep(sweep: SweepResult, objective: str, metrics: Sequence[str]) -> Any:
    """Heat maps of the simulated change [%] per cell (rows: durations, columns: payloads)."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    from app.simulation.sweep import classify

    fig = make_subplots(
        rows=1, cols=len(metrics), subplot_titles=[f"{m} change [%]" for m in metrics]
    )
    x = [f"{p:g} kg" for p in sweep.payloads]
    y = [f"{d:g} s" for d in sweep.durations]
    for col, metric in enumerate(metrics, start=1):
        z = sweep.table(objective, metric)
        text = []
        for d in sweep.durations:
            row = []
            for p in sweep.payloads:
                cell = sweep.cell(d, p, objective)
                if cell.status != "ok":
                    row.append(cell.status)
                    continue
                v = cell.change_pct[metric]
                floor = "<br>(on floor)" if cell.at_floor else ""
                row.append(f"{v:+.1f}%<br>{classify(v)}{floor}")
            text.append(row)
        finite = z[np.isfinite(z)]
        span = float(max(np.abs(finite).max(), 1.0)) if finite.size else 1.0
        fig.add_trace(
            go.Heatmap(
                z=[[float(v) if math.isfinite(v) else None for v in row] for row in z],
                x=x,
                y=y,
                text=text,
                texttemplate="%{text}",
                colorscale="RdBu",
                zmid=0.0,
                zmin=-span,
                zmax=span,
                showscale=col == len(metrics),
                colorbar={"title": "saving [%]"},
                hovertemplate="%{y}, %{x}: %{text}<extra></extra>",
            ),
            row=1,
            col=col,
        )
        fig.update_xaxes(title_text="payload", row=1, col=col)
        fig.update_yaxes(title_text="duration", row=1, col=col)
    c = sweep.conditions
    fig.update_layout(
        title=(
            f"Sweep on {sweep.robot}, PSO objective {objective} ({c['particles']} particles x "
            f"{c['iterations']} iterations per cell, seed {c['seed']}); blue = the bio-inspired "
            "plan saves, red = it costs more"
        ),
        height=460,
    )
    return fig


def _claim_rows(results: dict[str, SimulationResult]) -> list[dict[str, Any]]:
    """The paper's claims beside the savings measured in the simulation."""
    rows = []
    for robot, metric, claim, what in PAPER_CLAIMS:
        sim = results.get(robot)
        if sim is None:
            continue
        c = sim.conditions
        tracking = max(
            float(sim.standard.tracking_max.max()), float(sim.optimized.tracking_max.max())
        )
        rows.append(
            {
                "robot": robot,
                "metric": metric,
                "paper_claim_pct": claim,
                "paper_measure": what,
                "measured_pct": float(sim.improvement_pct[metric]),
                "planned_pct": float(sim.plan.improvement_pct[metric]),
                "conditions": (
                    f"{c['duration']:g} s, payload {c['payload']:g} kg, PSO objective "
                    f"{c['objective']} ({c['particles']}x{c['iterations']}, seed {c['seed']}), "
                    f"elbow velocity peak at {c['peak_velocity_angle_deg']:.1f} deg; MuJoCo "
                    f"{1000 * c['timestep']:g} ms {c['integrator']}, computed-torque tracking "
                    f"(max error {math.degrees(tracking):.3f} deg)"
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


def _pct(v: float) -> str:
    return f"{v:+.1f} %" if math.isfinite(v) else "-"


def _metrics_table(sim: SimulationResult) -> str:
    """Simulated metrics of both trajectories, the change, and the planner's change."""
    from app.simulation.sweep import METRICS, _scalar_metrics

    std = _scalar_metrics(sim.standard.metrics.to_dict())
    opt = _scalar_metrics(sim.optimized.metrics.to_dict())
    pstd = _scalar_metrics(sim.plan.standard.metrics.to_dict())
    popt = _scalar_metrics(sim.plan.optimized.metrics.to_dict())
    rows = []
    for n in METRICS:
        label = n if n != "peak_torque" else "peak_torque (largest joint) [Nm]"
        change = 100 * (std[n] - opt[n]) / std[n] if std[n] else math.nan
        planned = 100 * (pstd[n] - popt[n]) / pstd[n] if pstd[n] else math.nan
        rows.append([label, f"{std[n]:.4g}", f"{opt[n]:.4g}", _pct(change), _pct(planned)])
    rows.append(["floor: delta_potential [J]", f"{sim.floors.delta_potential:.4g}", "", "", ""])
    rows.append(["floor: min_peak_power [W]", f"{sim.floors.min_peak_power:.4g}", "", "", ""])
    return _table(
        ["metric (simulated)", "standard quintic", "bio-optimised", "saving", "planned saving"],
        rows,
    )


def _peaks_table(sim: SimulationResult) -> str:
    rows = []
    for label in ("standard", "optimized"):
        p = sim.peaks(label)
        for name, peak in [("total |power|", p["power"])] + [
            (f"torque {q['joint']}", q) for q in p["torque"] if abs(q["value"]) > 1e-9
        ]:
            rows.append(
                [
                    label,
                    name,
                    f"{abs(peak['value']):.4g}",
                    f"{peak['time']:.3f}",
                    f"{peak['elbow_deg']:.1f}",
                    peak["phase"],
                ]
            )
    return _table(["trajectory", "peak of", "value", "t [s]", "elbow [deg]", "phase"], rows)


_CSS = """
body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:4px 10px;
text-align:right}th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}
.note{color:#555;font-size:0.95em}
"""

#: The demo's small sweep: curtain_wall_6dof, 4 durations x 4 payloads.
DEMO_SWEEP_DURATIONS = (0.75, 1.0, 1.5, 2.0)
DEMO_SWEEP_PAYLOADS = (0.0, 4.0, 10.0, 20.0)
DEMO_SWEEP_OBJECTIVES = ("abs_work", "peak_power")
DEMO_SWEEP_METRICS = ("abs_work", "electrical_energy", "peak_power")


def write_demo_report(
    out_dir: Path,
    *,
    seed: int = 0,
    cases: tuple[DemoCase, ...] = DEFAULT_CASES,
    particles: int = 40,
    iterations: int = 100,
    sweep_robot: str | None = "curtain_wall_6dof",
    sweep_durations: Sequence[float] = DEMO_SWEEP_DURATIONS,
    sweep_payloads: Sequence[float] = DEMO_SWEEP_PAYLOADS,
    sweep_objectives: Sequence[str] = DEMO_SWEEP_OBJECTIVES,
    sweep_workers: int | None = None,
    progress: ProgressFn | None = None,
) -> Path:
    """Plan and simulate every demo case, run a small sweep, and write the report folder.

    Args:
        out_dir: the report folder (created).
        seed: PSO seed for every plan.
        cases: the planned + simulated comparisons.
        particles: PSO swarm size for the cases.
        iterations: PSO iterations for the cases.
        sweep_robot: robot of the sweep, or None for no sweep.
        sweep_durations: sweep durations [s].
        sweep_payloads: sweep payloads [kg].
        sweep_objectives: planner objectives of the sweep.
        sweep_workers: sweep processes (default: up to 2).
        progress: called with a ``Progress`` (stages ``report``, ``pso``, ``simulate``, ``sweep``).

    Returns:
        The path of ``index.html``.
    """
    import plotly.offline

    from app.planning.robots import load_robot
    from app.simulation.sweep import run_sweep, simulate_comparison

    out_dir.mkdir(parents=True, exist_ok=True)
    cases_share = 0.45 if sweep_robot else 0.95
    results: dict[str, SimulationResult] = {}
    sections: list[str] = []
    for i, case in enumerate(cases):
        report(
            progress,
            "report",
            i,
            len(cases),
            fraction=cases_share * i / len(cases),
            message=f"planning and simulating {case.robot}",
        )
        robot = load_robot(case.robot, payload=case.payload)
        sim = simulate_comparison(
            robot,
            duration=case.duration,
            objective=case.objective,
            seed=seed,
            particles=particles,
            iterations=iterations,
        )
        results[case.robot] = sim
        what = (
            f"{case.robot}: standard vs bio-optimised ({case.duration:g} s, {case.payload:g} kg, "
            f"objective {case.objective})"
        )
        warnings = "".join(f"<li>{html.escape(w)}</li>" for w in sim.warnings)
        sections.append(
            f"<h2>{html.escape(case.robot)}</h2>"
            + _metrics_table(sim)
            + _peaks_table(sim)
            + (f"<ul class='note'>{warnings}</ul>" if warnings else "")
            + _figure_html(figure_comparison(sim.plan, f"Fig. 7 - planned, {what}"))
            + _figure_html(figure_simulation(sim, f"Fig. 10 - MuJoCo simulation, {what}"))
        )

    sweep = None
    sweep_html = ""
    if sweep_robot:
        sweep = run_sweep(
            robot=load_robot(sweep_robot),
            durations=sweep_durations,
            payloads=sweep_payloads,
            objectives=sweep_objectives,
            seed=seed,
            workers=sweep_workers,
            progress=within(progress, cases_share, 0.95),
        )
        parts = [
            f"<h2>Where the bio-inspired plan wins: sweep on {html.escape(sweep.robot)}</h2>",
            "<p class='note'>Each cell plans both trajectories and simulates them; the number is "
            "the change measured in the simulation, 100·(standard − optimised)/standard. "
            "'no difference' means |change| &lt; 1 %; '(on floor)' marks cells where the "
            "standard quintic's |work| is already within 1 % of the potential-energy rise, so "
            "no trajectory can save work there. Infeasible cells: the planner found no "
            "trajectory within the joint limits.</p>",
        ]
        for objective in sweep.objectives:
            parts.append(_figure_html(figure_sweep(sweep, objective, DEMO_SWEEP_METRICS)))
            counts = ", ".join(
                f"{m}: "
                + ", ".join(f"{k} {v}" for k, v in sorted(sweep.counts(objective, m).items()))
                for m in DEMO_SWEEP_METRICS
            )
            parts.append(f"<p class='note'>objective {html.escape(objective)}: {counts}</p>")
        sweep_html = "".join(parts)

    report(progress, "report", 0, 1, fraction=0.96, message="writing the report")
    (out_dir / "plotly.min.js").write_text(plotly.offline.get_plotlyjs(), encoding="utf-8")
    claims = _claim_rows(results)
    claim_table = _table(
        ["robot", "metric", "paper", "measured (simulated)", "planned", "conditions"],
        [
            [
                c["robot"],
                f"{c['metric']} ({c['paper_measure']})",
                f"{c['paper_claim_pct']:.1f} %",
                _pct(c["measured_pct"]),
                _pct(c["planned_pct"]),
                c["conditions"],
            ]
            for c in claims
        ],
    )
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>BioPlan demo report</title>
<script src="plotly.min.js"></script><style>{_CSS}</style></head><body>
<h1>BioPlan demo report</h1>
<p class="note">Reproduces the figures of Liu et al., "Trajectory Planning of a Curtain Wall
Installation Robot Based on Biomimetic Mechanisms", with BioPlan's own dynamics and optimiser, and
validates them in MuJoCo (the paper used ADAMS). Savings are 100·(standard − optimised)/standard;
negative means the bio-inspired plan costs more. They depend on the metric, the duration and the
payload: see the sweep below and <code>bioplan sweep</code>.</p>
<h2>Paper claims vs measured</h2>{claim_table}
{_figure_html(figure_classical_profiles())}
{_figure_html(figure_quintic())}
{"".join(sections)}
{sweep_html}
</body></html>"""
    index = out_dir / "index.html"
    summary = {
        "claims": claims,
        "results": {name: sim.to_dict() for name, sim in results.items()},
        "sweep": sweep.to_dict() if sweep is not None else None,
    }
    # Write to temporary names first, then rename: no half-written report is left behind.
    tmp_json = out_dir / ".results.json.tmp"
    tmp_index = out_dir / ".index.html.tmp"
    tmp_json.write_text(json.dumps(summary, indent=2, allow_nan=False), encoding="utf-8")
    tmp_index.write_text(page, encoding="utf-8")
    tmp_json.replace(out_dir / "results.json")
    tmp_index.replace(index)
    report(progress, "done", 1, 1, message="report written")
    return index
