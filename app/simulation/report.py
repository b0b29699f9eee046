"""The demo report: the paper's figures and numbers, reproduced, simulated and measured.

``write_demo_report`` writes a folder with ``index.html`` (interactive Plotly figures, plotly.js
copied once from the installed ``plotly`` package, so the report opens offline) and
``results.json`` (every number shown). Figures follow the paper:

* Fig. 5: velocity profiles of the classical point-to-point curves (normalised); minimum-jerk is
  the same curve as the quintic, drawn as a band under it and said so.
* Fig. 6: the quintic polynomial trajectory (position, velocity, acceleration).
* Fig. 7: every method's planned elbow motion with power and cumulative-energy curves, the A/B/C
  phases shaded, for both built-in robots.
* Fig. 10 (the paper validated in ADAMS; here MuJoCo): joint power, total power, electrical
  power and cumulative energy over time *from the tracking simulation*, every method, each power
  peak labelled, phases shaded.
* Heat maps of a small sweep (durations x payloads on the 6-DOF robot): where the paper's plan
  saves, makes no difference or costs more, and where its verdict depends on the PSO's seed.

A table puts the paper's claims (12 % energy on the 2-link arm, 48.4 % lower peak of the
energy-consumption curve on the 6-DOF robot) beside what each method achieves in the
simulation — the paper's method, the human-like optimum, the physical bound and the industrial
jerk-limited profile — with each one's share of the achievable saving and the conditions.
Metric names, units, method and phase colours come from ``app.names``.
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
from numpy.typing import NDArray

from app import names
from app.progress import ProgressFn, report, within

if TYPE_CHECKING:
    from app.planning.planner import PlanResult
    from app.simulation.comparison import SimulationResult
    from app.simulation.sweep import SweepResult
    from app.simulation.tracking import TrackingResult


#: Paper claims: (robot, metric, claimed saving [%], what the paper measured).
PAPER_CLAIMS: tuple[tuple[str, str, float, str], ...] = (
    ("human_arm_2dof", "abs_work", 12.0, "energy consumption, 2-link model (MATLAB)"),
    ("curtain_wall_6dof", "peak_power", 48.4, "peak of the energy-consumption curve (ADAMS)"),
)


def _rgba(hex_colour: str, alpha: float) -> str:
    """CSS rgba() of a ``#rrggbb`` colour."""
    r, g, b = (int(hex_colour[i : i + 2], 16) for i in (1, 3, 5))
    return f"rgba({r}, {g}, {b}, {alpha})"


#: Phase shading: the phases' colours from ``app.names`` (the same in every plot and the viewer).
PHASE_COLOURS = {p.name: _rgba(p.colour, 0.12) for p in names.PHASES}
#: Room for axis titles, subplot titles and peak labels.
_MARGIN = {"l": 90, "r": 40, "t": 90, "b": 70}


