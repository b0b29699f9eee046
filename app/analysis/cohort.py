"""Cohorts: per-recording measures from the analysis pipeline, per-group summaries, and tests
between groups (conditions) with effect sizes and a multiple-comparison correction.

Each recording is analysed alone with :func:`app.analysis.analyze_recordings` (nothing is
re-implemented here) and reduced to a few numbers: the number of lifts, the mean lift and A/B/C
phase durations, per muscle the mean onset latency (relative to the lift's start) and the mean
envelope peak, and the template's velocity-peak angle. A measure that cannot be taken is None
with a reason, never 0.

Between every two groups each measure gets one named test: for independent groups Welch's t or
Mann-Whitney U, for paired designs (the same subjects in both groups) the paired t or Wilcoxon's
signed-rank test. ``test="auto"`` chooses by Shapiro-Wilk (on each group, or on the paired
differences): the parametric test when every check has n >= 3 and p > alpha, else the rank test.
Effect sizes: Hedges' g (g_z of the differences when paired) with the parametric tests, the
rank-biserial correlation with the rank tests; positive means the first group's values are
larger. The p-values are corrected over every test reported (Holm by default).
"""

from __future__ import annotations

import itertools
import math
import re
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from app.analysis.pipeline import RecordingAnalysis, analyze_recordings
from app.analysis.template import build_template, consensus_order
from app.errors import BioPlanError
from app.options import Options, OptionsError, check_option, option, option_specs
from app.planning.human_template import HumanTemplate
from app.recordings import bids_entities
from app.recordings.types import Recording

__all__ = [
    "CohortError",
    "CohortOptions",
    "CohortResult",
    "GroupSummary",
    "MeasureSummary",
    "OrderSummary",
    "RecordingMeasures",
    "TestResult",
    "adjust_p",
    "cohort_statistics",
    "compare_groups",
    "recording_measures",
    "subject_of",
    "write_cohort_csv",
]

FloatArray = NDArray[np.float64]
Design = Literal["paired", "independent"]

#: Units of the fixed measures (per-muscle ones are added as ``onset_<muscle>_s`` [s] and
#: ``envelope_peak_<muscle>_<unit>`` [the EMG unit, V after the readers]).
FIXED_MEASURES = {
    "n_lifts": "count",
    "lift_duration_s": "s",
    "phase_A_s": "s",
    "phase_B_s": "s",
    "phase_C_s": "s",
    "peak_velocity_angle_deg": "deg",
}
TESTS = {
    ("independent", "parametric"): "welch_t",
    ("independent", "rank"): "mann_whitney_u",
    ("paired", "parametric"): "paired_t",
    ("paired", "rank"): "wilcoxon",
}
CORRECTIONS = ("holm", "bonferroni", "fdr_bh", "none")
CORRECTION_NAMES = {
    "holm": "Holm step-down (family-wise error)",
    "bonferroni": "Bonferroni (family-wise error)",
    "fdr_bh": "Benjamini-Hochberg (false discovery rate)",
    "none": "no correction",
}


class CohortError(BioPlanError):
    """A cohort that cannot be compared (too few groups, an empty group, a bad option)."""


@dataclass(frozen=True)
class CohortOptions(Options):
    """Options of a cohort comparison; each field (:func:`app.options.option`) holds its
    default, help, unit, choices or range, from which ``bioplan cohort`` builds its flags and
    the API its request model.

    Attributes:
        emg_rate: true EMG sampling rate [Hz] for files that state a wrong one (None: each
            file's own).
        subject_pattern: regular expression searched in a recording's file name when it has no
            BIDS subject; its first group (else the whole match) is the subject, and without a
            match the file stem is.
        paired: ``"auto"`` pairs two groups when they hold the same subjects once each,
            ``"yes"`` pairs by subject (subjects in one group only are left out), ``"no"``
            treats the groups as independent.
        test: ``"auto"`` (Shapiro-Wilk decides), ``"parametric"`` (Welch / paired t) or
            ``"rank"`` (Mann-Whitney U / Wilcoxon).
        alpha: significance level for the tests and the normality checks, in (0, 1).
        correction: multiple-comparison correction over every test reported.
        min_n: fewest values per group (pairs when paired) for a test, >= 2.
    """

    emg_rate: float | None = option(
        None,
        help="true EMG sampling rate for files that state a wrong one",
        unit="Hz",
        gt=0.0,
        metavar="HZ",
        none_means="each file's own",
    )
    subject_pattern: str = option(
        r"sub-([A-Za-z0-9]+)",
        help="regex searched in the file name when it has no BIDS subject; its first group is"
        " the subject, without a match the file stem is",
        metavar="REGEX",
    )
    paired: str = option(
        "auto",
        help="auto: pair two groups holding the same subjects once each; yes: pair by subject;"
        " no: independent groups",
        choices=("auto", "yes", "no"),
    )
    test: str = option(
        "auto",
        help="auto: Shapiro-Wilk on each group (paired: the differences), parametric when all"
        " have n>=3 and p>alpha, else rank; parametric: Welch/paired t; rank: Mann-Whitney"
        " U/Wilcoxon",
        choices=("auto", "parametric", "rank"),
    )
    alpha: float = option(
        0.05,
        help="significance level (tests and normality checks)",
        gt=0.0,
        lt=1.0,
        metavar="A",
    )
    correction: str = option(
        "holm", help="multiple-comparison correction over all tests reported", choices=CORRECTIONS
    )
    min_n: int = option(
        3, help="fewest values per group (pairs when paired) for a test", ge=2, metavar="N"
    )

    def __post_init__(self) -> None:
        try:
            super().__post_init__()
        except OptionsError as exc:  # one error type for a cohort that cannot be compared
            raise CohortError(str(exc)) from None
        try:
            re.compile(self.subject_pattern)
        except re.error as exc:
            raise CohortError(
                f"option subject_pattern {self.subject_pattern!r} is not a regular expression"
                f" ({exc})"
            ) from None

    @classmethod
    def defaults(cls) -> dict[str, Any]:
        """Option name -> the library's default."""
        return {spec.name: spec.default for spec in option_specs(cls)}


