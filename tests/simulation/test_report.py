"""The demo report: simulated figures, sweep heat maps, claims table, nothing half-written."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from app.planning.robots import RobotError
from app.simulation.report import DemoCase, figure_simulation, figure_sweep, write_demo_report

SMALL = {"particles": 6, "iterations": 5}


def _strict(text: str) -> object:
    def bad(name: str) -> object:
        raise ValueError(f"non-finite number {name} in results.json")

    return json.loads(text, parse_constant=bad)


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("report")
    write_demo_report(
        out,
        seed=1,
        cases=(
            DemoCase("human_arm_2dof", "abs_work", 1.0, 12.0),
            DemoCase("curtain_wall_6dof", "peak_power", 1.0, 4.0),
        ),
        sweep_durations=(1.0, 2.0),
        sweep_payloads=(0.0, 4.0),
        sweep_objectives=("abs_work",),
        sweep_methods=("quintic", "paper"),
        sweep_workers=1,
        **SMALL,
    )
    return out


def test_report_files_and_claims_come_from_the_simulation(report_dir: Path) -> None:
    page = (report_dir / "index.html").read_text(encoding="utf-8")
    assert (report_dir / "plotly.min.js").stat().st_size > 1_000_000
    for needle in ("Fig. 5", "Fig. 6", "Fig. 7", "Fig. 10 - MuJoCo simulation", "Sweep on"):
        assert needle in page
    data = _strict((report_dir / "results.json").read_text(encoding="utf-8"))
    assert isinstance(data, dict)
    claims = {c["robot"]: c for c in data["claims"]}
    assert set(claims) == {"human_arm_2dof", "curtain_wall_6dof"}
    assert claims["curtain_wall_6dof"]["paper_claim_pct"] == 48.4
    assert claims["human_arm_2dof"]["paper_claim_pct"] == 12.0
    for robot, claim in claims.items():
        sim = data["results"][robot]
        assert claim["measured_pct"] == sim["improvement_pct"][claim["metric"]]
        assert claim["planned_pct"] == sim["planned"]["improvement_pct"][claim["metric"]]
        assert "MuJoCo 1 ms" in claim["conditions"] and "payload" in claim["conditions"]
    for claim in claims.values():
        assert set(claim["methods_pct"]) == {"paper", "human_optimal", "bound", "jerk_limited"}
        assert claim["methods_pct"]["paper"] == claim["measured_pct"]
        assert claim["share_of_achievable_pct"]["bound"] == pytest.approx(100.0)
    for needle in ("human-like optimum", "physical bound", "industrial jerk-limited",
                   "minimum-jerk (wide grey band) is the same curve as the quintic"):  # fmt: skip
        assert needle in page
    sweep = data["sweep"]
    assert sweep["durations"] == [1.0, 2.0] and sweep["payloads"] == [0.0, 4.0]
    assert len(sweep["cells"]) == 4


def test_figure_10_shows_both_runs_with_phases() -> None:
    from app.planning.robots import load_robot
    from app.simulation import simulate_comparison

    sim = simulate_comparison(load_robot("curtain_wall_6dof"), duration=1.0, seed=0, **SMALL)
    fig = figure_simulation(sim, "test")
    lines = [tr for tr in fig.data if tr.mode != "markers+text"]
    assert len(lines) == 12  # 6 panels x (standard, optimised)
    markers = [tr for tr in fig.data if tr.mode == "markers+text"]
    assert [m.y[0] for m in markers] == [sim.standard.power.max(), sim.optimized.power.max()]
    rects = [s for s in fig.layout.shapes if s.type == "rect"]
    t_ab, t_bc = sim.phase_times("optimized")
    assert [(r.x0, r.x1) for r in rects] == [(0.0, t_ab), (t_ab, t_bc), (t_bc, 1.0)]


def test_heat_map_cells_match_the_sweep() -> None:
    from app.planning.robots import load_robot
    from app.simulation import run_sweep

    sweep = run_sweep(
        robot=load_robot("curtain_wall_6dof"),
        durations=[0.3, 1.0],
        payloads=[4.0],
        objectives=["abs_work"],
        workers=1,
        **SMALL,
    )
    fig = figure_sweep(sweep, "abs_work", ["abs_work", "peak_power"])
    assert len(fig.data) == 2
    for trace, metric in zip(fig.data, ["abs_work", "peak_power"], strict=True):
        assert trace.z[0][0] is None and trace.text[0][0] == "infeasible"
        value = sweep.cell(1.0, 4.0, "abs_work").change_pct[metric]
        assert math.isclose(trace.z[1][0], value)
        assert trace.text[1][0].startswith(f"{value:+.1f}%")


def test_failed_report_leaves_no_half_written_files(tmp_path: Path) -> None:
    out = tmp_path / "bad"
    with pytest.raises(RobotError):
        write_demo_report(
            out, cases=(DemoCase("no_such_robot", "abs_work", 1.0, 1.0),), sweep_robot=None
        )
    assert not (out / "index.html").exists() and not (out / "results.json").exists()
