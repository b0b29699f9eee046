"""Cohort statistics, checked against scipy.stats on the per-recording numbers and against hand
computations (Holm, Bonferroni, Benjamini-Hochberg, effect sizes by brute force).

Most tests build per-recording measures directly (cheap); one runs synthetic curls (EMG and an
elbow goniometer) through the analysis pipeline and checks the measures against its lifts.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest
from scipy import stats

from app.analysis.cohort import (
    CohortError,
    CohortOptions,
    RecordingMeasures,
    adjust_p,
    cohort_statistics,
    compare_groups,
    recording_measures,
    subject_of,
)
from app.analysis.pipeline import analyze_recordings
from app.recordings.types import Channel, Recording
from tests.analysis import _synthetic as syn


def _rec(
    group: str, subject: str, order: Sequence[str] = (), **values: float | None
) -> RecordingMeasures:
    return RecordingMeasures(
        group=group,
        source=f"{subject}_{group}.csv",
        subject=subject,
        subject_from="test",
        values=dict(values),
        units={k: "s" for k in values},
        missing={k: "absent in the test" for k, v in values.items() if v is None},
        activation_order=tuple(order),
        lift_orders=(tuple(order),) if order else (),
    )


def _cohort(groups: dict[str, Sequence[float | None]], paired: bool = False) -> list[Any]:
    out = []
    for name, xs in groups.items():
        for i, x in enumerate(xs):
            subject = f"s{i}" if paired else f"{name}{i}"
            out.append(_rec(name, subject, x=x))
    return out


RNG = np.random.default_rng(7)
A = RNG.normal(10.0, 2.0, 9)
B = RNG.normal(12.5, 2.5, 8)


def _only(result: Any, measure: str = "x") -> Any:
    (test,) = [t for t in result.tests if t.measure == measure]
    return test


def test_welch_t_and_hedges_g_match_scipy_and_the_formula() -> None:
    result = compare_groups(_cohort({"a": A, "b": B}), CohortOptions(test="parametric"))
    t = _only(result)
    ref = stats.ttest_ind(A, B, equal_var=False)
    assert (t.test, t.design, t.n) == ("welch_t", "independent", (9, 8))
    assert t.statistic == pytest.approx(ref.statistic, rel=1e-12)
    assert t.p == pytest.approx(ref.pvalue, rel=1e-12)
    sp = np.sqrt((8 * A.var(ddof=1) + 7 * B.var(ddof=1)) / 15)
    g = (1 - 3 / (4 * 17 - 9)) * (A.mean() - B.mean()) / sp
    assert (t.effect_name, t.effect) == ("hedges_g", pytest.approx(g, rel=1e-12))
    assert t.p_adjusted == pytest.approx(t.p)  # a family of one


def test_mann_whitney_and_rank_biserial_match_scipy_and_brute_force() -> None:
    result = compare_groups(_cohort({"a": A, "b": B}), CohortOptions(test="rank"))
    t = _only(result)
    ref = stats.mannwhitneyu(A, B, alternative="two-sided")
    assert t.test == "mann_whitney_u"
    assert t.statistic == pytest.approx(ref.statistic)
    assert t.p == pytest.approx(ref.pvalue, rel=1e-12)
    wins = sum(np.sign(a - b) for a in A for b in B)  # (#a>b - #a<b) / (na nb)
    assert (t.effect_name, t.effect) == ("rank_biserial", pytest.approx(wins / (9 * 8)))


PA = np.array([5.1, 6.3, 4.8, 7.2, 5.9, 6.6, 5.4, 6.1])
PB = PA + np.array([0.4, 0.9, -0.2, 1.1, 0.7, 0.3, 0.8, 0.5])


def test_paired_t_and_g_z_match_scipy_and_the_formula() -> None:
    result = compare_groups(
        _cohort({"pre": PA, "post": PB}, paired=True), CohortOptions(test="parametric")
    )
    assert result.pairings[0].design == "paired"
    assert "same subjects" in result.pairings[0].why
    t = _only(result)
    ref = stats.ttest_rel(PA, PB)
    assert (t.test, t.n) == ("paired_t", (8, 8))
    assert t.statistic == pytest.approx(ref.statistic, rel=1e-12)
    assert t.p == pytest.approx(ref.pvalue, rel=1e-12)
    d = PA - PB
    gz = (1 - 3 / (4 * 7 - 1)) * d.mean() / d.std(ddof=1)
    assert (t.effect_name, t.effect) == ("hedges_g_z", pytest.approx(gz, rel=1e-12))


def test_wilcoxon_and_matched_rank_biserial_match_scipy() -> None:
    result = compare_groups(
        _cohort({"pre": PA, "post": PB}, paired=True), CohortOptions(test="rank")
    )
    t = _only(result)
    ref = stats.wilcoxon(PA, PB)
    assert t.test == "wilcoxon"
    assert t.statistic == pytest.approx(ref.statistic)
    assert t.p == pytest.approx(ref.pvalue, rel=1e-12)
    d = PA - PB
    ranks = stats.rankdata(np.abs(d))
    assert t.effect == pytest.approx((ranks[d > 0].sum() - ranks[d < 0].sum()) / ranks.sum())
    assert t.effect == pytest.approx(-1 + 2 * ranks[d > 0].sum() / ranks.sum())


def test_pairing_follows_the_subjects_in_any_order() -> None:
    recs = _cohort({"pre": PA, "post": PB}, paired=True)
    shuffled = recs[:8] + recs[8:][::-1]  # the second group listed in reverse subject order
    t = _only(compare_groups(shuffled, CohortOptions(test="parametric")))
    assert t.p == pytest.approx(stats.ttest_rel(PA, PB).pvalue, rel=1e-12)


def test_auto_chooses_by_shapiro_wilk() -> None:
    normal = compare_groups(_cohort({"a": A, "b": B}))
    t = _only(normal)
    pa, pb = stats.shapiro(A).pvalue, stats.shapiro(B).pvalue
    assert min(pa, pb) > 0.05 and t.test == "welch_t"
    assert f"{pa:.3g}" in t.rule and f"{pb:.3g}" in t.rule
    skewed = np.array([1.0, 1.1, 1.2, 1.15, 1.05, 9.0, 1.3, 1.25])
    assert stats.shapiro(skewed).pvalue < 0.05
    t = _only(compare_groups(_cohort({"a": A, "b": skewed})))
    assert t.test == "mann_whitney_u" and "rank test" in t.rule
    d = _only(compare_groups(_cohort({"pre": PA, "post": PB}, paired=True)))
    assert stats.shapiro(PA - PB).pvalue > 0.05 and d.test == "paired_t"


P = [0.01, 0.04, 0.03, 0.005]


def test_corrections_against_hand_computation() -> None:
    # Holm: sorted 0.005, 0.01, 0.03, 0.04 times 4, 3, 2, 1 = 0.02, 0.03, 0.06, 0.04 -> running
    # maximum 0.02, 0.03, 0.06, 0.06, back in the given order.
    assert adjust_p(P, "holm") == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert adjust_p(P, "bonferroni") == pytest.approx([0.04, 0.16, 0.12, 0.02])
    # BH: 0.005*4/1, 0.01*4/2, 0.03*4/3, 0.04*4/4 = 0.02, 0.02, 0.04, 0.04 (running minimum from
    # the top changes nothing).
    assert adjust_p(P, "fdr_bh") == pytest.approx([0.02, 0.04, 0.04, 0.02])
    assert adjust_p(P, "fdr_bh") == pytest.approx(stats.false_discovery_control(P))
    assert adjust_p(P, "none") == P
    assert adjust_p([0.5, 0.6], "bonferroni") == [1.0, 1.0]


def test_holm_is_applied_over_every_test_and_said() -> None:
    groups = {"a": A, "b": B, "c": A + 1.0}
    recs = []
    for name, xs in groups.items():
        for i, x in enumerate(xs):
            recs.append(_rec(name, f"{name}{i}", x=float(x), y=float(x) ** 2))
    result = compare_groups(recs, CohortOptions(test="parametric"))
    assert [p.groups for p in result.pairings] == [("a", "b"), ("a", "c"), ("b", "c")]
    assert len(result.tests) == 6
    raw = [t.p for t in result.tests]
    m = len(raw)
    order = np.argsort(raw)
    hand = np.empty(m)
    running = 0.0
    for k, i in enumerate(order):
        running = max(running, min(1.0, (m - k) * raw[i]))
        hand[i] = running
    assert [t.p_adjusted for t in result.tests] == pytest.approx(hand)
    assert [t.significant for t in result.tests] == [bool(h < 0.05) for h in hand]
    assert result.correction["method"] == "holm" and result.correction["family_size"] == 6
    assert "Holm" in result.correction["statement"]
    for t, (a, b) in zip(result.tests, [("a", "b")] * 2 + [("a", "c")] * 2 + [("b", "c")] * 2,
                         strict=True):  # fmt: skip
        xa = np.array(groups[a], dtype=float)
        xb = np.array(groups[b], dtype=float)
        if t.measure == "y":
            xa, xb = xa**2, xb**2
        assert t.p == pytest.approx(stats.ttest_ind(xa, xb, equal_var=False).pvalue, rel=1e-9)


def test_too_few_values_say_so_instead_of_a_p_value() -> None:
    result = compare_groups(_cohort({"a": [1.0, 2.0], "b": [3.0, 4.0, 5.0]}))
    t = _only(result)
    assert t.p is None and t.test is None and t.p_adjusted is None
    assert t.skipped is not None and "too few" in t.skipped and "n = 2 and 3" in t.skipped
    assert result.correction["family_size"] == 0
    flat = _only(compare_groups(_cohort({"a": [1.0] * 3, "b": [1.0] * 3})))
    assert flat.skipped is not None and "equal" in flat.skipped


def test_missing_values_are_left_out_and_summaries_match_numpy() -> None:
    xs: list[float | None] = [1.0, None, 3.5, 2.0, 8.0]
    result = compare_groups(_cohort({"a": xs, "b": [2.0, 3.0, 4.0]}))
    s = result.groups["a"].measures["x"]
    x = np.array([1.0, 3.5, 2.0, 8.0])
    assert (s.n, s.missing) == (4, 1)
    assert s.mean == pytest.approx(x.mean()) and s.sd == pytest.approx(x.std(ddof=1))
    assert s.median == pytest.approx(np.median(x))
    assert s.q3 - s.q1 == pytest.approx(stats.iqr(x))
    assert s.to_dict()["iqr"] == pytest.approx(stats.iqr(x))
    assert _only(result).n == (4, 3)
    row = next(r for r in result.to_dict()["recordings"] if r["measures"]["x"] is None)
    assert row["missing"]["x"]  # a reason, not a fake 0


def test_activation_order_most_common_and_frequency() -> None:
    recs = [
        _rec("a", "1", ("biceps", "deltoid"), x=1.0),
        _rec("a", "2", ("biceps", "deltoid"), x=2.0),
        _rec("a", "3", ("deltoid", "biceps"), x=3.0),
        _rec("b", "4", ("deltoid", "biceps"), x=1.0),
    ]
    o = compare_groups(recs).groups["a"].activation_order
    assert o.most_common == ("biceps", "deltoid") and (o.count, o.n) == (2, 3)
    assert o.frequency == pytest.approx(2 / 3)
    assert o.orders == {"biceps > deltoid": 2, "deltoid > biceps": 1}


def test_paired_options() -> None:
    recs = _cohort({"pre": PA, "post": PB}, paired=True)
    assert compare_groups(recs, CohortOptions(paired="no")).pairings[0].design == "independent"
    part = recs[:8] + [
        r if r.subject != "s0" else _rec("post", "other", x=r.values["x"]) for r in recs[8:]
    ]
    assert compare_groups(part).pairings[0].design == "independent"  # auto: not the same set
    yes = compare_groups(part, CohortOptions(paired="yes", test="parametric"))
    assert yes.pairings[0].design == "paired" and "s0" not in yes.pairings[0].subjects
    assert _only(yes).p == pytest.approx(stats.ttest_rel(PA[1:], PB[1:]).pvalue, rel=1e-12)
    dup = [*recs, _rec("pre", "s1", x=1.0)]
    assert compare_groups(dup).pairings[0].design == "independent"
    with pytest.raises(CohortError, match="several recordings"):
        compare_groups(dup, CohortOptions(paired="yes"))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"paired": "maybe"}, "paired"),
        ({"test": "t"}, "test"),
        ({"correction": "sidak"}, "correction"),
        ({"alpha": 1.5}, "alpha"),
        ({"min_n": 1}, "min_n"),
        ({"emg_rate": -1.0}, "emg_rate"),
        ({"subject_pattern": "sub-("}, "subject_pattern"),
    ],
)
def test_bad_options_name_the_field(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(CohortError, match=match):
        CohortOptions(**kwargs)


def test_groups_are_checked() -> None:
    with pytest.raises(CohortError, match="at least two groups"):
        compare_groups(_cohort({"a": [1.0, 2.0, 3.0]}))
    with pytest.raises(CohortError, match="'b' has no recordings"):
        cohort_statistics({"a": [_curls("x.csv", seed=0)], "b": []})


def test_subject_of() -> None:
    pat = CohortOptions().subject_pattern
    assert subject_of("sub-07_task-curl_emg.edf", pat) == ("07", "BIDS file name")
    assert subject_of("x.edf", pat, {"subject": "3", "bids_path": "sub-3/x"})[0] == "3"
    assert subject_of("x.csv", pat, {"subject": "TEST"}) == ("x", "file stem")  # not BIDS
    assert subject_of("p12_neutral.csv", r"p(\d+)") == ("12", r"pattern p(\d+)")
    assert subject_of("NT-01.mat", r"-\d+") == ("-01", r"pattern -\d+")


def _curls(name: str, seed: int, n_lifts: int = 3) -> Recording:
    """Synthetic curls at 1 kHz: an elbow goniometer and biceps/deltoid EMG bursts with the
    deltoid 0.1 s before the biceps."""
    rate = 1000.0
    t, elbow = syn.elbow_curls(n_lifts, rate)
    rng = np.random.default_rng(seed)
    cycle = syn.RISE_S + syn.HOLD_S + syn.LOWER_S + syn.REST_S
    channels = {"elbow_flex": Channel("elbow_flex", np.deg2rad(elbow), rate, "rad", "angle")}
    for muscle, lead in (("biceps", 0.0), ("deltoid", 0.1)):
        gain = np.full_like(t, 0.05)
        for k in range(n_lifts):
            gain += np.exp(-(((t - syn.REST_S - k * cycle + lead - 0.3) / 0.3) ** 2))
        data = 1e-4 * gain * rng.standard_normal(len(t))
        channels[muscle] = Channel(muscle, data, rate, "V", "emg", site=muscle)  # type: ignore[arg-type]
    return Recording(channels, source=name, format="test")


def test_measures_come_from_the_pipeline() -> None:
    rec = _curls("sub-01_curl.csv", seed=1)
    result = analyze_recordings([rec])
    analysis = result.recordings[0]
    m = recording_measures(analysis, group="g", template=result.template)
    lifts = analysis.lifts
    assert m.subject == "01" and m.values["n_lifts"] == len(lifts) == 3
    assert m.values["lift_duration_s"] == pytest.approx(np.mean([r.lift.duration for r in lifts]))
    a_dur = [
        sum(
            p.phase.duration
            for p in r.phases
            if (p.phase.name, p.phase.part) == ("A", "concentric")
        )
        for r in lifts
    ]
    assert m.values["phase_A_s"] == pytest.approx(np.mean(a_dur))
    assert m.values["peak_velocity_angle_deg"] == pytest.approx(
        result.template.peak_velocity_angle_deg
    )
    onsets = [r.onsets["biceps"] for r in lifts if "biceps" in r.onsets]
    assert m.values["onset_biceps_s"] == pytest.approx(np.mean(onsets))
    assert m.values["envelope_peak_biceps_V"] is not None and m.values["envelope_peak_biceps_V"] > 0
    assert m.activation_order == ("deltoid", "biceps")
    assert not m.missing


def test_cohort_statistics_runs_the_pipeline_per_recording() -> None:
    groups = {
        "a": [_curls(f"sub-0{i}_a.csv", seed=i) for i in range(1, 4)],
        "b": [_curls(f"sub-0{i}_b.csv", seed=10 + i, n_lifts=2) for i in range(1, 4)],
    }
    result = cohort_statistics(groups, CohortOptions(test="rank"))
    assert result.pairings[0].design == "paired"
    assert [r.values["n_lifts"] for r in result.recordings] == [3, 3, 3, 2, 2, 2]
    t = next(t for t in result.tests if t.measure == "lift_duration_s")
    xa = [r.values["lift_duration_s"] for r in result.recordings[:3]]
    xb = [r.values["lift_duration_s"] for r in result.recordings[3:]]
    assert t.p == pytest.approx(stats.wilcoxon(xa, xb).pvalue)
    assert result.groups["a"].activation_order.most_common == ("deltoid", "biceps")
    d = result.to_dict()
    assert set(d) >= {"recordings", "groups", "tests", "correction"}
    assert d["groups"]["a"]["n"] == 3


def test_plots_draw_every_recording_and_the_onset_order(tmp_path: Any) -> None:
    from app.analysis.cohort_plots import _measure_figure, _onset_figure, write_cohort_plots

    recs = [
        _rec("a", "1", ("biceps", "deltoid"), x=1.0, onset_biceps_s=-0.1, onset_deltoid_s=0.2),
        _rec("a", "2", ("biceps", "deltoid"), x=2.0, onset_biceps_s=-0.3, onset_deltoid_s=0.1),
        _rec("b", "3", ("deltoid", "biceps"), x=None, onset_biceps_s=0.4, onset_deltoid_s=0.0),
    ]
    result = compare_groups(recs)
    fig = _measure_figure(result, "x")
    assert [list(t.y) for t in fig.data] == [[1.0, 2.0], []]
    assert [t.name for t in fig.data] == ["a (n=2)", "b (n=0)"]
    onset = _onset_figure(result)
    biceps = next(t for t in onset.data if t.name == "biceps")
    assert list(biceps.x) == pytest.approx([-0.2, 0.4]) and list(biceps.y) == ["a", "b"]
    assert "biceps > deltoid in 2/2" in onset.layout.title.text
    written = write_cohort_plots(result, tmp_path / "fig")
    names = [p.name for p in written]
    assert "cohort_x.html" in names and "cohort_onset_order.html" in names
    assert names[-1] == "plotly.min.js" and all(p.is_file() for p in written)


def test_csv_and_json_lead_with_which_recording_and_whose(tmp_path: Any) -> None:
    import csv

    from app.analysis.cohort import write_cohort_csv

    recs = _cohort({"a": [1.5, None], "b": [3.25, 4.0]})
    result = compare_groups(recs)
    path, _ = write_cohort_csv(result, tmp_path / "cohort.csv")
    with path.open(newline="", encoding="utf-8") as fh:
        header, *rows = list(csv.reader(fh))
    ids = ["group", "source", "subject", "subject_from"]
    assert header == [*ids, "x", "activation_order", "missing"]
    assert [row[:4] for row in rows] == [
        [r.group, r.source, r.subject, r.subject_from] for r in recs
    ]
    assert [row[4] for row in rows] == ["1.5", "", "3.25", "4"]
    assert rows[1][-1] == "x: absent in the test"
    d = recs[0].to_dict()
    assert list(d) == [*ids, "measures", "missing", "activation_order", "warnings"]
    assert [d[k] for k in ids] == ["a", "a0_a.csv", "a0", "test"]