# -- per recording ---------------------------------------------------------------------------

#: The fields of :class:`RecordingMeasures` that say which recording it is and whose, in the
#: order the JSON form and the CSV give them.
IDENTITY_FIELDS = ("group", "source", "subject", "subject_from")


@dataclass(frozen=True)
class RecordingMeasures:
    """One recording's numbers.

    Attributes:
        group: its group (condition).
        source: file name.
        subject: subject label; ``subject_from`` says where it came from.
        values: measure -> value (None when it cannot be taken; ``missing`` says why).
        units: measure -> unit.
        missing: measure -> why it is None.
        activation_order: the recording's consensus order over its lifts (empty without EMG).
        lift_orders: each lift's activation order.
        warnings: the analysis' warnings for this recording.
    """

    group: str
    source: str
    subject: str
    subject_from: str
    values: dict[str, float | None]
    units: dict[str, str] = field(default_factory=dict)
    missing: dict[str, str] = field(default_factory=dict)
    activation_order: tuple[str, ...] = ()
    lift_orders: tuple[tuple[str, ...], ...] = ()
    warnings: tuple[str, ...] = ()

    def identity(self) -> dict[str, str]:
        """Which recording this is and whose: the :data:`IDENTITY_FIELDS` by name, in order
        (the first keys of :meth:`to_dict` and the first columns of the CSV)."""
        return {name: getattr(self, name) for name in IDENTITY_FIELDS}

    def to_dict(self) -> dict[str, Any]:
        return self.identity() | {
            "measures": dict(self.values),
            "missing": dict(self.missing),
            "activation_order": list(self.activation_order),
            "warnings": list(self.warnings),
        }


def subject_of(
    source: str, pattern: str, metadata: Mapping[str, Any] | None = None
) -> tuple[str, str]:
    """(subject, where it came from) of a recording: the BIDS subject in its metadata
    (:func:`app.recordings.read_bids`) or file name, else the first group (or whole match)
    of ``pattern`` in the file name, else the file stem."""
    if metadata and metadata.get("bids_path") and metadata.get("subject"):
        return str(metadata["subject"]), "BIDS metadata"
    name = Path(source).name
    sub = bids_entities(name).get("sub")
    if sub:
        return sub, "BIDS file name"
    match = re.search(pattern, name)
    if match:
        label = next((g for g in match.groups() if g), None) or match.group(0)
        return label, f"pattern {pattern}"
    return Path(name).stem, "file stem"


def _mean(values: Sequence[float]) -> float | None:
    return float(np.mean(values)) if values else None


def _lift_measures(analysis: RecordingAnalysis, out: dict[str, float | None]) -> dict[str, str]:
    """Lift and phase durations into ``out``; returns measure -> reason for the missing."""
    missing: dict[str, str] = {}
    lifts = analysis.lifts
    out["n_lifts"] = float(len(lifts))
    out["lift_duration_s"] = _mean([r.lift.duration for r in lifts])
    if not lifts:
        missing["lift_duration_s"] = "no lifts found"
    with_phases = [r for r in lifts if r.phases]
    for name in ("A", "B", "C"):
        key = f"phase_{name}_s"
        out[key] = _mean(
            [
                sum(p.phase.duration for p in r.phases
                    if p.phase.name == name and p.phase.part == "concentric")
                for r in with_phases
            ]
        )  # fmt: skip
        if not lifts:
            missing[key] = "no lifts found"
        elif not with_phases:
            missing[key] = "no phases: the lifts come from EMG bursts (no elbow angle)"
    return missing


