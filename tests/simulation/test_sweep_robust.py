"""Robust sweep verdicts (issue 25 item 5): the paper's PSO is checked by several seeds, a
verdict is certain only when all agree, and a cell where only the paper's family is infeasible
still reports every other method."""

from __future__ import annotations

import json
import math

import pytest

from app.planning.planner import PlanningError, plan
from app.planning.robots import Robot, load_robot
from app.simulation import METRICS, SimulationError, classify, run_sweep
from app.simulation.comparison import pct_change, scalar_metrics
from app.simulation.sweep import Verdict, certify_verdicts

#: A budget so small that the seeds of the paper's PSO really disagree on the 2-DOF 1 s / 4 kg
#: lift (one seed even finds no feasible plan): planted disagreement without a stub.
TINY = {"particles": 4, "iterations": 3}


@pytest.fixture(scope="module")
def arm() -> Robot:
    return load_robot("human_arm_2dof")


def test_verdicts_are_certain_only_when_every_seed_agrees() -> None:
    # Two PSO results injected: they agree on one metric, disagree on another (a near tie).
    runs = [{"abs_work": 4.0, "peak_power": 0.4}, {"abs_work": 9.0, "peak_power": -1.5}]
    got = certify_verdicts(runs)
    assert got["abs_work"] == Verdict("saves", True, ("saves", "saves"), 4.0, 9.0)
    assert got["peak_power"] == Verdict(
        "no difference", False, ("no difference", "costs more"), -1.5, 0.4
    )
    # A seed without a plan cannot certify a verdict; its NaN is left out of the spread.
    failed = certify_verdicts([{"tau_sq": 5.0}, {"tau_sq": math.nan}, {"tau_sq": 2.0}])
    assert failed["tau_sq"] == Verdict("saves", False, ("saves", "n/a", "saves"), 2.0, 5.0)
    # One seed is certain by itself (nothing disagrees), with no spread.
    assert certify_verdicts([{"tau_sq": -3.0}])["tau_sq"].certain
    with pytest.raises(ValueError, match="at least one"):
        certify_verdicts([])


def test_seeds_that_disagree_mark_the_verdict_uncertain_with_its_spread(arm: Robot) -> None:
    res = run_sweep(
        robot=arm, durations=[1.0], payloads=[4.0], methods=["quintic", "paper"], seed=0,
        seeds=4, workers=1, **TINY,
    )  # fmt: skip
    assert res.conditions["seeds"] == [0, 1, 2, 3]
    assert res.conditions["pso_budget"]["seeds"] == 4
    assert res.conditions["pso_budget"]["particles"] == 4
    [cell] = res.cells
    assert cell.seeds == (0, 1, 2, 3)
    # Independent re-plans of every seed on the simulation grid (1 ms steps over 1 s).
    by_seed: list[dict[str, float]] = []
    for seed in cell.seeds:
        try:
            p = plan(
                arm.with_payload(4.0), duration=1.0, seed=seed, report_samples=1001,
                methods=("quintic", "paper"), **TINY,
            )  # fmt: skip
        except PlanningError:  # a seed without a feasible plan: its verdict is n/a
            by_seed.append({k: math.nan for k in METRICS})
            continue
        std = scalar_metrics(p.standard.metrics)
        opt = scalar_metrics(p.methods["paper"].evaluated.metrics)
        by_seed.append({k: pct_change(std[k], opt[k]) for k in METRICS})
    uncertain = []
    for k in METRICS:
        labels = tuple(classify(run[k]) for run in by_seed)
        v = cell.verdicts[k]
        assert v.by_seed == labels
        assert v.certain == (len(set(labels)) == 1)
        finite = [run[k] for run in by_seed if math.isfinite(run[k])]
        assert (v.low_pct, v.high_pct) == pytest.approx((min(finite), max(finite)), rel=1e-9)
        if not v.certain:
            uncertain.append(k)
    # The planted disagreement is real: at this budget the seeds do not agree.
    assert uncertain and list(cell.unconverged) == uncertain
    assert cell.check_planned_change_pct == pytest.approx(by_seed[1], nan_ok=True)
    text = res.summary()
    assert "x 4 seed(s) per cell" in text
    assert f"uncertain: T=1 s, m=4 kg, abs_work, {uncertain[0]}:" in text
    d = res.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["cells"][0]["verdicts"][uncertain[0]]["certain"] is False


def test_the_seeds_option_changes_the_verdicts(arm: Robot) -> None:
    kwargs = {"durations": [1.0], "payloads": [4.0], "methods": ["quintic", "paper"], "seed": 0}
    one = run_sweep(robot=arm, seeds=1, workers=1, **kwargs, **TINY)  # type: ignore[arg-type]
    two = run_sweep(robot=arm, seeds=2, workers=1, **kwargs, **TINY)  # type: ignore[arg-type]
    assert one.cells[0].seeds == (0,) and one.conditions["check_seed"] is None
    assert all(v.certain for v in one.cells[0].verdicts.values())  # nothing to disagree with
    assert two.cells[0].seeds == (0, 1) and two.conditions["check_seed"] == 1
    assert two.cells[0].unconverged  # seed 1 finds no plan at this budget
    assert one.cells[0].change_pct == two.cells[0].change_pct  # the cell's own plan is the same
    with pytest.raises(SimulationError, match="seeds must be an integer >= 1"):
        run_sweep(robot=arm, seeds=0, workers=1, **kwargs)  # type: ignore[arg-type]


def test_a_cell_where_only_the_paper_is_infeasible_reports_the_other_methods(arm: Robot) -> None:
    # 2-DOF, 0.5 s, 8 kg: no trajectory with the elbow's velocity peak at 62 deg fits the limits,
    # while the bound (the limits only) exists.
    res = run_sweep(
        robot=arm, durations=[0.5], payloads=[8.0], objectives=["abs_work"],
        methods=["quintic", "paper", "bound"], seeds=2, workers=1,
    )  # fmt: skip
    [cell] = res.cells
    assert cell.status == "ok" and cell.paper_infeasible
    assert "elbow's velocity peak" in cell.method_status["paper"]
    assert cell.method_status["bound"] == "ok"
    assert set(cell.classification.values()) == {"infeasible"}
    assert set(cell.methods_change_pct) == {"quintic", "bound"}
    # Independently: the planner alone finds the bound, below the quintic on abs_work.
    alone = plan(arm.with_payload(8.0), duration=0.5, methods=("quintic", "bound"))
    assert alone.objective_values["bound"] < alone.objective_values["quintic"]
    assert cell.methods_change_pct["bound"]["abs_work"] > 0.0
    assert "paper infeasible: T=0.5 s, m=8 kg" in res.summary()
    json.dumps(res.to_dict(), allow_nan=False)
    # With nothing but the quintic left the cell stays infeasible, as before.
    only = run_sweep(
        robot=arm, durations=[0.5], payloads=[8.0], methods=["quintic", "paper"], seeds=1,
        workers=1,
    )  # fmt: skip
    assert only.cells[0].status == "infeasible"
