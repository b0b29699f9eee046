"""Comparisons built from planner and simulator arrays: phases, curves, errors."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from app.viewer.comparison import (
    Comparison,
    ComparisonError,
    comparison_from_arrays,
    crossing_times,
    phase_of,
)


def test_phase_times_agree_with_the_planner(plan_result: Any, plan_comparison: Comparison) -> None:
    _, result = plan_result
    c = plan_comparison
    # The planner finds the boundaries on its Trajectory objects; we on the stored arrays.
    for label in ("standard", "optimized"):
        np.testing.assert_allclose(c.phase_times[label], result.phase_times(label), atol=1e-12)
    # The phase of each sample follows from the elbow angle: A < 40 <= B < 90 <= C.
    flex = np.degrees(c.q["optimized"][:, c.elbow_joint])
    expected = np.where(flex < 40, "A", np.where(flex < 90, "B", "C"))
    got = [c.phase_at("optimized", i) for i in range(len(c.t))]
    assert got == expected.tolist()
    assert c.joint_names[c.elbow_joint] == "j3_elbow_pitch"


def test_simulation_uses_measured_motion_and_commanded_phases(
    simulation_result: Any, simulation_comparison: Comparison
) -> None:
    _, result = simulation_result
    c = simulation_comparison
    arrays = result.arrays()
    np.testing.assert_array_equal(c.q["standard"], arrays["standard_q"])
    np.testing.assert_array_equal(c.qdd["optimized"], arrays["optimized_qdd_cmd"])
    np.testing.assert_array_equal(c.energy["optimized"], arrays["optimized_energy"])
    np.testing.assert_allclose(c.phase_times["optimized"], result.phase_times(), atol=2e-3)
    assert c.payload_mass == 6.0
    assert c.result["conditions"]["payload"] == 6.0


def test_curves_are_decimated_json(plan_comparison: Comparison) -> None:
    curves = plan_comparison.curves(points=50)
    assert len(curves["t"]) == 50
    assert curves["t"][0] == 0.0 and curves["t"][-1] == pytest.approx(1.0)
    for label in ("standard", "optimized"):
        assert np.shape(curves[label]["tau"]) == (50, 6)
        assert len(curves[label]["energy"]) == 50
    # The last cumulative energy is the abs_work metric (power is sum |tau qd|).
    for label in ("standard", "optimized"):
        assert curves[label]["energy"][-1] == pytest.approx(
            plan_comparison.result[label]["abs_work"], rel=1e-3
        )
    summary = plan_comparison.summary()
    assert summary["payload"]["body"] == "flange"
    assert summary["phase_times"]["optimized"][0] == pytest.approx(
        plan_comparison.phase_times["optimized"][0]
    )
    with pytest.raises(ValueError, match="points must be >= 2"):
        plan_comparison.curves(points=1)


def test_index_at_is_the_nearest_sample(plan_comparison: Comparison) -> None:
    c = plan_comparison
    for t in (-1.0, 0.0, 0.00049, 0.0006, 0.5, 0.99999, 3.0):
        i = c.index_at(t)
        assert i == int(np.argmin(np.abs(c.t - t)))


def test_crossing_times_and_phase_in_closed_form() -> None:
    t = np.linspace(0.0, 1.0, 11)
    flex = 150.0 * t  # 40 deg at 0.2667 s, 90 deg at 0.6 s
    ab, bc = crossing_times(t, flex, (40.0, 90.0))
    assert ab == pytest.approx(40.0 / 150.0) and bc == pytest.approx(0.6)
    assert all(math.isnan(v) for v in crossing_times(t, 0.1 * flex, (40.0, 90.0)))
    assert [phase_of(v, (40.0, 90.0)) for v in (0.0, 39.9, 40.0, 89.9, 90.0)] == list("AABBC")


def test_missing_or_misshapen_arrays_are_named(plan_result: Any) -> None:
    robot, result = plan_result
    arrays = dict(result.arrays())
    del arrays["optimized_tau"]
    with pytest.raises(ComparisonError, match="no 'optimized_tau'"):
        comparison_from_arrays("plan", 1, arrays, result.to_dict(), robot)
    arrays = dict(result.arrays())
    arrays["standard_qd"] = arrays["standard_qd"][:, :2]
    with pytest.raises(ComparisonError, match=r"standard_qd has shape \(1000, 2\)"):
        comparison_from_arrays("plan", 1, arrays, result.to_dict(), robot)
    with pytest.raises(ComparisonError, match="unknown comparison kind"):
        comparison_from_arrays("sweep", 1, result.arrays(), result.to_dict(), robot)  # type: ignore[arg-type]
