"""The CLI contract of DESIGN.md: --json prints one object; bad input exits 2, in one line."""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from pathlib import Path

import pytest


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, timeout=300
    )


def test_plan_json_is_one_object_with_the_contract_keys() -> None:
    proc = run_cli(
        "plan",
        "--robot",
        "human_arm_2dof",
        "--duration",
        "1.0",
        "--payload",
        "12",
        "--objective",
        "abs_work",
        "--particles",
        "8",
        "--iterations",
        "5",
        "--method",
        "paper",
        "--json",
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)  # the whole of stdout is one JSON document
    assert {
        "standard",
        "optimized",
        "floors",
        "improvement_pct",
        "peak_velocity_angle_deg",
        "optimizer",
    } <= set(data)
    assert data["optimizer"]["seed"] == 0


def test_plan_writes_out_file(tmp_path: Path) -> None:
    out = tmp_path / "plan.json"
    proc = run_cli(
        "plan",
        "--robot",
        "human_arm_2dof",
        "--particles",
        "6",
        "--iterations",
        "3",
        "--objective",
        "tau_sq",
        "--intervals",
        "16",
        "--out",
        str(out),
    )
    assert proc.returncode == 0, proc.stderr
    assert "standard quintic" in proc.stdout
    assert json.loads(out.read_text())["conditions"]["robot"] == "human_arm_2dof"


def test_profiles_lists_classical_and_min_torque_change() -> None:
    proc = run_cli(
        "profiles", "--robot", "human_arm_2dof", "--duration", "1.0", "--method", "none", "--json"
    )
    assert proc.returncode == 0, proc.stderr
    names = set(json.loads(proc.stdout)["profiles"])
    expected = {"trapezoidal", "triangular", "s_curve", "cubic", "quintic", "minimum_jerk"}
    assert names == expected | {"min_torque_change"}


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["plan", "--robot", "no_such_robot"], "no_such_robot"),
        (["plan", "--robot", "human_arm_2dof", "--objective", "beauty"], "beauty"),
        (["plan", "--robot", "human_arm_2dof", "--duration", "-1"], "duration"),
        (["plan", "--robot", "human_arm_2dof", "--duration", "0"], "duration"),
        (
            ["plan", "--robot", "human_arm_2dof", "--start-deg", "0,90", "--goal-deg", "0,90"],
            "start equals goal",
        ),
        (["plan", "--robot", "human_arm_2dof", "--duration", "0.05"], "infeasible"),
        (["plan", "--robot", "human_arm_2dof", "--duration", "abc"], "duration"),
    ],
)
def test_bad_input_one_line_exit_2(args: list[str], needle: str) -> None:
    proc = run_cli(*args)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert needle in lines[0]
    assert "Traceback" not in proc.stderr


def test_malformed_urdf_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "broken.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot")
    proc = run_cli("plan", "--robot", str(bad))
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1
    assert "broken.urdf" in proc.stderr


# -- every option changes the result (in-process: one parse + run per call) -------------------


def run_json(capsys: pytest.CaptureFixture[str], *args: str) -> dict[str, object]:
    from app.cli import main

    code = main([*args, "--json"])
    out = capsys.readouterr()
    assert code == 0, out.err
    data = json.loads(out.out)
    assert isinstance(data, dict)
    return data


#: Outputs of :func:`base_json` by arguments: the parametrised option tests below compare each
#: option against the same unchanged run, computed once per module run rather than once a case.
_BASES: dict[tuple[str, ...], dict[str, object]] = {}


def base_json(capsys: pytest.CaptureFixture[str], *args: str) -> dict[str, object]:
    """:func:`run_json` of a reference run several tests share (a fresh copy each time)."""
    if args not in _BASES:
        _BASES[args] = run_json(capsys, *args)
    return copy.deepcopy(_BASES[args])


FAST_PLAN = ("plan", "--robot", "human_arm_2dof", "--particles", "12", "--iterations", "12")


def test_plan_reports_every_method_by_default(capsys: pytest.CaptureFixture[str]) -> None:
    data = run_json(capsys, *FAST_PLAN, "--objective", "tau_sq", "--intervals", "16")
    methods = data["methods"]
    assert isinstance(methods, dict)
    assert list(methods) == ["quintic", "paper", "human_optimal", "bound", "jerk_limited"]
    shares = data["share_of_achievable_pct"]
    assert isinstance(shares, dict) and shares["bound"] == pytest.approx(100.0)
    assert "optimized" in data and "standard" in data


