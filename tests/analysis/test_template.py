"""Honest templates: where every number comes from, the peak as a fraction of each lift's
range mapped onto the robot's stroke, edge peaks rejected, EMG timing only against tops the
elbow defined; checked on synthetic curls with a known peak and on the real recordings."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from app.analysis import analyze_recordings, build_template, detect_lifts, lift_profile
from app.analysis.segmentation import Lift
from app.planning.human_template import HumanTemplate, joint_on_stroke
from app.recordings import Channel, Recording
from tests.analysis import _synthetic as syn
from tests.analysis._data import noraxon_recording, pyomeca_c3d


def _angle_recording(rate: float = 100.0, n_lifts: int = 3) -> Recording:
    _, y = syn.elbow_curls(n_lifts, rate)
    ch = Channel("elbow_flexion", np.deg2rad(y), rate, "rad", "angle")
    return Recording({"elbow_flexion": ch}, source="curls.mot", format="mot")


def test_peak_as_a_fraction_of_the_lifts_range_matches_the_closed_form() -> None:
    result = analyze_recordings([_angle_recording()])
    tpl = result.template
    expected = syn.peak_range_fraction()  # where the skewed cycloid is fastest
    assert tpl.n_lifts == 3 and tpl.source == "3 lift(s) with kinematics"
    assert tpl.peak_velocity_range_fraction == pytest.approx(expected, abs=0.02)
    # Absolute angles are kept and reported too.
    span = syn.TOP_DEG - syn.REST_DEG
    assert tpl.peak_velocity_angle_deg == pytest.approx(syn.REST_DEG + expected * span, abs=2.5)
    assert tpl.lift_range_deg == pytest.approx((syn.REST_DEG, syn.TOP_DEG), abs=1.0)
    assert tpl.files == ("curls.mot",) and not tpl.assumptions


def test_the_fraction_is_placed_on_the_robot_stroke_not_the_absolute_angle() -> None:
    """A template from 40 -> 127 deg lifts peaking at 67 deg (31 % of the range): on a
    0 -> 150 deg task the peak goes to 31 % of the stroke (46.6 deg), not to 67 deg."""
    tpl = HumanTemplate(
        peak_velocity_angle_deg=67.0,
        peak_velocity_range_fraction=(67.0 - 40.0) / (127.0 - 40.0),
        n_lifts=1,
        source="1 lift(s) with kinematics",
    )
    q0, q1 = 0.0, math.radians(150.0)
    assert math.degrees(tpl.peak_joint_angle(q0, q1)) == pytest.approx(150 * 27 / 87, abs=1e-9)
    # Any stroke, either direction: the same fraction of it.
    assert tpl.peak_joint_angle(1.0, -0.5) == pytest.approx(1.0 - 1.5 * 27 / 87)
    # The paper default has no lifts: its absolute 62 deg, placed as before.
    default = HumanTemplate()
    assert default.peak_velocity_range_fraction is None and default.is_paper_default
    assert default.peak_joint_angle(q0, q1) == joint_on_stroke(62.0, q0, q1)


def test_template_json_round_trip_and_old_files_still_load() -> None:
    tpl = build_template(
        [lift_profile(lift, **arrays) for lift, arrays in _profiles()],
        files=["a.csv"],
        assumptions=["video size unknown"],
    )
    again = HumanTemplate.from_json(tpl.to_json())
    assert again == tpl
    old = {"peak_velocity_angle_deg": 70.0, "n_lifts": 4, "source": "x.c3d"}
    assert HumanTemplate.from_dict(old).peak_velocity_range_fraction is None
    with pytest.raises(ValueError, match="peak_velocity_range_fraction"):
        HumanTemplate(peak_velocity_range_fraction=1.2)


def _profiles() -> list[tuple[Lift, dict[str, np.ndarray]]]:
    rec = _angle_recording()
    y = rec.channels["elbow_flexion"].data
    t = np.arange(len(y)) / 100.0
    v = np.gradient(y, t)
    a = np.gradient(v, t)
    lifts = detect_lifts(y, t)
    arrays = {"t": t, "elbow": y, "elbow_velocity": v, "elbow_acceleration": a}
    return [(lift, arrays) for lift in lifts]


def test_a_velocity_peak_on_the_first_sample_is_rejected() -> None:
    """A lift cut so that it starts already at full speed: no peak, no kinematics."""
    t = np.linspace(0.0, 1.0, 101)
    y = 0.2 + 1.5 * np.sin(np.pi / 2 * t)  # fastest at t = 0, slowest at the top
    v = np.gradient(y, t)
    lift = Lift(0.0, 1.0, 1.0, "angle", float(y[0]), float(y[-1]), float(y[-1]))
    prof = lift_profile(lift, t=t, elbow=y, elbow_velocity=v, elbow_acceleration=np.gradient(v, t))
    assert not prof.has_kinematics
    assert prof.rejected == "the velocity peaks on the lift's first sample"
    tpl = build_template([prof])
    assert tpl.is_paper_default and "first sample" in tpl.source


def test_emg_only_template_says_paper_default_and_has_no_emg_timing() -> None:
    result = analyze_recordings([noraxon_recording("SP-01")])
    tpl = result.template
    assert tpl.is_paper_default and tpl.source == "paper default: no kinematics in these files"
    assert tpl.emg_lifts == 10 and tpl.activation_order  # onsets still order the muscles
    assert tpl.emg_peak_time_fraction == {}  # tops are the EMG's own peaks
    assert any("paper's defaults" in w for w in result.warnings)


def test_no_lifts_at_all_is_said_too() -> None:
    t = np.arange(500) / 100.0
    flat = Channel("elbow_flexion", np.full(500, 0.3) + 1e-4 * np.sin(t), 100.0, "rad", "angle")
    result = analyze_recordings([Recording({"elbow_flexion": flat}, "still.mot", "mot")])
    assert result.template.source == "paper default: no lifts found in these files"
    assert result.warnings and "paper's defaults" in result.warnings[0]


def test_the_source_says_how_many_lifts_were_left_out_and_why() -> None:
    lift = Lift(0.0, 1.0, 2.0, "angle", start_angle=0.2, top_angle=2.2, end_angle=0.2)
    t = np.linspace(0.0, 2.0, 201)
    elbow = 0.2 + 2.0 * np.sin(np.pi * t / 2.0) ** 2
    vel, acc = np.gradient(elbow, t), np.gradient(np.gradient(elbow, t), t)
    prof = lift_profile(lift, t=t, elbow=elbow, elbow_velocity=vel, elbow_acceleration=acc)
    assert prof.has_kinematics
    plain = build_template([prof, prof])
    assert plain.source == "2 lift(s) with kinematics"
    some = build_template([prof], left_out={"low pose quality": 1})
    assert some.source == "1 lift(s) with kinematics; 1 lift(s) left out (low pose quality)"
    assert some.n_lifts == 1
    none = build_template([], left_out={"low pose quality": 3})
    assert none.is_paper_default
    assert none.source == "paper default: every lift found was left out (3 for low pose quality)"
    assert build_template([], left_out={"low pose quality": 0}).source == (
        "paper default: no lifts found in these files"
    )


def test_pyomeca_lifts_start_when_the_elbow_moves_and_peaks_map_by_range() -> None:
    """The real trial (31->114, 40->127, 38->138 deg with the old 5 %-of-range start): the
    speed rule starts each lift earlier and lower, the peak lies inside each range, and the
    template's fraction is the mean of the per-lift fractions."""
    result = analyze_recordings([pyomeca_c3d()], load_mass=2.0)
    lifts = result.lifts
    assert len(lifts) == 3
    old_starts = (31.0, 40.0, 38.0)
    fractions = []
    for report, old in zip(lifts, old_starts, strict=True):
        lift, prof = report.lift, report.profile
        assert math.degrees(lift.start_angle) < old  # starts before the elbow is fast
        assert prof.has_kinematics and 0.1 < prof.peak_velocity_range_fraction < 0.9
        frac = (prof.peak_velocity_angle - lift.start_angle) / (lift.top_angle - lift.start_angle)
        assert prof.peak_velocity_range_fraction == pytest.approx(frac, abs=1e-9)
        fractions.append(frac)
    tpl = result.template
    assert tpl.peak_velocity_range_fraction == pytest.approx(np.mean(fractions), abs=1e-9)
    assert tpl.emg_peak_time_fraction  # angle-defined tops: EMG timing is measured


