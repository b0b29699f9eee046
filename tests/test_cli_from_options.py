"""Flags made from the options dataclasses (``bioplan analyze``, ``bioplan submit``, ``bioplan
profiles``) and the mesh-refinement evidence ``bioplan plan`` prints.

Each flag is checked against its field (name, default, range) and shown to change what the
command does; the printed error estimate is checked against a Richardson estimate worked out
here from the printed sequence of objectives.
"""

from __future__ import annotations

import argparse
import json
import math
import re
from pathlib import Path
from typing import Any

import pytest

from app.analysis.pipeline import AnalysisOptions
from app.cli import build_parser, main
from app.cli.analyze import HAND_MADE, analysis_options
from app.cli.plan import _convergence_text
from app.cli.submit import SWEEP_OPTIONS, TASK_OPTIONS, _job_body
from app.options import option_specs
from app.planning.options import MethodOptions
from app.simulation.options import SweepGrid
from tests.analysis import _synthetic as syn


def _subparser(*path: str) -> argparse.ArgumentParser:
    """The parser of ``bioplan <path...>`` (e.g. ``("submit", "plan")``)."""
    parser = build_parser()
    for name in path:
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = sub.choices[name]
    return parser


def _actions(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    return {flag: a for a in parser._actions for flag in a.option_strings}


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


# ------------------------------------------------------------------------- bioplan analyze


def test_every_analysis_option_is_a_flag_with_its_default_and_range() -> None:
    actions = _actions(_subparser("analyze"))
    specs = {s.name: s for s in option_specs(AnalysisOptions)}
    assert set(HAND_MADE) <= set(specs), "a hand-made flag names no AnalysisOptions field"
    for name, spec in specs.items():
        if name in HAND_MADE:  # written by hand in another form: those flags exist
            assert all(flag in actions for flag in HAND_MADE[name]), name
            continue
        action = actions[_flag(name)]
        assert action.dest == name
        assert action.default == spec.interface_default, name
        for sign, bound in (
            (">", spec.meta.get("gt")),
            (">=", spec.meta.get("ge")),
            ("<", spec.meta.get("lt")),
            ("<=", spec.meta.get("le")),
        ):
            if bound is not None:
                assert f"{sign} {bound:g}" in (action.help or ""), (name, sign)
    # What the fields made: the EMG rate (> 0 Hz) and keeping low-quality lifts.
    assert actions["--emg-rate"].type is float and actions["--emg-rate"].default is None
    assert actions["--keep-low-quality-lifts"].default is False


def _options(*argv: str) -> AnalysisOptions:
    return analysis_options(build_parser().parse_args(["analyze", "some.csv", *argv]))


def test_the_flags_defaults_are_the_fields_defaults() -> None:
    # Every field, the hand-made ones too (bounds in radians from the flag's degrees).
    assert _options() == AnalysisOptions()


@pytest.mark.parametrize(
    ("argv", "field", "value"),
    [
        (("--emg-rate", "2000"), "emg_rate", 2000.0),
        (("--keep-low-quality-lifts",), "keep_low_quality_lifts", True),
        (("--muscle", "EMG1=biceps", "--muscle", "EMG2=triceps"), "muscle_map",
         {"EMG1": "biceps", "EMG2": "triceps"}),
        (("--exclude", "EMG3", "--exclude", "EMG4"), "exclude_channels",
         frozenset({"EMG3", "EMG4"})),
        (("--phase-bounds-deg", "30,100"), "bounds", (math.pi / 6, 5 * math.pi / 9)),
        (("--offset", "-0.25"), "offset", -0.25),
        (("--offset", "auto"), "offset", "auto"),
        (("--side", "left", "--landmarks", "plugin_gait_left"), "pose_options",
         {"side": "left", "landmarks": "plugin_gait_left"}),
    ],
)  # fmt: skip
def test_each_analysis_flag_sets_its_field_and_no_other(
    argv: tuple[str, ...], field: str, value: object
) -> None:
    changed, default = _options(*argv), AnalysisOptions()
    if field == "bounds":
        assert changed.bounds == pytest.approx(value, rel=1e-15)
    else:
        assert getattr(changed, field) == value
    assert getattr(default, field) != getattr(changed, field)
    assert changed.replace(**{field: getattr(default, field)}) == default


@pytest.fixture(scope="module")
def emg_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("cli_from_options")
    t, _ = syn.elbow_curls(3, 60.0)
    cycle = syn.RISE_S + syn.HOLD_S + syn.LOWER_S + syn.REST_S
    bursts = [syn.REST_S + k * cycle for k in range(3)]
    path: Path = syn.write_emg_csv(d / "emg.csv", bursts, seconds=float(t[-1]) + 0.5)
    return path


def test_the_emg_rate_flag_keeps_the_fields_range(
    emg_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # That the flags change the result: test_cli_analyze.py::test_emg_rate_rescales_the_emg_clock
    # and analysis/test_pose_quality.py::test_cli_flag_keeps_low_quality_lifts.
    for bad in ("0", "-5"):
        assert main(["analyze", str(emg_file), "--emg-rate", bad]) == 2
        err = capsys.readouterr().err.strip()
        assert "--emg-rate" in err and "> 0 Hz" in err and "\n" not in err


# -------------------------------------------------------------------------- bioplan submit


def _body(*argv: str) -> tuple[str, dict[str, Any]]:
    args = build_parser().parse_args(["submit", *argv])
    return _job_body(args)


@pytest.mark.parametrize("kind", ["plan", "simulate"])
def test_submit_sends_the_method_options_with_their_defaults(kind: str) -> None:
    actions = _actions(_subparser("submit", kind))
    specs = {s.name: s for s in option_specs(MethodOptions)}
    path, body = _body(kind)
    assert path == ("/api/plans" if kind == "plan" else "/api/simulations")
    for name in TASK_OPTIONS:
        assert actions[_flag(name)].default == specs[name].interface_default, name
        if specs[name].interface_default is not None:
            assert body[name] == specs[name].interface_default, name
    assert "peak_angle_deg" not in body  # None: the template's, left to the server


@pytest.mark.parametrize(
    ("flag", "value", "key", "sent"),
    [
        ("--objective", "tau_sq", "objective", "tau_sq"),
        ("--seed", "7", "seed", 7),
        ("--particles", "12", "particles", 12),
        ("--iterations", "9", "iterations", 9),
        ("--peak-angle-deg", "70", "peak_angle_deg", 70.0),
    ],
)
def test_each_submit_plan_flag_changes_the_request(
    flag: str, value: str, key: str, sent: object
) -> None:
    _, base = _body("plan")
    _, changed = _body("plan", flag, value)
    assert changed[key] == sent and base.get(key) != sent
    assert {k: v for k, v in changed.items() if k != key} == {
        k: v for k, v in base.items() if k != key
    }


def test_submit_sweep_sends_the_grid_from_its_flags() -> None:
    specs = {s.name: s for s in option_specs(SweepGrid)}
    _, base = _body("sweep")
    assert base == {
        "robot": "curtain_wall_6dof",
        **{name: list(specs[name].interface_default) for name in SWEEP_OPTIONS[:3]},
        "seed": specs["seed"].default,
    }
    _, changed = _body("sweep", "--durations", "0.8,1.6", "--payloads", "3", "--objectives",
                       "tau_sq,peak_power", "--seed", "5")  # fmt: skip
    assert changed == {
        "robot": "curtain_wall_6dof",
        "durations": [0.8, 1.6],
        "payloads": [3.0],
        "objectives": ["tau_sq", "peak_power"],
        "seed": 5,
    }


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (("plan", "--particles", "1"), "--particles: particles must be >= 2"),
        (("plan", "--iterations", "0"), "--iterations: iterations must be >= 1"),
        (("simulate", "--peak-angle-deg", "180"), "--peak-angle-deg: peak_angle_deg must be < 180"),
        (("sweep", "--seed", "-1"), "--seed: seed must be >= 0"),
        (("sweep", "--objectives", "tau_sq,nope"), "--objectives: unknown objectives 'nope'"),
        (("sweep", "--durations", "1,700"), "--durations: durations must be <= 600 s"),
    ],
)
def test_submit_refuses_out_of_range_options_before_sending(
    argv: tuple[str, ...], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    # Nothing listens on port 9: had the request been sent, it would fail with exit 1.
    code = main(["submit", "--server", "http://127.0.0.1:9", *argv])
    err = capsys.readouterr().err.strip()
    assert code == 2 and needle in err and "\n" not in err, err


# ------------------------------------------------------------------------- bioplan profiles


def test_profiles_objective_and_seed_are_plan_options() -> None:
    actions = _actions(_subparser("profiles"))
    specs = {s.name: s for s in option_specs(MethodOptions)}
    for name in ("objective", "seed"):
        assert actions[_flag(name)].default == specs[name].default
    assert tuple(actions["--objective"].choices or ()) == specs["objective"].choices


def test_profiles_refuses_an_unknown_objective(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["profiles", "--robot", "human_arm_2dof", "--objective", "speed"])
    assert stop.value.code == 2
    assert "--objective: invalid choice: 'speed'" in capsys.readouterr().err


# ------------------------------------------------------- bioplan plan: the mesh error estimate


def _richardson(values: list[float]) -> float:
    """The relative error left in the last of objectives on meshes N, 2N, 4N, ...: the
    geometric tail of changes shrinking at the observed ratio r (capped at 4, second order)."""
    d1, d2 = values[-3] - values[-2], values[-2] - values[-1]
    r = min(d1 / d2, 4.0)
    assert r >= 2.0  # the case these tests take: at least first order
    return abs(d2) / max(abs(values[-2]), abs(values[-1])) / (r - 1.0)


def test_the_printed_estimate_is_richardsons_and_the_change_is_labelled() -> None:
    values = [1.0, 0.9, 0.875]  # changes 0.1 then 0.025: ratio 4, second order
    conv = {
        "sequence": [{"n_intervals": 8 * 2**k, "objective": v} for k, v in enumerate(values)],
        "relative_change": 0.025 / 0.9,
        "error_estimate": _richardson(values),
        "extrapolated": True,
        "converged": True,
        "final_intervals": 32,
        "tolerance": 1e-3,
    }
    text = _convergence_text(conv)
    assert "relative change 2.78 %" in text
    assert f"error estimate {100 * 0.025 / 0.9 / 3:.3g} % (Richardson)" in text
    assert "error estimate 0.926 %" in text
    # Not extrapolated: the estimate is the last change, and says so.
    plain = _convergence_text({**conv, "error_estimate": conv["relative_change"],
                               "extrapolated": False})  # fmt: skip
    assert "error estimate 2.78 % (the last change)" in plain
    # A result stored before the estimate existed: only the relative change, no invented one.
    old = {k: v for k, v in conv.items() if k not in ("error_estimate", "extrapolated")}
    assert "error estimate" not in _convergence_text(old)
    assert "relative change 2.78 %" in _convergence_text(old)
    # JSON turns NaN (one mesh only) into null.
    assert "relative change n/a, error estimate n/a" in _convergence_text(
        {**conv, "relative_change": None, "error_estimate": None}
    )


def test_plan_converge_prints_the_results_error_estimate(
    capsys: pytest.CaptureFixture[str],
) -> None:
    args = ["plan", "--robot", "human_arm_2dof", "--method", "bound", "--converge",
            "--intervals", "8", "--objective", "tau_sq"]  # fmt: skip
    assert main([*args, "--json"]) == 0
    conv = json.loads(capsys.readouterr().out)["methods"]["bound"]["solver"]["convergence"]
    assert main(args) == 0
    text = capsys.readouterr().out
    line = next(x for x in text.splitlines() if "mesh refinement" in x)
    printed = [float(v) for v in re.findall(r"\d+: ([0-9.e+-]+)", line)]
    values = [s["objective"] for s in conv["sequence"]]
    assert printed == pytest.approx(values, rel=1e-5) and len(values) >= 3
    estimate = float(re.search(r"error estimate ([0-9.e+-]+) %", line).group(1))  # type: ignore[union-attr]
    change = float(re.search(r"relative change ([0-9.e+-]+) %", line).group(1))  # type: ignore[union-attr]
    last = abs(values[-1] - values[-2]) / max(abs(values[-1]), abs(values[-2]))
    assert change == pytest.approx(100 * last, rel=5e-3)
    if conv["extrapolated"]:
        assert "(Richardson)" in line
        assert estimate == pytest.approx(100 * _richardson(values), rel=5e-3)
        assert estimate < change  # the tail of a shrinking sequence is below its last step
    else:
        assert "(the last change)" in line and estimate == pytest.approx(change, rel=5e-3)
    assert math.isclose(estimate, 100 * conv["error_estimate"], rel_tol=5e-3)