def _muscle_measures(
    analysis: RecordingAnalysis,
    muscles: Sequence[str],
    out: dict[str, float | None],
    units: dict[str, str],
) -> dict[str, str]:
    """Onset latency and envelope peak per muscle into ``out``; measure -> reason if None."""
    missing: dict[str, str] = {}
    series = {m.muscle: m for m in analysis.emg}
    for muscle in muscles:
        m = series.get(muscle)
        unit = m.unit if m is not None else _unit_of(muscle, units)
        onset_key, peak_key = f"onset_{muscle}_s", f"envelope_peak_{muscle}_{unit}"
        units[onset_key], units[peak_key] = "s", unit
        latencies = [r.onsets[muscle] for r in analysis.lifts if muscle in r.onsets]
        peaks: list[float] = []
        if m is not None:
            for r in analysis.lifts:
                i0, i1 = np.searchsorted(m.t, [r.lift.start, r.lift.end])
                if i1 > i0:
                    peaks.append(float(np.max(m.envelope[i0:i1])))
        out[onset_key], out[peak_key] = _mean(latencies), _mean(peaks)
        if m is None:
            why = f"no {muscle} EMG channel"
            missing[onset_key] = missing[peak_key] = why
            continue
        if not analysis.lifts:
            missing[onset_key] = missing[peak_key] = "no lifts found"
        elif not latencies:
            missing[onset_key] = f"no {muscle} onset in any lift"
    return missing


def _unit_of(muscle: str, units: Mapping[str, str]) -> str:
    prefix = f"envelope_peak_{muscle}_"
    return next((k[len(prefix) :] for k in units if k.startswith(prefix)), "V")


def _template_measure(template: HumanTemplate, out: dict[str, float | None]) -> dict[str, str]:
    if template.n_lifts > 0:
        out["peak_velocity_angle_deg"] = float(template.peak_velocity_angle_deg)
        return {}
    out["peak_velocity_angle_deg"] = None
    return {"peak_velocity_angle_deg": f"no template kinematics ({template.source})"}


def recording_measures(
    analysis: RecordingAnalysis,
    *,
    group: str,
    template: HumanTemplate | None = None,
    muscles: Sequence[str] | None = None,
    subject_pattern: str = CohortOptions.subject_pattern,
    metadata: Mapping[str, Any] | None = None,
) -> RecordingMeasures:
    """The numbers of one analysed recording.

    Args:
        analysis: one recording's analysis (:func:`analyze_recordings`).
        group: its group name.
        template: its template (default: built from its lifts).
        muscles: the muscles to measure (default: its own); a muscle it lacks gets None.
        subject_pattern: see :class:`CohortOptions`.
        metadata: the recording's metadata (a BIDS subject there wins).
    """
    tpl = template or build_template([r.profile for r in analysis.lifts])
    names = list(muscles) if muscles is not None else [m.muscle for m in analysis.emg]
    values: dict[str, float | None] = {}
    units = dict(FIXED_MEASURES)
    missing = _lift_measures(analysis, values)
    missing |= _template_measure(tpl, values)
    missing |= _muscle_measures(analysis, names, values, units)
    subject, where = subject_of(analysis.source, subject_pattern, metadata)
    orders = tuple(r.activation_order for r in analysis.lifts if r.activation_order)
    return RecordingMeasures(
        group=group,
        source=analysis.source,
        subject=subject,
        subject_from=where,
        values=values,
        units=units,
        missing=missing,
        activation_order=consensus_order(orders),
        lift_orders=orders,
        warnings=tuple(analysis.warnings),
    )


# -- statistics ------------------------------------------------------------------------------


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


@dataclass(frozen=True)
class MeasureSummary:
    """One measure over a group's recordings: n with a value, how many lack it, mean +- SD
    (SD with ddof=1, None for n < 2), median and quartiles (linear interpolation)."""

    n: int
    missing: int
    mean: float | None = None
    sd: float | None = None
    median: float | None = None
    q1: float | None = None
    q3: float | None = None

    @classmethod
    def of(cls, values: Sequence[float | None]) -> MeasureSummary:
        x = np.array([v for v in values if v is not None], dtype=np.float64)
        if not x.size:
            return cls(n=0, missing=len(values))
        q1, med, q3 = np.percentile(x, [25.0, 50.0, 75.0])
        return cls(
            n=int(x.size),
            missing=len(values) - int(x.size),
            mean=float(x.mean()),
            sd=float(x.std(ddof=1)) if x.size > 1 else None,
            median=float(med),
            q1=float(q1),
            q3=float(q3),
        )

    def to_dict(self) -> dict[str, Any]:
        iqr = None if self.q1 is None or self.q3 is None else self.q3 - self.q1
        return asdict(self) | {"iqr": iqr}


