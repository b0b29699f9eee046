"""Issue 27 item 5: simulating the Panda warned "simulated pos_work differs by +15913 %" where
both values were near zero. A near-zero planned value's difference is now stated in the
metric's unit and judged against the task's scale (the quintic's absolute work for energies).
The numbers below are worked by hand."""

from __future__ import annotations

import math

from app.simulation.comparison import (
    AGREEMENT_PCT,
    NEAR_ZERO_FRACTION,
    agreement_warning,
    metric_scale,
)

#: A lowering task's quintic (the Panda's case): it moves 12 J of absolute work, almost no
#: positive work.
QUINTIC = {
    "tau_sq": 40.0,
    "abs_work": 12.0,
    "pos_work": 0.0001,
    "electrical_energy": math.nan,
    "peak_power": 30.0,
    "peak_torque": 20.0,
}


def test_the_scale_of_an_energy_is_at_least_the_quintics_absolute_work() -> None:
    assert metric_scale("pos_work", QUINTIC) == 12.0  # not its own 0.0001 J
    assert metric_scale("electrical_energy", QUINTIC) == 12.0  # not modelled: abs_work
    assert metric_scale("abs_work", QUINTIC) == 12.0
    assert metric_scale("peak_power", QUINTIC) == 30.0  # W: its own value
    assert metric_scale("tau_sq", QUINTIC) == 40.0


def test_two_near_zero_values_are_not_a_disagreement() -> None:
    planned, simulated = 0.0001, 0.0160130  # +15913 % of each other, 16 mJ apart
    assert round(100 * (simulated - planned) / planned) == 15913
    scale = metric_scale("pos_work", QUINTIC)
    assert planned < NEAR_ZERO_FRACTION * scale  # near zero: below 0.12 J
    assert abs(simulated - planned) < AGREEMENT_PCT / 100 * scale  # within 0.24 J
    assert agreement_warning("paper", "pos_work", planned, simulated, scale) is None


def test_a_near_zero_value_that_does_disagree_is_stated_in_joules() -> None:
    scale = metric_scale("pos_work", QUINTIC)
    text = agreement_warning("paper", "pos_work", 0.0001, 0.5001, scale)
    assert text is not None
    assert "differs from the planned value by +0.5 J" in text  # 0.5001 - 0.0001
    assert "planned 0.0001 J" in text and "scale 12 J" in text
    assert "%" not in text.split("by ")[1].split("(")[0]  # the difference itself: no percent


def test_values_of_the_tasks_size_keep_their_percentage() -> None:
    scale = metric_scale("abs_work", QUINTIC)
    text = agreement_warning("standard", "abs_work", 10.0, 10.5, scale)
    assert text == (
        "standard: simulated abs_work differs from the planned value by +5.0% (> 2%) although "
        "tracking is good"
    )
    assert agreement_warning("standard", "abs_work", 10.0, 10.1, scale) is None  # 1 %
    assert agreement_warning("standard", "abs_work", math.nan, 10.1, scale) is None