def test_energetics_on_thinned_angles_match_full_rate(monkeypatch: pytest.MonkeyPatch) -> None:
    """Energetics run at >= 250 Hz (ENERGETICS_RATE) on a 2 kHz goniometer: the metrics equal
    those at the full rate to 1e-3 (6 Hz-smoothed angles carry nothing above 250 Hz)."""
    import app.analysis.pipeline as pipeline

    rec = _angle_recording(rate=2000.0, n_lifts=2)
    thin = analyze_recordings([rec])
    monkeypatch.setattr(pipeline, "ENERGETICS_RATE", 1e9)
    full = analyze_recordings([rec])
    for a, b in zip(thin.lifts, full.lifts, strict=True):
        assert a.energetics is not None and b.energetics is not None
        assert len(a.energetics.t) < len(b.energetics.t) / 4
        for key in ("tau_sq", "abs_work", "pos_work", "peak_power", "delta_potential"):
            assert a.energetics.metrics[key] == pytest.approx(b.energetics.metrics[key], rel=1e-3)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"peak_velocity_angle_deg": "ninety"}, "'peak_velocity_angle_deg': expected a finite"),
        ({"phase_bounds_deg": [30.0]}, "'phase_bounds_deg': expected an array of two"),
        ({"n_lifts": -1}, "'n_lifts': expected a non-negative integer"),
        ({"velocity_mean": [0.1, float("nan")]}, "'velocity_mean': expected an array of finite"),
        (
            {"lift_range_deg": "wide"},
            "'lift_range_deg': expected an array of two finite numbers or null",
        ),
        ({"wings": 2}, "unknown HumanTemplate fields: ['wings']"),
    ],
)
def test_a_malformed_template_names_its_field(change: dict[str, object], message: str) -> None:
    """``HumanTemplate.from_dict`` raised TypeError/KeyError for malformed input; now a
    BioPlanError naming the field and what was expected (the CLI's exit 2, the API's 422)."""
    from app.errors import BioPlanError
    from app.planning.human_template import HumanTemplate

    good = HumanTemplate().to_dict()
    assert HumanTemplate.from_dict(good) == HumanTemplate()
    with pytest.raises(BioPlanError, match=re.escape(message)):
        HumanTemplate.from_dict({**good, **change})
    with pytest.raises(BioPlanError, match="must be a JSON object, got list"):
        HumanTemplate.from_dict([1, 2])  # type: ignore[arg-type]
    with pytest.raises(BioPlanError, match="line 1 column"):
        HumanTemplate.from_json("{not json")