@dataclass(frozen=True)
class OrderSummary:
    """Activation orders in a group: the most common recording order and how often it occurs
    (``count`` of ``n`` recordings with an order of at least two muscles; one muscle alone is
    no order), the same over single lifts, and the mean onset latency [s] per muscle (for the
    onset-order diagram)."""

    most_common: tuple[str, ...]
    count: int
    n: int
    orders: dict[str, int]
    lift_most_common: tuple[str, ...]
    lift_count: int
    lift_n: int
    mean_onset_s: dict[str, float]

    @property
    def frequency(self) -> float | None:
        return self.count / self.n if self.n else None

    @property
    def lift_frequency(self) -> float | None:
        return self.lift_count / self.lift_n if self.lift_n else None

    def to_dict(self) -> dict[str, Any]:
        return {
            "most_common": list(self.most_common),
            "count": self.count,
            "n": self.n,
            "frequency": self.frequency,
            "orders": dict(self.orders),
            "lifts": {
                "most_common": list(self.lift_most_common),
                "count": self.lift_count,
                "n": self.lift_n,
                "frequency": self.lift_frequency,
            },
            "mean_onset_s": dict(self.mean_onset_s),
        }


ORDER_SEP = " > "


def _most_common(orders: Sequence[tuple[str, ...]]) -> tuple[tuple[str, ...], int, dict[str, int]]:
    counts = Counter(ORDER_SEP.join(o) for o in orders if len(o) > 1)
    ranked = sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))
    if not ranked:
        return (), 0, {}
    top, count = ranked[0]
    return tuple(top.split(ORDER_SEP)), count, dict(ranked)


def _order_summary(members: Sequence[RecordingMeasures], muscles: Sequence[str]) -> OrderSummary:
    top, count, orders = _most_common([m.activation_order for m in members])
    lifts = [o for m in members for o in m.lift_orders]
    lift_top, lift_count, _ = _most_common(lifts)
    onsets = {}
    for muscle in muscles:
        x = [m.values.get(f"onset_{muscle}_s") for m in members]
        mean = MeasureSummary.of(x).mean
        if mean is not None:
            onsets[muscle] = mean
    return OrderSummary(
        most_common=top,
        count=count,
        n=sum(len(m.activation_order) > 1 for m in members),
        orders=orders,
        lift_most_common=lift_top,
        lift_count=lift_count,
        lift_n=sum(len(o) > 1 for o in lifts),
        mean_onset_s=onsets,
    )


@dataclass(frozen=True)
class GroupSummary:
    """A group: recordings, subjects, every measure summarised, activation orders."""

    name: str
    n: int
    subjects: tuple[str, ...]
    measures: dict[str, MeasureSummary]
    activation_order: OrderSummary

    def to_dict(self) -> dict[str, Any]:
        return {
            "n": self.n,
            "subjects": list(self.subjects),
            "measures": {k: v.to_dict() for k, v in self.measures.items()},
            "activation_order": self.activation_order.to_dict(),
        }


@dataclass(frozen=True)
class TestResult:
    """One measure compared between two groups.

    Attributes:
        measure, unit: what was compared.
        groups: (a, b); effects are a minus b.
        design: ``"paired"`` or ``"independent"``.
        n: values used per group (pairs: both the same).
        test: ``welch_t``, ``mann_whitney_u``, ``paired_t`` or ``wilcoxon``; None if skipped.
        rule: why this test (the normality checks, or the user's choice).
        statistic, p: the test's statistic and two-sided p-value.
        p_adjusted: p after the correction; significant: p_adjusted < alpha.
        effect_name, effect: ``hedges_g`` / ``hedges_g_z`` / ``rank_biserial`` and its value
            (None when undefined, e.g. no spread).
        skipped: why there is no test (too few values, no variation); None when tested.
    """

    __test__ = False  # not a pytest class

    measure: str
    unit: str
    groups: tuple[str, str]
    design: Design
    n: tuple[int, int]
    test: str | None = None
    rule: str = ""
    statistic: float | None = None
    p: float | None = None
    p_adjusted: float | None = None
    significant: bool | None = None
    effect_name: str | None = None
    effect: float | None = None
    skipped: str | None = None

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["groups"], d["n"] = list(self.groups), list(self.n)
        return d