def _style(method: str) -> dict[str, str]:
    """Line style of a method: its colour from ``app.names``; the quintic dashed."""
    style: dict[str, str] = {"color": names.METHODS[method].colour}
    if method == "quintic":
        style["dash"] = "dash"
    return style


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
    """Fig. 5: normalised velocity of the classical profiles for a unit stroke.

    The minimum-jerk and quintic rest-to-rest profiles are the same polynomial, so minimum-jerk
    is drawn as a wide pale band under the quintic, and the figure says so.
    """
    import plotly.graph_objects as go

    from app.planning.profiles import CLASSICAL_PROFILES

    fig = go.Figure()
    for name, make in CLASSICAL_PROFILES.items():
        tr = make(np.zeros(1), np.ones(1), duration, n_samples=501)
        line: dict[str, Any] = {}
        if name == "minimum_jerk":
            line = {"width": 9, "color": "rgba(120, 120, 120, 0.35)"}
        fig.add_trace(go.Scatter(x=tr.t / duration, y=tr.qd[:, 0] * duration, name=name, line=line))
    fig.add_annotation(
        text="minimum-jerk (wide grey band) is the same curve as the quintic",
        xref="paper",
        yref="paper",
        x=0.5,
        y=1.0,
        yanchor="bottom",
        showarrow=False,
    )
    fig.update_layout(
        title="Fig. 5 - velocity profiles of the classical curves (unit stroke, unit time)",
        xaxis_title="normalised time t/T [-]",
        yaxis_title="normalised velocity q̇·T/Δq [-]",
        height=460,
        margin=_MARGIN,
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
        fig.update_yaxes(title_text=f"[{unit}]", row=1, col=col)
        fig.update_xaxes(title_text="t [s]", row=1, col=col)
    fig.update_layout(
        title=f"Fig. 6 - quintic trajectory, 0 -> {stroke_deg:g} deg in {duration:g} s",
        height=380,
        margin=_MARGIN,
    )
    return fig


def figure_comparison(result: PlanResult, title: str) -> Any:
    """Fig. 7: every planned method's elbow motion, power and cumulative energy, phases shaded.

    Phases are shaded for the paper's trajectory (the quintic's when the paper did not run).
    """
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
    for row, (label, key, per_joint) in enumerate(panels, start=1):
        for method in result.methods:
            y = arrays[f"{method}_{key}"]
            y = np.degrees(y[:, e]) if per_joint else y
            _add_method_line(fig, method, t, y, row)
        fig.update_yaxes(title_text=label, row=row, col=1)
    shaded = "optimized" if "paper" in result.methods else "standard"
    t_ab, t_bc = result.phase_times(shaded)
    _shade_phases(fig, t_ab, t_bc, float(t[-1]))
    fig.update_xaxes(title_text="t [s]", row=len(panels), col=1)
    fig.update_layout(title=title, height=1150, margin=_MARGIN)
    return fig


def _add_method_line(
    fig: Any, method: str, x: NDArray[np.float64], y: NDArray[np.float64], row: int
) -> None:
    """One method's curve ``y`` over ``x`` [s] in panel ``row`` (legend entry on the first row)."""
    import plotly.graph_objects as go

    fig.add_trace(
        go.Scatter(
            x=x,
            y=y,
            name=names.METHODS[method].label,
            line=_style(method),
            showlegend=row == 1,
            legendgroup=method,
        ),
        row=row,
        col=1,
    )


def _simulation_panels(
    sim: SimulationResult,
) -> list[tuple[str, Callable[[TrackingResult], NDArray[np.float64]]]]:
    c = sim.conditions
    e = sim.plan.elbow_joint
    joint_names = list(c["joint_names"])
    shoulder = joint_names.index(c["shoulder_joint"])
    return [
        (f"elbow ({joint_names[e]}) power [W]", lambda r: r.joint_power[:, e]),
        (f"shoulder ({joint_names[shoulder]}) power [W]", lambda r: r.joint_power[:, shoulder]),
        ("total |power| Σ|τ·ω| [W]", lambda r: r.power),
        ("electrical bus power [W]", lambda r: r.electrical_power),
        ("cumulative |work| [J]", lambda r: r.energy),
        ("cumulative electrical energy [J]", lambda r: r.electrical_energy),
    ]


def figure_simulation(sim: SimulationResult, title: str) -> Any:
    """Fig. 10 style, from the MuJoCo simulation: power and cumulative energy over time.

    Panels: power of the elbow and shoulder joints (tau * qd [W]), total |power| (the
    "energy-consumption curve" whose peak the paper reports), electrical bus power, and the
    cumulative |work| and electrical energy [J]; one line per simulated method (the quintic
    dashed), its power peak labelled. The paper's trajectory's phases are shaded (the
    quintic's without it); dotted lines mark the quintic's phase bounds.
    """
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    panels = _simulation_panels(sim)
    fig = make_subplots(rows=len(panels), cols=1, shared_xaxes=True, vertical_spacing=0.025)
    for row, (label, get) in enumerate(panels, start=1):
        for method, run in sim.runs.items():
            _add_method_line(fig, method, run.t, get(run), row)
        fig.update_yaxes(title_text=label, row=row, col=1)
    for method, run in sim.runs.items():
        k = int(np.argmax(run.power))
        fig.add_trace(
            go.Scatter(
                x=[run.t[k]],
                y=[run.power[k]],
                mode="markers+text",
                marker={"color": names.METHODS[method].colour, "size": 9},
                text=[f"{run.power[k]:.0f} W"],
                textposition="top center",
                cliponaxis=False,
                showlegend=False,
            ),
            row=3,
            col=1,
        )
    t_end = float(sim.standard.t[-1])
    shaded = "optimized" if sim.optimized is not None else "standard"
    _shade_phases(fig, *sim.phase_times(shaded), t_end)
    for t_b in sim.phase_times("standard"):
        if math.isfinite(t_b):
            fig.add_vline(x=t_b, line={"color": "#555", "dash": "dot", "width": 1})
    fig.update_xaxes(title_text="t [s]", row=len(panels), col=1)
    fig.update_layout(title=title, height=1300, margin=_MARGIN)
    return fig


def figure_sweep(sweep: SweepResult, objective: str, metrics: Sequence[str]) -> Any:
    """Heat maps of the simulated change [%] per cell (rows: durations, columns: payloads)."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    from app.simulation.sweep import classify

    fig = make_subplots(
        rows=1,
        cols=len(metrics),
        subplot_titles=[f"{names.METRICS[m].label} ({m}) change [%]" for m in metrics],
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
                if cell.status != "ok" or cell.paper_infeasible:
                    row.append(cell.classification[metric])
                    continue
                v = cell.change_pct[metric]
                floor = "<br>(on floor)" if cell.at_floor else ""
                unsure = "<br>(? the PSO seeds disagree)" if metric in cell.unconverged else ""
                row.append(f"{v:+.1f}%<br>{classify(v)}{floor}{unsure}")
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
        fig.update_xaxes(title_text="payload [kg]", row=1, col=col)
        fig.update_yaxes(title_text="duration [s]", row=1, col=col)
    c = sweep.conditions
    fig.update_layout(
        title=(
            f"Sweep on {sweep.robot}, PSO objective {objective} ({c['particles']} particles x "
            f"{c['iterations']} iterations per cell, seed {c['seed']}); blue = the bio-inspired "
            "plan saves, red = it costs more"
        ),
        height=500,
        margin=_MARGIN,
    )
    return fig


def _claim_rows(results: dict[str, SimulationResult]) -> list[dict[str, Any]]:
    """The paper's claims beside the savings measured in the simulation, per method."""
    rows = []
    for robot, metric, claim, what in PAPER_CLAIMS:
        sim = results.get(robot)
        if sim is None:
            continue
        c = sim.conditions
        tracking = max(float(run.tracking_max.max()) for run in sim.runs.values())
        by_method = sim.to_dict()["methods"]
        rows.append(
            {
                "robot": robot,
                "metric": metric,
                "paper_claim_pct": claim,
                "paper_measure": what,
                "measured_pct": float(sim.improvement_pct[metric]),
                "planned_pct": float(sim.plan.improvement_pct[metric]),
                "methods_pct": {
                    name: d["improvement_pct"][metric]
                    for name, d in by_method.items()
                    if name != "quintic"
                },
                "share_of_achievable_pct": sim.to_dict()["share_of_achievable_pct"],
                "conditions": (
                    f"{c['duration']:g} s, payload {c['payload']:g} kg, objective "
                    f"{c['objective']} (PSO {c['particles']}x{c['iterations']}, seed {c['seed']}; "
                    f"human-like optimum with the {c['human_constraint']} constraint), paper's "
                    f"elbow velocity peak at {c['peak_velocity_angle_deg']:.1f} deg; MuJoCo "
                    f"{1000 * c['timestep']:g} ms {c['integrator']}, computed-torque tracking "
                    f"(max error {math.degrees(tracking):.3f} deg)"
                ),
            }
        )
    return rows


def _claims_table(claims: list[dict[str, Any]]) -> str:
    """'48.4 % claimed; paper method X %; human-like optimum Y %; bound Z %', with conditions."""
    shown = [m for m in ("paper", "human_optimal", "bound", "jerk_limited")]
    headers = ["robot", "metric", "paper's claim"]
    headers += [f"{names.METHODS[m].label} (simulated)" for m in shown]
    headers += ["conditions"]
    rows = []
    for c in claims:
        cells = [
            c["robot"],
            f"{c['metric']} [{names.METRICS[c['metric']].unit}] ({c['paper_measure']})",
            f"{c['paper_claim_pct']:.1f} % lower",
        ]
        for m in shown:
            v = c["methods_pct"].get(m)
            share = c["share_of_achievable_pct"].get(m)
            text = "not run" if v is None else _pct(float(v))
            if v is not None and share is not None and m not in ("bound",):
                text += f" ({share:.0f} % of achievable)"
            cells.append(text)
        cells.append(c["conditions"])
        rows.append(cells)
    return _table(headers, rows)


def _table(headers: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _pct(v: float) -> str:
    return f"{v:+.1f} %" if math.isfinite(v) else "-"


def _metrics_table(sim: SimulationResult) -> str:
    """Simulated metrics of every method (with units), the saving against the quintic, floors."""
    from app.simulation.comparison import METRICS, pct_change, scalar_metrics

    values = {name: scalar_metrics(run.metrics) for name, run in sim.runs.items()}
    planned = {name: scalar_metrics(sim.plan.methods[name].evaluated.metrics) for name in sim.runs}
    rows = []
    for n in METRICS:
        info = names.METRICS[n]
        label = f"{n} [{info.unit}]" + (" (largest joint)" if info.per_joint else "")
        row = [label]
        for name in sim.runs:
            v = values[name][n]
            if name == "quintic":
                row.append(f"{v:.4g}")
                continue
            saving = pct_change(values["quintic"][n], v)
            plan_saving = pct_change(planned["quintic"][n], planned[name][n])
            row.append(f"{v:.4g} ({_pct(saving)}; planned {_pct(plan_saving)})")
        rows.append(row)
    fl = sim.floors
    floor_text = (
        f"floors: |ΔPE| {fl.abs_work:.4g} J (ΔPE {fl.delta_potential:+.4g} J), positive work "
        f"{fl.pos_work:.4g} J, peak power {fl.peak_power:.4g} W, electrical "
        f"{fl.electrical_energy:.4g} J (friction {fl.friction_energy:.4g} J)"
    )
    headers = ["metric (simulated)"] + [names.METHODS[n].label for n in sim.runs]
    return _table(headers, rows) + f"<p class='note'>{html.escape(floor_text)}; in brackets: "
    "the saving against the standard quintic, simulated and planned (positive = lower)</p>"


def _peaks_table(sim: SimulationResult) -> str:
    """Where each method's power and torque peaks fall (value with its unit, time, phase)."""
    rows = []
    for method in sim.runs:
        p = sim.peaks(method)
        for name, unit, peak in [("total |power|", "W", p["power"])] + [
            (f"torque {q['joint']}", "Nm", q) for q in p["torque"] if abs(q["value"]) > 1e-9
        ]:
            rows.append(
                [
                    names.METHODS[method].label,
                    name,
                    f"{abs(peak['value']):.4g} {unit}",
                    f"{peak['time']:.3f}",
                    f"{peak['elbow_deg']:.1f}",
                    peak["phase"],
                ]
            )
    return _table(["method", "peak of", "value", "t [s]", "elbow [deg]", "phase"], rows)


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


def _case_section(case: DemoCase, sim: SimulationResult) -> str:
    what = (
        f"{case.robot}: every method ({case.duration:g} s, {case.payload:g} kg, "
        f"objective {case.objective})"
    )
    warnings = "".join(f"<li>{html.escape(w)}</li>" for w in sim.warnings)
    return (
        f"<h2>{html.escape(case.robot)}</h2>"
        + _metrics_table(sim)
        + _peaks_table(sim)
        + (f"<ul class='note'>{warnings}</ul>" if warnings else "")
        + _figure_html(figure_comparison(sim.plan, f"Fig. 7 - planned, {what}"))
        + _figure_html(figure_simulation(sim, f"Fig. 10 - MuJoCo simulation, {what}"))
    )


def _sweep_section(sweep: SweepResult) -> str:
    parts = [
        f"<h2>Where the bio-inspired plan wins: sweep on {html.escape(sweep.robot)}</h2>",
        "<p class='note'>Each cell plans the trajectories and simulates them; the number is "
        "the change of the paper's method measured in the simulation, "
        "100·(standard − optimised)/standard. 'no difference' means |change| &lt; 1 %; '(on "
        "floor)' marks cells where the standard quintic's |work| is already within 1 % of "
        "|ΔPE|, so no trajectory can save work there; '(?)' marks verdicts that change when "
        "the PSO runs with a second seed. Infeasible cells: the planner found no trajectory "
        "within the joint limits. Every method's change per cell is in results.json.</p>",
    ]
    for objective in sweep.objectives:
        parts.append(_figure_html(figure_sweep(sweep, objective, DEMO_SWEEP_METRICS)))
        counts = ", ".join(
            f"{m}: " + ", ".join(f"{k} {v}" for k, v in sorted(sweep.counts(objective, m).items()))
            for m in DEMO_SWEEP_METRICS
        )
        parts.append(f"<p class='note'>objective {html.escape(objective)}: {counts}</p>")
    return "".join(parts)


def _page(claims: list[dict[str, Any]], sections: list[str], sweep_html: str) -> str:
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>BioPlan demo report</title>
<script src="plotly.min.js"></script><style>{_CSS}</style></head><body>
<h1>BioPlan demo report</h1>
<p class="note">Reproduces the figures of Liu et al., "Trajectory Planning of a Curtain Wall
Installation Robot Based on Biomimetic Mechanisms", with BioPlan's own dynamics and optimisers, and
validates them in MuJoCo (the paper used ADAMS). Beside the paper's method it shows the human-like
optimum (optimal control with the template's constraint), the physical bound (optimal control,
limits only) and an industrial jerk-limited profile. Savings are 100·(standard − method)/standard;
negative means the method costs more. They depend on the metric, the duration and the payload:
see the sweep below and <code>bioplan sweep</code>.</p>
<h2>Paper claims vs measured</h2>{_claims_table(claims)}
{_figure_html(figure_classical_profiles())}
{_figure_html(figure_quintic())}
{"".join(sections)}
{sweep_html}
</body></html>"""


def _write_atomically(out_dir: Path, page: str, summary: dict[str, Any]) -> Path:
    """Write to temporary names first, then rename: no half-written report is left behind."""
    import plotly.offline

    (out_dir / "plotly.min.js").write_text(plotly.offline.get_plotlyjs(), encoding="utf-8")
    tmp_json = out_dir / ".results.json.tmp"
    tmp_index = out_dir / ".index.html.tmp"
    tmp_json.write_text(json.dumps(summary, indent=2, allow_nan=False), encoding="utf-8")
    tmp_index.write_text(page, encoding="utf-8")
    tmp_json.replace(out_dir / "results.json")
    index = out_dir / "index.html"
    tmp_index.replace(index)
    return index


def _run_cases(
    cases: Sequence[DemoCase],
    *,
    seed: int,
    particles: int,
    iterations: int,
    methods: Sequence[str],
    progress: ProgressFn | None,
) -> dict[str, SimulationResult]:
    """Plan and simulate each demo case (PSO with ``particles`` x ``iterations``), by robot."""
    from app.planning.robots import load_robot
    from app.simulation.comparison import simulate_comparison

    results: dict[str, SimulationResult] = {}
    for i, case in enumerate(cases):
        report(
            progress, "report", i, len(cases), fraction=i / len(cases),
            message=f"planning and simulating {case.robot}",
        )  # fmt: skip
        results[case.robot] = simulate_comparison(
            load_robot(case.robot, payload=case.payload),
            duration=case.duration,
            objective=case.objective,
            seed=seed,
            particles=particles,
            iterations=iterations,
            methods=methods,
        )
    return results


def write_demo_report(
    out_dir: Path,
    *,
    seed: int = 0,
    cases: tuple[DemoCase, ...] = DEFAULT_CASES,
    particles: int = 40,
    iterations: int = 100,
    methods: Sequence[str] | None = None,
    sweep_robot: str | None = "curtain_wall_6dof",
    sweep_durations: Sequence[float] = DEMO_SWEEP_DURATIONS,
    sweep_payloads: Sequence[float] = DEMO_SWEEP_PAYLOADS,
    sweep_objectives: Sequence[str] = DEMO_SWEEP_OBJECTIVES,
    sweep_methods: Sequence[str] | None = None,
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
        methods: methods of the cases (None: all five).
        sweep_robot: robot of the sweep, or None for no sweep.
        sweep_durations: sweep durations [s].
        sweep_payloads: sweep payloads [kg].
        sweep_objectives: planner objectives of the sweep.
        sweep_methods: methods per sweep cell (None: all five).
        sweep_workers: sweep processes (default: up to 2).
        progress: called with a ``Progress`` (stages ``report``, ``pso``, ``optimal_control``,
            ``simulate``, ``sweep``).

    Returns:
        The path of ``index.html``.
    """
    from app.names import STANDARD_METHODS
    from app.planning.robots import load_robot
    from app.simulation.sweep import run_sweep

    out_dir.mkdir(parents=True, exist_ok=True)
    cases_share = 0.45 if sweep_robot else 0.95
    results = _run_cases(
        cases,
        seed=seed,
        particles=particles,
        iterations=iterations,
        methods=STANDARD_METHODS if methods is None else methods,
        progress=within(progress, 0.0, cases_share),
    )
    sections = [_case_section(case, results[case.robot]) for case in cases]
    sweep = None
    if sweep_robot:
        sweep = run_sweep(
            robot=load_robot(sweep_robot),
            durations=sweep_durations,
            payloads=sweep_payloads,
            objectives=sweep_objectives,
            seed=seed,
            workers=sweep_workers,
            methods=STANDARD_METHODS if sweep_methods is None else sweep_methods,
            progress=within(progress, cases_share, 0.95),
        )
    report(progress, "report", 0, 1, fraction=0.96, message="writing the report")
    claims = _claim_rows(results)
    summary = {
        "claims": claims,
        "results": {name: sim.to_dict() for name, sim in results.items()},
        "sweep": sweep.to_dict() if sweep is not None else None,
    }
    page = _page(claims, sections, _sweep_section(sweep) if sweep is not None else "")
    index = _write_atomically(out_dir, page, summary)
    report(progress, "done", 1, 1, message="report written")
    return index