@pytest.mark.parametrize(
    ("option", "value", "methods", "path"),
    [
        ("--method", "quintic,bound", "paper", ("conditions", "methods")),
        ("--human-constraint", "phases", "human_optimal", ("methods", "human_optimal", "tau_sq")),
        ("--intervals", "20", "bound", ("methods", "bound", "tau_sq")),
        ("--peak-angle-deg", "80", "human_optimal", ("methods", "human_optimal", "tau_sq")),
        ("--template", "TEMPLATE", "human_optimal", ("methods", "human_optimal", "tau_sq")),
        ("--seed", "3", "paper", ("methods", "paper", "tau_sq")),
        ("--particles", "16", "paper", ("methods", "paper", "tau_sq")),
        ("--iterations", "20", "paper", ("methods", "paper", "tau_sq")),
        ("--objective", "peak_power", "bound", ("methods", "bound", "tau_sq")),
        ("--duration", "1.3", "jerk_limited", ("methods", "jerk_limited", "tau_sq")),
        ("--payload", "5", "quintic", ("methods", "quintic", "tau_sq")),
        ("--goal-deg", "30,140", "quintic", ("methods", "quintic", "tau_sq")),
        ("--start-deg", "5,10", "quintic", ("methods", "quintic", "tau_sq")),
    ],
)
def test_each_plan_option_changes_the_result(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    option: str,
    value: str,
    methods: str,
    path: tuple[str, ...],
) -> None:
    if value == "TEMPLATE":
        from app.planning.human_template import HumanTemplate

        template = tmp_path / "template.json"
        template.write_text(HumanTemplate(peak_velocity_angle_deg=75.0, n_lifts=2).to_json())
        value = str(template)
    base_args = (*FAST_PLAN, "--objective", "tau_sq", "--intervals", "16", "--method", methods)
    base = base_json(capsys, *base_args)
    changed = run_json(capsys, *base_args, option, value)

    def get(d: object) -> object:
        for key in path:
            d = d[key]  # type: ignore[index]
        return d

    assert get(base) != get(changed)


def test_allow_reversal_lets_the_still_shoulder_move(capsys: pytest.CaptureFixture[str]) -> None:
    args = (*FAST_PLAN, "--objective", "tau_sq", "--method", "bound", "--goal-deg", "0,150",
            "--intervals", "16")  # fmt: skip
    kept = run_json(capsys, *args)
    free = run_json(capsys, *args, "--allow-reversal")
    assert free["methods"]["bound"]["tau_sq"] < kept["methods"]["bound"]["tau_sq"]  # type: ignore[index]
    assert free["conditions"]["no_reversal"] is False  # type: ignore[index]


def test_profiles_options_change_the_result(capsys: pytest.CaptureFixture[str]) -> None:
    args = ("profiles", "--robot", "human_arm_2dof", "--method", "none")
    coarse = run_json(capsys, *args, "--mtc-intervals", "20")
    finer = run_json(capsys, *args, "--mtc-intervals", "40")
    mtc = [d["profiles"]["min_torque_change"]["tau_sq"] for d in (coarse, finer)]  # type: ignore[index]
    assert mtc[0] != mtc[1]
    solver = finer["min_torque_change_solver"]
    assert solver["status"] == "Solve_Succeeded" and solver["n_intervals"] == 40  # type: ignore[index]
    assert "methods" not in coarse
    skipped = run_json(capsys, *args, "--no-min-torque-change")
    assert "min_torque_change" not in skipped["profiles"]  # type: ignore[operator]


@pytest.mark.parametrize(
    ("option", "value", "method"),
    [("--objective", "tau_sq", "bound"), ("--seed", "4", "paper"), ("--method", "bound", "bound")],
)
def test_profiles_list_the_planning_methods(
    capsys: pytest.CaptureFixture[str], option: str, value: str, method: str
) -> None:
    args = ("profiles", "--robot", "human_arm_2dof", "--no-min-torque-change")
    base = base_json(capsys, *args, "--method", "paper,bound", "--objective", "peak_power")
    assert list(base["methods"]) == ["quintic", "paper", "bound"]  # type: ignore[arg-type]
    assert base["share_of_achievable_pct"]["bound"] == pytest.approx(100.0)  # type: ignore[index]
    changed = run_json(
        capsys, *args, "--method", "paper,bound", "--objective", "peak_power", option, value
    )
    if option == "--method":
        assert list(changed["methods"]) == ["quintic", "bound"]  # type: ignore[arg-type]
    else:
        assert changed["methods"][method] != base["methods"][method]  # type: ignore[index]