def adjust_p(p: Sequence[float], method: str) -> list[float]:
    """Adjusted p-values: ``holm`` (step-down), ``bonferroni``, ``fdr_bh`` (Benjamini-Hochberg
    step-up) or ``none``; each capped at 1 and kept monotone in the raw p order."""
    try:
        check_option("correction", method, CORRECTIONS)
    except OptionsError as exc:
        raise CohortError(str(exc)) from None
    x = np.asarray(p, dtype=np.float64)
    m = x.size
    if m == 0 or method == "none":
        return [float(v) for v in x]
    if method == "bonferroni":
        return [float(v) for v in np.minimum(1.0, m * x)]
    order = np.argsort(x, kind="stable")
    ranked = x[order]
    if method == "holm":
        adj = np.maximum.accumulate((m - np.arange(m)) * ranked)
    else:  # fdr_bh
        adj = np.minimum.accumulate((m / np.arange(1, m + 1) * ranked)[::-1])[::-1]
    out = np.empty(m)
    out[order] = np.minimum(1.0, adj)
    return [float(v) for v in out]


def _hedges_g(a: FloatArray, b: FloatArray) -> float | None:
    na, nb = a.size, b.size
    pooled = ((na - 1) * a.var(ddof=1) + (nb - 1) * b.var(ddof=1)) / (na + nb - 2)
    if not pooled > 0:
        return None
    j = 1.0 - 3.0 / (4.0 * (na + nb) - 9.0)
    return float(j * (a.mean() - b.mean()) / math.sqrt(pooled))


def _hedges_gz(d: FloatArray) -> float | None:
    sd = float(d.std(ddof=1))
    if not sd > 0:
        return None
    j = 1.0 - 3.0 / (4.0 * (d.size - 1) - 1.0)
    return float(j * d.mean() / sd)


def _rank_biserial_paired(d: FloatArray) -> float | None:
    from scipy.stats import rankdata

    nz = d[d != 0]
    if not nz.size:
        return None
    r = rankdata(np.abs(nz))
    return float((r[nz > 0].sum() - r[nz < 0].sum()) / r.sum())


def _normal(samples: Sequence[FloatArray], alpha: float) -> tuple[bool, str]:
    """Whether every sample passes Shapiro-Wilk (n >= 3, p > alpha), and the rule as text."""
    from scipy.stats import shapiro

    parts: list[str] = []
    ok = True
    for x in samples:
        if x.size < 3:
            return False, f"Shapiro-Wilk needs n >= 3 (n = {x.size}): rank test"
        if np.ptp(x) == 0:
            return False, "a sample without spread: rank test"
        p = float(shapiro(x).pvalue)
        parts.append(f"{p:.3g}")
        ok = ok and p > alpha
    verdict = "all > alpha: parametric" if ok else f"some <= {alpha:g}: rank test"
    return ok, f"Shapiro-Wilk p = {', '.join(parts)} ({verdict})"


def _kind(samples: Sequence[FloatArray], options: CohortOptions) -> tuple[str, str]:
    if options.test != "auto":
        return options.test, f"{options.test} test chosen by the user"
    ok, rule = _normal(samples, options.alpha)
    return ("parametric" if ok else "rank"), rule


def _independent(base: TestResult, a: FloatArray, b: FloatArray, o: CohortOptions) -> TestResult:
    from scipy import stats

    kind, rule = _kind([a, b], o)
    test = TESTS[("independent", kind)]
    if kind == "parametric":
        res = stats.ttest_ind(a, b, equal_var=False)
        name, effect = "hedges_g", _hedges_g(a, b)
    else:
        res = stats.mannwhitneyu(a, b, alternative="two-sided")
        name, effect = "rank_biserial", float(2.0 * res.statistic / (a.size * b.size) - 1.0)
    return _filled(base, test, rule, res, name, effect)


def _paired(base: TestResult, d: FloatArray, o: CohortOptions) -> TestResult:
    from scipy import stats

    kind, rule = _kind([d], o)
    test = TESTS[("paired", kind)]
    if kind == "parametric":
        res = stats.ttest_1samp(d, 0.0)
        name, effect = "hedges_g_z", _hedges_gz(d)
    else:
        res = stats.wilcoxon(d)
        name, effect = "rank_biserial", _rank_biserial_paired(d)
    return _filled(base, test, rule, res, name, effect)


def _filled(
    base: TestResult, test: str, rule: str, res: Any, name: str, effect: float | None
) -> TestResult:
    stat, p = _num(float(res.statistic)), _num(float(res.pvalue))
    if p is None:
        return _skip(base, f"{test} gives no p-value here (no spread)")
    return _replace(
        base, test=test, rule=rule, statistic=stat, p=p, effect_name=name, effect=effect
    )


def _replace(base: TestResult, **changes: Any) -> TestResult:
    return replace(base, **changes)


def _skip(base: TestResult, why: str) -> TestResult:
    return _replace(base, skipped=why)


@dataclass(frozen=True)
class Pairing:
    """How two groups are compared: design, the subjects paired, and why."""

    groups: tuple[str, str]
    design: Design
    subjects: tuple[str, ...]
    why: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "groups": list(self.groups),
            "design": self.design,
            "subjects": list(self.subjects),
            "why": self.why,
        }


