"""``bioplan cohort``: every option changes the result, bad input exits 2 with one line, and the
shared Noraxon curls (neutral vs supinated grip) go through it, checked against scipy.stats on
the per-recording numbers it prints.

The option tests use small synthetic EMG files (``tests/analysis/_synthetic``): three people
(p01-p03) under two conditions, each file with its own noise and burst times.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import stats

from app.cli import main
from tests.analysis import _synthetic as syn
from tests.utils.data import SHARED_DATA

Run = Callable[..., dict[str, Any]]
NORAXON = SHARED_DATA / "noraxon_curls_biceps_brachioradialis"


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[str]]:
    d = tmp_path_factory.mktemp("cli_cohort")
    out: dict[str, list[str]] = {"slow": [], "fast": []}
    for i in range(1, 4):
        for k, (cond, gap) in enumerate((("slow", 5.0), ("fast", 3.5))):
            bursts = [1.0 + j * (gap + 0.2 * i) for j in range(4)]
            path = d / f"p0{i}_{cond}.csv"
            syn.write_emg_csv(path, bursts, seconds=bursts[-1] + 3.0, seed=10 * i + k)
            out[cond].append(str(path))
    return out


@pytest.fixture(scope="module")
def cache() -> dict[tuple[str, ...], dict[str, Any]]:
    return {}


@pytest.fixture()
def run(
    capsys: pytest.CaptureFixture[str],
    files: dict[str, list[str]],
    cache: dict[tuple[str, ...], dict[str, Any]],
) -> Run:
    """``bioplan cohort --group slow ... --group fast ... ARGS --json`` (cached per ARGS)."""

    def go(*args: str) -> dict[str, Any]:
        if args not in cache:
            argv = ["cohort", "--group", "slow", *files["slow"], "--group", "fast", *files["fast"]]
            code = main([*argv, *args, "--json"])
            out = capsys.readouterr().out
            assert code == 0
            cache[args] = json.loads(out)  # exactly one JSON object on stdout
        return cache[args]

    return go


def _test(data: dict[str, Any], measure: str) -> dict[str, Any]:
    found: dict[str, Any] = next(t for t in data["tests"] if t["measure"] == measure)
    return found


def _values(data: dict[str, Any], group: str, measure: str) -> list[float]:
    return [r["measures"][measure] for r in data["recordings"] if r["group"] == group]


def test_json_shape_and_stats_match_scipy(run: Run) -> None:
    data = run("--test", "rank")
    assert set(data) >= {"recordings", "groups", "tests", "correction"}
    assert data["groups"]["slow"]["n"] == 3 and len(data["recordings"]) == 6
    assert data["recordings"][0]["subject"] == "p01_slow"  # no match of the default pattern
    assert data["pairings"][0]["design"] == "independent"
    t = _test(data, "lift_duration_s")
    ref = stats.mannwhitneyu(
        _values(data, "slow", "lift_duration_s"), _values(data, "fast", "lift_duration_s")
    )
    assert t["test"] == "mann_whitney_u" and t["p"] == pytest.approx(ref.pvalue)
    assert "Holm" in data["correction"]["statement"]
    assert data["groups"]["slow"]["activation_order"]["most_common"] == ["deltoid", "biceps"]


def test_emg_rate_changes_the_clock(run: Run) -> None:
    base, fast = run(), run("--emg-rate", "2000")
    a = np.array(_values(base, "slow", "lift_duration_s"))
    b = np.array(_values(fast, "slow", "lift_duration_s"))
    # The files are 1 kHz: read as 2 kHz every burst lasts half as long (the envelope's 6 Hz
    # low-pass then widens it again, so not exactly half), and the lifts change with them.
    assert not np.allclose(a, b, rtol=0.05)
    assert fast["options"]["emg_rate"] == 2000.0


def test_subject_pattern_and_paired(run: Run) -> None:
    pattern = ("--subject-pattern", r"p(\d+)_")
    paired = run(*pattern, "--test", "parametric")
    assert [r["subject"] for r in paired["recordings"]][:3] == ["01", "02", "03"]
    assert paired["pairings"][0]["design"] == "paired"
    t = _test(paired, "lift_duration_s")
    ref = stats.ttest_rel(
        _values(paired, "slow", "lift_duration_s"), _values(paired, "fast", "lift_duration_s")
    )
    assert t["test"] == "paired_t" and t["p"] == pytest.approx(ref.pvalue)
    unpaired = run(*pattern, "--test", "parametric", "--paired", "no")
    assert unpaired["pairings"][0]["design"] == "independent"
    assert _test(unpaired, "lift_duration_s")["test"] == "welch_t"


def test_test_option(run: Run) -> None:
    assert _test(run("--test", "parametric"), "lift_duration_s")["test"] == "welch_t"
    assert _test(run("--test", "rank"), "lift_duration_s")["test"] == "mann_whitney_u"


def test_alpha_changes_the_choice_of_test(run: Run) -> None:
    # Shapiro-Wilk p of the lift durations is about 0.6 and 0.9 in the two groups: above 0.05
    # (Welch), not above 0.95 (rank test).
    low, high = run(), run("--alpha", "0.95")
    assert _test(low, "lift_duration_s")["test"] == "welch_t"
    assert _test(high, "lift_duration_s")["test"] == "mann_whitney_u"
    assert "0.95" in _test(high, "lift_duration_s")["rule"]
    assert high["correction"]["alpha"] == 0.95


def test_correction_changes_the_adjusted_p(run: Run) -> None:
    holm = run("--test", "rank")
    none = run("--test", "rank", "--correction", "none")
    bonf = run("--test", "rank", "--correction", "bonferroni")
    raw = [t["p"] for t in holm["tests"] if t["p"] is not None]
    m = len(raw)
    assert m > 1
    assert [t["p_adjusted"] for t in none["tests"] if t["p"] is not None] == raw
    assert [t["p_adjusted"] for t in bonf["tests"] if t["p"] is not None] == pytest.approx(
        [min(1.0, m * p) for p in raw]
    )
    assert (
        none["correction"]["method"] == "none"
        and "no correction" in (none["correction"]["statement"])
    )


def test_min_n_skips_tests(run: Run) -> None:
    data = run("--min-n", "4")
    assert all(t["p"] is None and "at least 4" in t["skipped"] for t in data["tests"])


def test_plot_and_csv_write_files(run: Run, tmp_path: Path) -> None:
    data = run("--plot", str(tmp_path / "fig"), "--csv", str(tmp_path / "c.csv"))
    names = {Path(p).name for p in data["plots"]}
    assert {"cohort_onset_order.html", "cohort_lift_duration_s.html", "plotly.min.js"} <= names
    rows = (tmp_path / "c.csv").read_text(encoding="utf-8").splitlines()
    assert len(rows) == 1 + 6 and rows[0].startswith("group,source,subject")
    tests = (tmp_path / "c_tests.csv").read_text(encoding="utf-8").splitlines()
    assert len(tests) == 1 + len(data["tests"])


def test_text_output_without_json(
    capsys: pytest.CaptureFixture[str], files: dict[str, list[str]]
) -> None:
    code = main(["cohort", "--group", "s", *files["slow"], "--group", "f", *files["fast"]])
    out = capsys.readouterr().out
    assert code == 0 and "group s: n = 3" in out and "correction: Holm" in out
    with pytest.raises(json.JSONDecodeError):
        json.loads(out)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--group", "a", "{0}"], "at least two --group"),
        (["--group", "a", "{0}", "--group", "b", "nope.csv"], "nope.csv: no such file"),
        (["--group", "a", "{0}", "--group", "b"], "'b' has no files"),
        (["--group", "a", "{0}", "--group", "a", "{1}"], "given twice"),
        (["--group", "a", "{0}", "--group", "b", "{1}", "--alpha", "2"], "alpha"),
        (["--group", "a", "{0}", "--group", "b", "{1}", "--subject-pattern", "("], "regular"),
        (["--group", "a", "{0}", "--group", "b", "{1}", "--paired", "yes"], "cannot pair"),
        (["--group", "a", "{0}", "--group", "b", "{1}", "--test", "t"], "invalid choice"),
        (["--group", "a", "{0}", "--group", "b", "{1}", "--min-n", "1"], "min_n"),
        (["a.csv"], "--group"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    capsys: pytest.CaptureFixture[str], files: dict[str, list[str]], argv: list[str], message: str
) -> None:
    args = [a.format(files["slow"][0], files["fast"][0]) for a in argv]
    try:
        code = main(["cohort", *args, "--json"])
    except SystemExit as exc:  # argparse's own errors (choices, a missing --group)
        code = int(exc.code or 0)
    assert code == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    err = captured.err.strip()
    assert "\n" not in err and message in err


@pytest.mark.skipif(not NORAXON.is_dir(), reason=f"shared data not found at {NORAXON}")
def test_noraxon_neutral_vs_supinated(capsys: pytest.CaptureFixture[str]) -> None:
    neutral = [NORAXON / "2023-04-20-15-06_BR_posredni.csv", NORAXON / "NT-01.mat"]
    supinated = [NORAXON / "2023-04-20-15-07_BR_podchwyt.csv", NORAXON / "SP-01.mat"]
    argv = ["cohort", "--group", "neutral", *map(str, neutral)]
    argv += ["--group", "supinated", *map(str, supinated), "--emg-rate", "2000", "--json"]
    assert main(argv) == 0
    data = json.loads(capsys.readouterr().out)
    assert [r["subject"] for r in data["recordings"]] == [
        "2023-04-20-15-06_BR_posredni", "NT-01", "2023-04-20-15-07_BR_podchwyt", "SP-01"
    ]  # fmt: skip
    n_lifts = [r["measures"]["n_lifts"] for r in data["recordings"]]
    assert n_lifts[1] == n_lifts[3] == 10  # the .mat files hold 10 curls each (README)
    for r in data["recordings"]:
        m = r["measures"]
        assert m["phase_A_s"] is None and "EMG bursts" in r["missing"]["phase_A_s"]
        assert m["peak_velocity_angle_deg"] is None  # no elbow angle: no template kinematics
    csv_rows = [r for r in data["recordings"] if r["source"].endswith(".csv")]
    assert all("biceps" in r["missing"]["onset_biceps_s"] for r in csv_rows)
    # Two recordings per group: below the default minimum of 3, no test, said so.
    assert all(t["p"] is None and "too few" in t["skipped"] for t in data["tests"])
    assert data["groups"]["neutral"]["activation_order"]["lifts"]["most_common"] == [
        "biceps", "forearm"
    ]  # fmt: skip
    # With the .mat files as subject 01 and the CSVs as subject BR: a paired design, 2 pairs.
    argv += [r"--subject-pattern=-(\d+)\.mat|_(BR)_", "--min-n", "2"]  # "=": it starts with "-"
    assert main(argv) == 0
    paired = json.loads(capsys.readouterr().out)
    assert paired["pairings"][0]["design"] == "paired"
    t = _test(paired, "onset_forearm_s")
    a = _values(paired, "neutral", "onset_forearm_s")
    b = _values(paired, "supinated", "onset_forearm_s")
    assert t["test"] == "wilcoxon" and t["p"] == pytest.approx(stats.wilcoxon(a, b).pvalue)


def test_flags_come_from_the_options() -> None:
    from dataclasses import fields

    from app.analysis.cohort import CohortOptions
    from app.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    cohort = sub.choices["cohort"]
    flags = {a.dest: a for a in cohort._actions if a.option_strings}
    for f in fields(CohortOptions):
        action = flags[f.name]
        assert action.default == f.default and f.metadata["help"] in (action.help or "")
        assert action.choices == f.metadata.get("choices")