SIM = ("simulate", "--robot", "human_arm_2dof", "--particles", "12", "--iterations", "12",
       "--method", "quintic,paper")  # fmt: skip


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("--start-deg", "10,20"),
        ("--goal-deg", "30,120"),
        ("--objective", "peak_power"),
        ("--seed", "5"),
        ("--particles", "16"),
        ("--iterations", "20"),
        ("--peak-angle-deg", "85"),
        ("--timestep-ms", "2"),
        ("--payload", "3"),
        ("--duration", "1.2"),
        ("--template", "TEMPLATE"),
    ],
)
def test_each_simulate_option_changes_the_result(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, option: str, value: str
) -> None:
    if value == "TEMPLATE":
        from app.planning.human_template import HumanTemplate

        template = tmp_path / "template.json"
        template.write_text(HumanTemplate(peak_velocity_angle_deg=80.0, n_lifts=2).to_json())
        value = str(template)
    base = base_json(capsys, *SIM)
    changed = run_json(capsys, *SIM, option, value)
    assert base["optimized"] != changed["optimized"]


def test_simulate_tracks_every_requested_method(capsys: pytest.CaptureFixture[str]) -> None:
    data = run_json(
        capsys, "simulate", "--robot", "human_arm_2dof", "--particles", "12", "--iterations", "12",
        "--method", "paper,bound,jerk_limited", "--objective", "tau_sq",
        "--human-constraint", "none",
    )  # fmt: skip
    assert list(data["methods"]) == ["quintic", "paper", "bound", "jerk_limited"]  # type: ignore[arg-type]
    for m in data["methods"].values():  # type: ignore[attr-defined]
        assert max(m["tracking"]["max"]) < 0.02  # rad: every method is followed closely
    assert data["share_of_achievable_pct"]["bound"] == pytest.approx(100.0, abs=3.0)  # type: ignore[index]


def test_simulate_human_constraint_changes_the_human_like_optimum(
    capsys: pytest.CaptureFixture[str],
) -> None:
    args = (*SIM[:-1], "human_optimal", "--objective", "tau_sq")
    peak = run_json(capsys, *args)
    none = run_json(capsys, *args, "--human-constraint", "none")
    assert peak["conditions"]["human_constraint"] == "peak"  # type: ignore[index]
    assert none["methods"]["human_optimal"]["tau_sq"] < peak["methods"]["human_optimal"]["tau_sq"]  # type: ignore[index]


SWEEP = (
    *("sweep", "--robot", "human_arm_2dof", "--durations", "1.0", "--payloads", "6"),
    *("--particles", "12", "--iterations", "12", "--workers", "1", "--method", "quintic,paper"),
)


@pytest.mark.parametrize(
    ("option", "value", "key"),
    [
        ("--method", "quintic,paper,jerk_limited", "methods_change_pct"),
        ("--check-seed", "11", "check_planned_change_pct"),
        ("--no-check", None, "check_planned_change_pct"),
        ("--seed", "2", "change_pct"),
        ("--particles", "16", "change_pct"),
        ("--iterations", "20", "change_pct"),
        ("--objectives", "peak_power", "change_pct"),
        ("--durations", "1.2", "change_pct"),
        ("--payloads", "3", "change_pct"),
    ],
)
def test_each_sweep_option_changes_the_result(
    capsys: pytest.CaptureFixture[str], option: str, value: str | None, key: str
) -> None:
    base = base_json(capsys, *SWEEP)
    extra = (option,) if value is None else (option, value)
    changed = run_json(capsys, *SWEEP, *extra)
    assert base["cells"][0][key] != changed["cells"][0][key]  # type: ignore[index]