def _pairing(
    a: str, b: str, members: Mapping[str, Sequence[RecordingMeasures]], paired: str
) -> Pairing:
    sa = [m.subject for m in members[a]]
    sb = [m.subject for m in members[b]]
    dup = sorted({s for s in sa if sa.count(s) > 1} | {s for s in sb if sb.count(s) > 1})
    common = tuple(s for s in sa if s in set(sb))
    if paired == "no":
        why = "independent (paired=no)"
        if common:
            why += f"; subjects in both groups ({', '.join(common)}) are not independent"
        return Pairing((a, b), "independent", (), why)
    if paired == "yes":
        if dup:
            raise CohortError(
                f"cannot pair groups {a!r} and {b!r}: subject {dup[0]!r} has several"
                " recordings in one group (expected one recording per subject and group)"
            )
        if not common:
            raise CohortError(
                f"cannot pair groups {a!r} and {b!r}: no subject is in both"
                f" ({a}: {', '.join(sa)}; {b}: {', '.join(sb)})"
            )
        left = sorted(set(sa) ^ set(sb))
        why = "paired by subject (paired=yes)" + (
            f"; left out (in one group only): {', '.join(left)}" if left else ""
        )
        return Pairing((a, b), "paired", common, why)
    if not dup and set(sa) == set(sb):
        return Pairing((a, b), "paired", common, "paired (auto): the same subjects, once each")
    if dup:
        why = f"independent (auto): subject {dup[0]!r} has several recordings in one group"
    elif common:
        why = f"independent (auto): only some subjects are in both groups ({', '.join(common)})"
    else:
        why = "independent (auto): no subject is in both groups"
    return Pairing((a, b), "independent", (), why)


def _compare(
    measure: str,
    unit: str,
    pairing: Pairing,
    members: Mapping[str, Sequence[RecordingMeasures]],
    options: CohortOptions,
) -> TestResult:
    a, b = pairing.groups
    if pairing.design == "paired":
        va = {m.subject: m.values.get(measure) for m in members[a]}
        vb = {m.subject: m.values.get(measure) for m in members[b]}
        both = [s for s in pairing.subjects if va.get(s) is not None and vb.get(s) is not None]
        xa = np.array([va[s] for s in both], dtype=np.float64)
        xb = np.array([vb[s] for s in both], dtype=np.float64)
    else:
        xa = _values(members[a], measure)
        xb = _values(members[b], measure)
    base = TestResult(measure, unit, (a, b), pairing.design, (int(xa.size), int(xb.size)))
    what = "pairs" if pairing.design == "paired" else "recordings per group"
    if min(xa.size, xb.size) < options.min_n:
        return _skip(
            base,
            f"too few {what} with a value (n = {xa.size} and {xb.size};"
            f" a test needs at least {options.min_n})",
        )
    if pairing.design == "paired":
        d = xa - xb
        if not np.any(d != 0):
            return _skip(base, "no differences (every pair is equal)")
        return _paired(base, d, options)
    if np.ptp(np.concatenate([xa, xb])) == 0:
        return _skip(base, "no variation (every value is equal)")
    return _independent(base, xa, xb, options)


def _values(members: Sequence[RecordingMeasures], measure: str) -> FloatArray:
    x = [m.values.get(measure) for m in members]
    return np.array([v for v in x if v is not None], dtype=np.float64)


@dataclass(frozen=True)
class CohortResult:
    """Per-recording measures, per-group summaries and tests between groups.

    Attributes:
        recordings: every recording's measures, group by group.
        groups: name -> summary, in the order given.
        tests: one per measure and pair of groups (skipped ones say why).
        pairings: per pair of groups, the design and why.
        units: measure -> unit.
        correction: method, family size, alpha and a sentence saying what was done.
        options: the options used.
        subject_rule: how subjects were found.
        warnings: what the analysis or the comparison assumed.
    """

    recordings: list[RecordingMeasures]
    groups: dict[str, GroupSummary]
    tests: list[TestResult]
    pairings: list[Pairing]
    units: dict[str, str]
    correction: dict[str, Any]
    options: CohortOptions
    subject_rule: str
    warnings: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {
            "recordings": [r.to_dict() for r in self.recordings],
            "groups": {k: g.to_dict() for k, g in self.groups.items()},
            "tests": [t.to_dict() for t in self.tests],
            "pairings": [p.to_dict() for p in self.pairings],
            "correction": dict(self.correction),
            "units": dict(self.units),
            "subject_rule": self.subject_rule,
            "options": self.options.to_dict(),
            "warnings": list(self.warnings),
        }

    def summary(self) -> str:
        """Human-readable report: groups, measures (mean +- SD, median [IQR]), tests."""
        return _summary_text(self)


