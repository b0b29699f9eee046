"""Particle swarm optimisation on test functions with known optima."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from app.planning.pso import PSOResult, pso_minimize

FloatArray = NDArray[np.float64]


def sphere(x: FloatArray) -> FloatArray:
    out: FloatArray = np.sum(x * x, axis=1)
    return out


def rosenbrock(x: FloatArray) -> FloatArray:
    out: FloatArray = np.sum(
        100.0 * (x[:, 1:] - x[:, :-1] ** 2) ** 2 + (1.0 - x[:, :-1]) ** 2, axis=1
    )
    return out


def rastrigin(x: FloatArray) -> FloatArray:
    out: FloatArray = 10.0 * x.shape[1] + np.sum(x * x - 10.0 * np.cos(2.0 * np.pi * x), axis=1)
    return out


def _box(d: int, half: float) -> tuple[FloatArray, FloatArray]:
    return np.full(d, -half), np.full(d, half)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sphere_5d(seed: int) -> None:
    """Optimum 0 at 0. The convergence tests run the full budget: with the default early stop
    (20 stalled iterations) a run may stop during the exploratory high-inertia phase."""
    lo, hi = _box(5, 5.12)
    r = pso_minimize(sphere, lo, hi, seed=seed, iterations=150, stagnation_iterations=None)
    assert r.best_cost < 1e-10
    np.testing.assert_allclose(r.best_position, 0.0, atol=1e-5)
    assert r.best_cost == pytest.approx(float(sphere(r.best_position[None])[0]), abs=0)


@pytest.mark.parametrize(
    ("dim", "iterations", "cost_tol", "pos_tol"), [(2, 300, 1e-8, 1e-3), (4, 2000, 1e-2, 0.1)]
)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rosenbrock(dim: int, iterations: int, cost_tol: float, pos_tol: float, seed: int) -> None:
    """Optimum 0 at (1, ..., 1). In 4-D the valley is long and curved: a looser tolerance."""
    lo, hi = _box(dim, 2.048)
    r = pso_minimize(
        rosenbrock, lo, hi, seed=seed, iterations=iterations, stagnation_iterations=None
    )
    assert r.best_cost < cost_tol
    np.testing.assert_allclose(r.best_position, 1.0, atol=pos_tol)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_rastrigin_2d(seed: int) -> None:
    """Many local minima (at integer points, cost >= 1); the global one is 0 at 0."""
    lo, hi = _box(2, 5.12)
    r = pso_minimize(rastrigin, lo, hi, seed=seed, iterations=200, stagnation_iterations=None)
    assert r.best_cost < 1e-8
    np.testing.assert_allclose(r.best_position, 0.0, atol=1e-5)


def _assert_same(a: PSOResult, b: PSOResult) -> None:
    assert np.array_equal(a.best_position, b.best_position)
    assert np.array_equal(a.history, b.history)
    assert (a.best_cost, a.best_violation, a.iterations, a.evaluations, a.stopped_early) == (
        b.best_cost,
        b.best_violation,
        b.iterations,
        b.evaluations,
        b.stopped_early,
    )


def test_same_seed_same_result_bit_for_bit() -> None:
    lo, hi = _box(3, 2.048)
    runs = [pso_minimize(rosenbrock, lo, hi, seed=42, iterations=60) for _ in range(2)]
    _assert_same(*runs)
    assert runs[0].seed == 42
    other = pso_minimize(rosenbrock, lo, hi, seed=43, iterations=60)
    assert not np.array_equal(other.history, runs[0].history)
    assert not np.array_equal(other.best_position, runs[0].best_position)


def test_constrained_optimum_by_feasibility_rules() -> None:
    """min x^2 + y^2 s.t. x + y >= 1: optimum (0.5, 0.5), cost 0.5."""

    def fn(x: FloatArray) -> tuple[FloatArray, FloatArray]:
        return sphere(x), np.maximum(1.0 - x.sum(axis=1), 0.0)

    for seed in (0, 1, 2):
        r = pso_minimize(
            fn, [-2.0, -2.0], [2.0, 2.0], seed=seed, iterations=200, stagnation_iterations=None
        )
        assert r.feasible and r.best_violation == 0.0
        assert r.best_position.sum() >= 1.0
        assert 0.5 <= r.best_cost < 0.5 + 1e-3
        np.testing.assert_allclose(r.best_position, 0.5, atol=0.02)


def test_infeasible_problem_returns_least_violation() -> None:
    """x >= 3 is impossible in [-1, 1]: the best point is the one closest to feasibility."""

    def fn(x: FloatArray) -> tuple[FloatArray, FloatArray]:
        return x[:, 0] ** 2, np.maximum(3.0 - x[:, 0], 0.0)

    r = pso_minimize(fn, [-1.0], [1.0], seed=0, iterations=60)
    assert not r.feasible
    assert r.best_violation == pytest.approx(2.0, abs=1e-6)
    assert r.best_position[0] == pytest.approx(1.0, abs=1e-6)


def test_non_finite_costs_count_as_infeasible() -> None:
    def fn(x: FloatArray) -> FloatArray:
        cost = sphere(x - 0.5)
        return np.where(x[:, 0] > 0.8, np.nan, np.where(x[:, 0] < -0.5, np.inf, cost))

    r = pso_minimize(fn, [-1.0, -1.0], [1.0, 1.0], seed=0, iterations=100)
    assert r.feasible and np.isfinite(r.best_cost)
    np.testing.assert_allclose(r.best_position, 0.5, atol=1e-4)


def test_callback_once_per_iteration_with_non_increasing_costs() -> None:
    calls: list[tuple[int, float]] = []
    lo, hi = _box(3, 5.12)
    r = pso_minimize(
        rastrigin,
        lo,
        hi,
        seed=5,
        iterations=50,
        stagnation_iterations=None,
        callback=lambda i, c: calls.append((i, c)),
    )
    assert [i for i, _ in calls] == list(range(1, 51))
    costs = np.array([c for _, c in calls])
    assert np.all(np.diff(costs) <= 0.0)
    np.testing.assert_array_equal(costs, r.history)
    assert r.iterations == 50 and r.evaluations == 50 * 40 and not r.stopped_early


def test_one_batched_call_per_iteration() -> None:
    shapes: list[tuple[int, ...]] = []

    def fn(x: FloatArray) -> FloatArray:
        shapes.append(x.shape)
        return sphere(x)

    r = pso_minimize(fn, *_box(4, 1.0), particles=17, iterations=12, stagnation_iterations=None)
    assert shapes == [(17, 4)] * 12
    assert r.evaluations == 17 * 12


def test_early_stop_on_flat_function() -> None:
    r = pso_minimize(
        lambda x: np.ones(x.shape[0]),
        *_box(3, 1.0),
        iterations=100,
        stagnation_iterations=15,
    )
    # Iteration 1 sets the incumbent; 15 iterations without improvement follow.
    assert r.stopped_early
    assert r.iterations == 16
    assert r.history.shape == (16,)
    assert r.evaluations == 16 * 40


def test_bounds_respected_everywhere() -> None:
    lo = np.array([-1.0, 2.0, 0.0])
    hi = np.array([1.0, 3.0, 0.01])
    seen: list[FloatArray] = []

    def fn(x: FloatArray) -> FloatArray:
        seen.append(x)
        out: FloatArray = -np.sum(x, axis=1)  # pushes every particle against the upper walls
        return out

    r = pso_minimize(fn, lo, hi, seed=1, iterations=40, velocity_clamp=0.9)
    allx = np.concatenate(seen)
    assert np.all(allx >= lo) and np.all(allx <= hi)
    np.testing.assert_allclose(r.best_position, hi)


def test_velocity_clamp_limits_every_step() -> None:
    lo, hi = np.array([-10.0, 0.0]), np.array([10.0, 1.0])
    seen: list[FloatArray] = []

    def fn(x: FloatArray) -> FloatArray:
        seen.append(x)
        return rastrigin(x)

    pso_minimize(fn, lo, hi, seed=3, iterations=30, velocity_clamp=0.05)
    steps = np.abs(np.diff(np.stack(seen), axis=0))  # (iterations - 1, P, D)
    v_max = 0.05 * (hi - lo)
    assert np.all(steps <= v_max * (1 + 1e-12))
    assert np.any(steps[..., 0] > 0.99 * v_max[0])  # the clamp is actually reached


def test_initial_particle_is_used() -> None:
    calls: list[FloatArray] = []

    def fn(x: FloatArray) -> FloatArray:
        calls.append(x)
        return sphere(x - 0.3)

    start = np.array([0.3, 0.3])
    r = pso_minimize(fn, [-1.0, -1.0], [1.0, 1.0], iterations=1, initial=start)
    np.testing.assert_array_equal(calls[0][0], start)
    assert r.best_cost == 0.0
    np.testing.assert_array_equal(r.best_position, start)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"lower": [0.0, 1.0], "upper": [1.0, 1.0]}, "upper > lower"),
        ({"lower": [0.0], "upper": [1.0], "particles": 0}, "particles"),
        ({"lower": [0.0], "upper": [1.0], "velocity_clamp": 0.0}, "velocity_clamp"),
        ({"lower": [0.0], "upper": [1.0], "initial": [0.1, 0.2]}, "initial"),
    ],
)
def test_bad_options_raise(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        pso_minimize(sphere, **kwargs)  # type: ignore[arg-type]


def test_bad_cost_function_output_raises() -> None:
    with pytest.raises(ValueError, match=r"shape \(40,\)"):
        pso_minimize(lambda x: np.zeros(3), [0.0], [1.0])
    with pytest.raises(ValueError, match="violations must be >= 0"):
        pso_minimize(lambda x: (np.zeros(len(x)), -np.ones(len(x))), [0.0], [1.0])