def test_bad_method_and_too_short_jerk_limited_are_one_line_errors() -> None:
    proc = run_cli("plan", "--robot", "human_arm_2dof", "--method", "quintic,magic")
    assert proc.returncode == 2 and "magic" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    proc = run_cli(
        "plan", "--robot", "curtain_wall_6dof", "--duration", "0.6", "--method", "jerk_limited"
    )
    assert proc.returncode == 2 and "needs at least 0.7" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_plan_text_shows_every_floor_once() -> None:
    """The table's floors line showed ΔPE and peak power only, and a second line the rest: now
    one line with every floor (|ΔPE|, positive work, peak power, electrical with friction)."""
    args = ("--robot", "human_arm_2dof", "--particles", "8", "--iterations", "5")
    text = run_cli("plan", *args, "--method", "paper")
    data = json.loads(run_cli("plan", *args, "--method", "paper", "--json").stdout)
    assert text.returncode == 0, text.stderr
    lines = [line for line in text.stdout.splitlines() if line.startswith("floors")]
    assert len(lines) == 1, text.stdout
    floors = data["floors"]
    for label, key, unit in (
        ("|ΔPE| ", "abs_work", "J"),
        ("positive work ", "pos_work", "J"),
        ("peak power ", "peak_power", "W"),
        ("electrical ", "electrical_energy", "J"),
        ("friction ", "friction_energy", "J"),
    ):
        assert f"{label}{floors[key]:.4g} {unit}" in lines[0], (key, lines[0])


def test_demo_json_is_one_object_with_the_claims(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``bioplan demo --json`` prints one object: the report's paths and its claims as stored in
    its ``results.json`` (the real demo runs in the README test; here a tiny one)."""
    from app.cli import main
    from app.simulation import report

    small = (report.DemoCase("human_arm_2dof", "abs_work", 1.0, 12.0),)
    real = report.write_demo_report

    def tiny(out_dir: Path, **kw: object) -> Path:
        return real(
            out_dir, seed=3, cases=small, particles=6, iterations=3, methods=("quintic", "paper"),
            sweep_robot=None,
        )  # fmt: skip

    monkeypatch.setattr(report, "write_demo_report", tiny)
    assert main(["demo", "--out-dir", str(tmp_path / "r"), "--seed", "3", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)  # the whole of stdout is one JSON document
    stored = json.loads((tmp_path / "r" / "results.json").read_text())
    assert data["claims"] == stored["claims"] and data["seed"] == 3
    assert Path(data["report"]).is_file() and data["report"].endswith("index.html")
    assert {c["robot"] for c in data["claims"]} == {"human_arm_2dof"}
    assert all("conditions" in c and "methods_pct" in c for c in data["claims"])


def test_an_error_message_is_shown_as_one_printable_line() -> None:
    """What the CLI prints and the API answers for bad input: one line, control bytes escaped,
    whitespace runs as one space, at most 1000 characters."""
    from app.errors import one_line

    assert one_line("x.c3d: parameter A\x07B\n  has  data type 90") == (
        "x.c3d: parameter A\\x07B has data type 90"
    )
    long = one_line("y" * 5000)
    assert len(long) == 1000 and long.endswith("…")
    assert one_line("fine: ä ok") == "fine: ä ok"


def test_plan_text_skips_a_joint_whose_change_has_no_ratio(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`bioplan plan --robot curtain_wall_6dof --objective peak_torque --method
    quintic,bound_unrestricted` stopped with a TypeError traceback, even with --json: the
    unrestricted bound turns the base, which the quintic leaves unloaded, so that joint's
    peak-torque change has no ratio (NaN, null in the JSON). The summary line now shows the
    largest change of the other joints. That run took 92 s beside a CPU hog with a cold compile
    cache (13 s warm, idle), so the human arm's plan gets a shoulder with the same undefined
    change here."""
    import math

    from app.cli import main
    from app.planning import planner
    from app.planning.energy import EnergyMetrics

    def without_a_ratio(
        standard: EnergyMetrics, optimized: EnergyMetrics
    ) -> dict[str, float | list[float]]:
        out = improvement(standard, optimized)
        per_joint = out["peak_torque"]
        assert isinstance(per_joint, list)
        out["peak_torque"] = [math.nan, *per_joint[1:]]
        return out

    improvement = planner.improvement_pct  # type: ignore[attr-defined]
    monkeypatch.setattr(planner, "improvement_pct", without_a_ratio)
    out = tmp_path / "plan.json"
    args = ["--robot", "human_arm_2dof", "--objective", "peak_torque", "--intervals", "8"]
    code = main(["plan", *args, "--method", "quintic,bound", "--out", str(out)])
    text = capsys.readouterr()
    assert code == 0, text.err
    per_joint = json.loads(out.read_text())["methods"]["bound"]["improvement_pct"]["peak_torque"]
    assert per_joint[0] is None and per_joint[1] is not None
    assert f"bound: peak_torque {per_joint[1]:+.1f}% vs the quintic" in text.out