SUBJECT_RULE = (
    "subject = the BIDS subject (read_bids metadata or a sub-<label> entity in the file name),"
    " else the first group of the pattern {pattern!r} in the file name, else the file stem"
)


def _measure_names(members: Sequence[RecordingMeasures]) -> dict[str, str]:
    units: dict[str, str] = {}
    for m in members:
        for k in m.values:
            units.setdefault(k, m.units.get(k, ""))
    fixed = {k: units.pop(k) for k in FIXED_MEASURES if k in units}
    return fixed | dict(sorted(units.items()))


def _check_groups(groups: Mapping[str, Sequence[Any]]) -> None:
    if len(groups) < 2:
        names = ", ".join(repr(g) for g in groups) or "none"
        raise CohortError(f"a cohort needs at least two groups to compare, got {names}")
    for name, items in groups.items():
        if not str(name).strip():
            raise CohortError("a group has an empty name (expected a condition name)")
        if not items:
            raise CohortError(f"group {name!r} has no recordings (expected at least one)")


def compare_groups(
    recordings: Sequence[RecordingMeasures], options: CohortOptions | None = None
) -> CohortResult:
    """Group summaries and tests between every two groups from per-recording measures.

    Args:
        recordings: measures of every recording; ``group`` says which group each is in
            (groups keep the order of first appearance).
        options: see :class:`CohortOptions` (``emg_rate`` and ``subject_pattern`` are used
            before, when measuring).

    Raises:
        CohortError: fewer than two groups; pairing asked (``paired="yes"``) but impossible.
    """
    options = options or CohortOptions()
    members: dict[str, list[RecordingMeasures]] = {}
    for r in recordings:
        members.setdefault(r.group, []).append(r)
    _check_groups(members)
    units = _measure_names(recordings)
    muscles = sorted({k[len("onset_") : -len("_s")] for k in units if k.startswith("onset_")})
    groups = {
        name: GroupSummary(
            name=name,
            n=len(ms),
            subjects=tuple(dict.fromkeys(m.subject for m in ms)),
            measures={k: MeasureSummary.of([m.values.get(k) for m in ms]) for k in units},
            activation_order=_order_summary(ms, muscles),
        )
        for name, ms in members.items()
    }
    pairings = [
        _pairing(a, b, members, options.paired) for a, b in itertools.combinations(members, 2)
    ]
    tests = [_compare(k, u, p, members, options) for p in pairings for k, u in units.items()]
    tests, correction = _corrected(tests, options)
    warnings = [f"{r.source}: {w}" for r in recordings for w in r.warnings]
    return CohortResult(
        recordings=list(recordings),
        groups=groups,
        tests=tests,
        pairings=pairings,
        units=units,
        correction=correction,
        options=options,
        subject_rule=SUBJECT_RULE.format(pattern=options.subject_pattern),
        warnings=list(dict.fromkeys(warnings)),
    )


def _corrected(
    tests: list[TestResult], options: CohortOptions
) -> tuple[list[TestResult], dict[str, Any]]:
    done = [i for i, t in enumerate(tests) if t.p is not None]
    adjusted = adjust_p([tests[i].p or 0.0 for i in done], options.correction)
    out = list(tests)
    for i, p in zip(done, adjusted, strict=True):
        out[i] = _replace(tests[i], p_adjusted=p, significant=p < options.alpha)
    skipped = len(tests) - len(done)
    statement = (
        f"{CORRECTION_NAMES[options.correction]} over the {len(done)} test(s) reported"
        f" (every measure x every pair of groups); significant: adjusted p < {options.alpha:g}"
        + (f"; {skipped} comparison(s) not tested, each says why" if skipped else "")
    )
    return out, {
        "method": options.correction,
        "family_size": len(done),
        "alpha": options.alpha,
        "statement": statement,
    }


def cohort_statistics(
    recordings_by_group: Mapping[str, Sequence[Recording | RecordingAnalysis]],
    options: CohortOptions | None = None,
) -> CohortResult:
    """Analyse every recording alone, measure it, and compare the groups.

    Args:
        recordings_by_group: group (condition) name -> its recordings (read, or already
            analysed); at least two groups, none empty.
        options: see :class:`CohortOptions`.

    Returns:
        CohortResult.

    Raises:
        CohortError: fewer than two groups, an empty group, impossible pairing.
        RecordingError: a recording the analysis cannot use (names the file).
    """
    options = options or CohortOptions()
    _check_groups(recordings_by_group)
    measures: list[RecordingMeasures] = []
    for group, items in recordings_by_group.items():
        for item in items:
            # Measured at once, so that only one recording's arrays are held at a time.
            if isinstance(item, RecordingAnalysis):
                analysis, tpl, meta = item, None, None
            else:
                result = analyze_recordings([item], emg_rate=options.emg_rate)
                analysis, tpl, meta = result.recordings[0], result.template, item.metadata
                analysis.warnings.extend(w for w in result.warnings if w not in analysis.warnings)
            measures.append(
                recording_measures(
                    analysis,
                    group=group,
                    template=tpl,
                    subject_pattern=options.subject_pattern,
                    metadata=meta,
                )
            )
    return compare_groups(_every_muscle(measures), options)


