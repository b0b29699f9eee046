"""Plan + simulate comparisons and the sweep: metrics, phases, classification, bad cells."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.planning.energy import energy_metrics
from app.planning.profiles import quintic
from app.planning.robots import Robot, RobotError, load_robot
from app.simulation import (
    METRICS,
    SimulationError,
    SimulationResult,
    classify,
    run_sweep,
    simulate_comparison,
)

BUDGET = {"particles": 12, "iterations": 15}


@pytest.fixture(scope="module")
def cw() -> Robot:
    return load_robot("curtain_wall_6dof")


@pytest.fixture(scope="module")
def comparison(cw: Robot) -> SimulationResult:
    return simulate_comparison(cw, duration=1.0, objective="peak_power", seed=3, **BUDGET)


def test_to_dict_has_the_contract_keys_and_is_strict_json(comparison: SimulationResult) -> None:
    d = comparison.to_dict()
    assert set(d) == {
        "standard",
        "optimized",
        "tracking",
        "floors",
        "improvement_pct",
        "planned",
        "conditions",
        "warnings",
        "methods",
        "share_of_achievable_pct",
    }
    json.dumps(d, allow_nan=False)
    n = 6
    for label in ("standard", "optimized"):
        tr = d["tracking"][label]
        assert len(tr["rms"]) == len(tr["max"]) == n
        assert all(
            0.0 <= r <= m < math.radians(0.1) for r, m in zip(tr["rms"], tr["max"], strict=True)
        )
        assert set(METRICS) - {"peak_torque"} <= set(d[label])
    assert d["conditions"]["timestep"] == 1e-3
    assert d["conditions"]["payload"] == 4.0
    assert d["warnings"] == []


def test_simulated_metrics_agree_with_the_planner_within_2_percent(
    comparison: SimulationResult,
) -> None:
    for label, diffs in comparison.agreement_pct().items():
        for metric, pct in diffs.items():
            assert abs(pct) < 2.0, (label, metric, pct)
    # The planned trajectories were sampled on the simulation grid itself.
    assert comparison.plan.standard.trajectory.t.size == comparison.standard.t.size == 1001


def test_improvement_is_computed_from_the_simulation(comparison: SimulationResult) -> None:
    std, opt = comparison.standard, comparison.optimized
    independent = energy_metrics(
        opt.t, opt.qd, opt.tau, motors=load_robot("curtain_wall_6dof").motors
    )
    assert independent.peak_power == pytest.approx(opt.metrics.peak_power, rel=1e-12)
    expected = 100 * (std.metrics.peak_power - opt.metrics.peak_power) / std.metrics.peak_power
    assert comparison.improvement_pct["peak_power"] == pytest.approx(expected)


def test_peaks_fall_in_the_phase_given_by_the_commanded_elbow_crossings(
    comparison: SimulationResult,
) -> None:
    for label in ("standard", "optimized"):
        t_ab, t_bc = comparison.phase_times(label)  # interpolated crossings of 40 and 90 deg
        peaks = comparison.peaks(label)
        run = comparison.optimized if label == "optimized" else comparison.standard
        k = int(np.argmax(run.power))
        assert peaks["power"]["time"] == pytest.approx(run.t[k])
        assert peaks["power"]["value"] == pytest.approx(run.power.max())
        for peak in (peaks["power"], *peaks["torque"]):
            t = peak["time"]
            if abs(t - t_ab) < 2e-3 or abs(t - t_bc) < 2e-3:
                continue  # tracking error may flip a sample on the boundary
            expected = "A" if t < t_ab else ("B" if t < t_bc else "C")
            assert peak["phase"] == expected, (label, peak)
        assert [p["joint"] for p in peaks["torque"]] == list(comparison.conditions["joint_names"])


def test_summary_is_readable(comparison: SimulationResult) -> None:
    text = comparison.summary()
    for needle in ("curtain_wall_6dof", "peak_power", "max tracking error", "phase", "floors"):
        assert needle in text


def test_robot_without_mjcf_fails_before_planning(cw: Robot) -> None:
    bare = dataclasses.replace(cw, mjcf_path=None)
    with pytest.raises(RobotError, match="no MJCF"):
        simulate_comparison(bare, duration=1.0, particles=2, iterations=1)
    with pytest.raises(RobotError, match="no MJCF"):
        run_sweep(robot=bare, durations=[1.0], payloads=[4.0])


def test_classification_thresholds() -> None:
    assert classify(12.0) == "saves"
    assert classify(0.99) == classify(-0.99) == "no difference"
    assert classify(-1.0) == "costs more"
    assert classify(math.nan) == "n/a"


def test_sweep_classifies_cells_flags_the_floor_and_reports_infeasible(cw: Robot) -> None:
    fractions: list[float] = []
    res = run_sweep(
        robot=cw,
        durations=[0.3, 1.0, 2.0],
        payloads=[0.0, 4.0],
        objectives=["abs_work"],
        seed=0,
        workers=1,
        progress=lambda update: fractions.append(update.fraction),
        **BUDGET,
    )
    assert fractions[-1] == 1.0 and fractions == sorted(fractions)
    assert len(res.cells) == 6
    for p in (0.0, 4.0):
        fast = res.cell(0.3, p, "abs_work")
        assert fast.status == "infeasible" and "0.3 s" in fast.message
        assert set(fast.classification.values()) == {"infeasible"}
    for cell in res.cells:
        if cell.status != "ok":
            continue
        for metric in METRICS:
            change = cell.change_pct[metric]
            s, o = cell.standard[metric], cell.optimized[metric]
            assert change == pytest.approx(100 * (s - o) / s)
            label = cell.classification[metric]
            assert label == (
                "no difference" if abs(change) < 1 else "saves" if change > 0 else "costs more"
            )
        # Independent check of the floor flag: the standard quintic's abs_work from Pinocchio.
        robot = cw.with_payload(cell.payload)
        traj = quintic(robot.default_start, robot.default_goal, cell.duration, n_samples=2001)
        tau = robot.dynamics().inverse_dynamics(traj.q, traj.qd, traj.qdd)
        abs_work = energy_metrics(traj.t, traj.qd, tau).abs_work
        pe = robot.dynamics().potential_energy(np.stack([traj.q[0], traj.q[-1]]))
        assert cell.at_floor == (abs_work <= 1.01 * float(pe[1] - pe[0]))
    # A slow upward lift sits on the abs_work floor: nothing left to save there ...
    slow = res.cell(2.0, 4.0, "abs_work")
    assert slow.at_floor and slow.classification["abs_work"] == "no difference"
    # ... while at 1 s the bio-inspired plan saves work.
    assert res.cell(1.0, 4.0, "abs_work").classification["abs_work"] == "saves"
    table = res.table("abs_work", "abs_work")
    assert table.shape == (3, 2) and np.all(np.isnan(table[0]))
    text = res.summary()
    assert "infeasible" in text and "saves" in text and "no difference" in text
    json.dumps(res.to_dict(), allow_nan=False)


def test_parallel_sweep_equals_serial_sweep(cw: Robot) -> None:
    kwargs = {"durations": [1.0], "payloads": [0.0, 8.0], "objectives": ["peak_power"], "seed": 5}
    serial = run_sweep(robot=cw, workers=1, **kwargs, **BUDGET)  # type: ignore[arg-type]
    parallel = run_sweep(robot=cw, workers=2, **kwargs, **BUDGET)  # type: ignore[arg-type]
    assert parallel.conditions["workers"] == 2
    for a, b in zip(serial.cells, parallel.cells, strict=True):
        assert (a.duration, a.payload, a.status) == (b.duration, b.payload, b.status)
        assert a.change_pct == b.change_pct  # bit for bit
        assert a.standard == b.standard and a.optimized == b.optimized


def test_unknown_objective_is_the_planners_error(cw: Robot) -> None:
    from app.planning.planner import PlanningError

    with pytest.raises(PlanningError, match="beauty"):
        run_sweep(robot=cw, durations=[1.0], payloads=[1.0], objectives=["beauty"], workers=1)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"durations": [], "payloads": [1.0]}, "empty"),
        ({"durations": [0.0], "payloads": [1.0]}, "durations"),
        ({"durations": [1.0], "payloads": [-1.0]}, "payloads"),
        ({"durations": [1.0, 1.0], "payloads": [1.0]}, "repeat"),
    ],
)
def test_bad_sweep_input_is_refused(cw: Robot, kwargs: dict[str, object], needle: str) -> None:
    with pytest.raises(SimulationError, match=needle):
        run_sweep(robot=cw, workers=1, **kwargs)  # type: ignore[arg-type]


def test_script_without_main_guard_still_gets_its_sweep(tmp_path: Path) -> None:
    # Spawned workers re-import __main__; an unguarded script breaks the pool, and the sweep
    # then finishes in the calling process instead of crashing.
    script = tmp_path / "unguarded.py"
    script.write_text(
        "from app.planning.robots import load_robot\n"
        "from app.simulation import run_sweep\n"
        "res = run_sweep(robot=load_robot('curtain_wall_6dof'), durations=[1.0],\n"
        "                payloads=[0.0, 4.0], workers=2, particles=4, iterations=3)\n"
        "print('RESULT', res.conditions['workers'], [c.status for c in res.cells])\n",
        encoding="utf-8",
    )
    root = Path(__file__).resolve().parents[2]
    proc = subprocess.run(
        [sys.executable, str(script)],
        capture_output=True,
        text=True,
        timeout=240,
        cwd=root,
        env={**os.environ, "PYTHONPATH": str(root)},
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "RESULT 1 ['ok', 'ok']" in proc.stdout


def test_convergence_check_marks_metrics_whose_verdict_changes(cw: Robot) -> None:
    """The check re-plans the paper's method with each check seed; a metric is unconverged when
    the seeds' verdicts (saves / no difference / costs more) differ from the cell's planned one."""
    from app.simulation.sweep import _CellJob, _init_worker, _seed_runs, certify_verdicts, classify

    _init_worker(cw)
    job = _CellJob(1.0, 4.0, "abs_work", 0, 10, 8, 1e-3, ("quintic", "paper"), (5,))
    planned = {k: 50.0 for k in METRICS}  # "saves" everywhere
    changes, shares = _seed_runs(job, planned, math.nan, 1001, None)
    assert len(changes) == 2 and changes[0] is planned and set(changes[1]) == set(METRICS)
    assert all(math.isnan(s) for s in shares)  # no bound: no share
    uncertain = [k for k, v in certify_verdicts(changes).items() if not v.certain]
    assert uncertain == [k for k in METRICS if classify(changes[1][k]) != "saves"]
    same = _CellJob(1.0, 4.0, "abs_work", 0, 10, 8, 1e-3, ("quintic", "paper"), ())
    assert _seed_runs(same, planned, 1.0, 1001, None) == ([planned], [1.0])


def test_simulated_arrays_hold_every_method(cw: Robot) -> None:
    sim = simulate_comparison(
        cw, duration=1.0, objective="tau_sq", particles=10, iterations=8,
        methods=("quintic", "paper", "bound"),
    )  # fmt: skip
    arrays = sim.arrays()
    for name in ("quintic", "paper", "bound", "standard", "optimized"):
        assert arrays[f"{name}_q"].shape == (arrays["t"].size, 6)
        assert arrays[f"{name}_energy"].shape == arrays["t"].shape
    d = sim.to_dict()
    assert set(d["methods"]) == {"quintic", "paper", "bound"}
    assert d["share_of_achievable_pct"]["bound"] == pytest.approx(100.0)
    # The bound is tracked as closely as the others, so its simulated tau_sq stays the lowest.
    tau_sq = {n: m["tau_sq"] for n, m in d["methods"].items()}
    assert tau_sq["bound"] < min(tau_sq["paper"], tau_sq["quintic"])