def _every_muscle(measures: list[RecordingMeasures]) -> list[RecordingMeasures]:
    """Each recording's measures with every muscle of the cohort; one it lacks is None with
    the reason."""
    units: dict[str, str] = {}
    for m in measures:
        units |= {k: u for k, u in m.units.items() if k not in FIXED_MEASURES}
    out = []
    for m in measures:
        values, missing, own = dict(m.values), dict(m.missing), dict(m.units)
        for k in units:
            if k in values:
                continue
            muscle = k.removeprefix("onset_").removesuffix("_s")
            if k.startswith("envelope_peak_"):
                muscle = k.removeprefix("envelope_peak_").rsplit("_", 1)[0]
            values[k], own[k], missing[k] = None, units[k], f"no {muscle} EMG channel"
        keys = [k for k in FIXED_MEASURES if k in values] + sorted(
            k for k in values if k not in FIXED_MEASURES
        )
        out.append(replace(m, values={k: values[k] for k in keys}, units=own, missing=missing))
    return out


# -- text and CSV ----------------------------------------------------------------------------


def _fmt(x: float | None, digits: int = 3) -> str:
    return "-" if x is None else f"{x:.{digits}g}"


def _summary_text(result: CohortResult) -> str:
    lines = [result.subject_rule + "."]
    for name, g in result.groups.items():
        lines.append(f"group {name}: n = {g.n} recording(s), subjects {', '.join(g.subjects)}")
        for k, s in g.measures.items():
            if s.n == 0:
                lines.append(f"  {k}: no value ({s.missing} missing)")
                continue
            lines.append(
                f"  {k}: {_fmt(s.mean)} +- {_fmt(s.sd)}  median {_fmt(s.median)}"
                f" [{_fmt(s.q1)}, {_fmt(s.q3)}]  (n {s.n}"
                + (f", {s.missing} missing)" if s.missing else ")")
            )
        o = g.activation_order
        if o.most_common:
            lines.append(
                f"  activation order: {ORDER_SEP.join(o.most_common)} in {o.count} of {o.n}"
                f" recordings; over lifts {ORDER_SEP.join(o.lift_most_common)} in"
                f" {o.lift_count} of {o.lift_n}"
            )
    for p in result.pairings:
        lines.append(f"{p.groups[0]} vs {p.groups[1]}: {p.why}")
    for t in result.tests:
        head = f"  {t.measure} ({t.groups[0]} vs {t.groups[1]}, {t.design}):"
        if t.skipped:
            lines.append(f"{head} not tested: {t.skipped}")
            continue
        lines.append(
            f"{head} {t.test} = {_fmt(t.statistic)}, p = {_fmt(t.p)},"
            f" adjusted p = {_fmt(t.p_adjusted)}{' *' if t.significant else ''};"
            f" {t.effect_name} = {_fmt(t.effect)}; {t.rule}"
        )
    lines.append(f"correction: {result.correction['statement']}")
    for w in result.warnings:
        lines.append(f"warning: {w}")
    return "\n".join(lines)


def _cell(v: float | None) -> str:
    if v is None:
        return ""
    return str(int(v)) if float(v).is_integer() and abs(v) < 1e15 else repr(float(v))


def write_cohort_csv(result: CohortResult, path: str | Path) -> list[Path]:
    """One row per recording with every measure (empty = missing; the reasons in
    ``missing``) at ``path``, and one row per test at ``<stem>_tests.csv`` beside it."""
    import csv

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    names = list(result.units)
    with out.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow([*IDENTITY_FIELDS, *names, "activation_order", "missing"])
        for r in result.recordings:
            values = [r.values.get(k) for k in names]
            w.writerow(
                list(r.identity().values())
                + [_cell(v) for v in values]
                + [ORDER_SEP.join(r.activation_order),
                   "; ".join(f"{k}: {v}" for k, v in r.missing.items())]
            )  # fmt: skip
    tests = out.with_name(f"{out.stem}_tests.csv")
    cols = ["measure", "unit", "group_a", "group_b", "design", "n_a", "n_b", "test",
            "statistic", "p", "p_adjusted", "significant", "effect_name", "effect", "rule",
            "skipped"]  # fmt: skip
    with tests.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for t in result.tests:
            d = t.to_dict()
            d["group_a"], d["group_b"] = t.groups
            d["n_a"], d["n_b"] = t.n
            w.writerow(["" if d[c] is None else d[c] for c in cols])
    return [out, tests]
