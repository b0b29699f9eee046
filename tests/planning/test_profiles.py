"""Point-to-point profiles: boundary conditions, closed-form peaks, derivative consistency."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from app.planning.profiles import (
    CLASSICAL_PROFILES,
    Trajectory,
    check_limits,
    cubic,
    is_monotonic,
    minimum_jerk,
    piecewise_quintic,
    piecewise_quintic_batch,
    quintic,
    s_curve,
    time_grid,
    trapezoidal,
    triangular,
)

Q0 = np.array([0.1, -0.4, 1.2])
Q1 = np.array([1.6, 0.5, 1.2 - 2.0])  # rising, rising, falling: signs matter
DELTA = Q1 - Q0
DURATION = 1.7

# Profiles whose acceleration is zero at both ends (the others start/stop with a step).
ZERO_END_ACCEL = {"s_curve", "quintic", "minimum_jerk"}


def test_classical_profiles_are_the_six_in_order() -> None:
    assert list(CLASSICAL_PROFILES) == [
        "trapezoidal",
        "s_curve",
        "triangular",
        "cubic",
        "quintic",
        "minimum_jerk",
    ]


def test_time_grid_spans_duration_inclusive() -> None:
    t = time_grid(2.5, 11)
    assert t.shape == (11,)
    assert t[0] == 0.0 and t[-1] == 2.5
    np.testing.assert_allclose(np.diff(t), 0.25)


@pytest.mark.parametrize("name", list(CLASSICAL_PROFILES))
def test_boundary_conditions_and_equal_duration(name: str) -> None:
    traj = CLASSICAL_PROFILES[name](Q0, Q1, DURATION, n_samples=201)
    assert traj.name == name
    assert traj.t.shape == (201,)
    for arr in (traj.q, traj.qd, traj.qdd, traj.jerk):
        assert arr.shape == (201, 3)
    assert traj.duration == DURATION
    np.testing.assert_allclose(traj.q[0], Q0, atol=1e-12)
    np.testing.assert_allclose(traj.q[-1], Q1, atol=1e-12)
    np.testing.assert_allclose(traj.qd[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(traj.qd[-1], 0.0, atol=1e-12)
    if name in ZERO_END_ACCEL:
        np.testing.assert_allclose(traj.qdd[0], 0.0, atol=1e-10)
        np.testing.assert_allclose(traj.qdd[-1], 0.0, atol=1e-10)
    # The joint that does not move stays put.
    np.testing.assert_allclose(traj.q[:, 2] - Q0[2], DELTA[2] * (traj.q[:, 0] - Q0[0]) / DELTA[0])


def _integral(t: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cumulative trapezoid integral along axis 0, starting at 0."""
    steps = 0.5 * (y[1:] + y[:-1]) * np.diff(t)[:, None]
    return np.vstack([np.zeros((1, y.shape[1])), np.cumsum(steps, axis=0)])


def _assert_integrates_to(
    t: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64], corners: int
) -> None:
    """low(t) − low(0) = ∫ high dt. A jump of ``high`` at a sample costs the trapezoid rule up
    to |jump| dt / 2 <= max|high| dt, so allow that per corner (plus round-off); a wrong scale
    or sign would be off by O(max|high| T) instead."""
    dt = float(t[1] - t[0])
    atol = (corners + 1e-3) * np.abs(high).max() * dt
    np.testing.assert_allclose(low - low[0], _integral(t, high), atol=atol)


@pytest.mark.parametrize(
    ("name", "corners"),
    [
        ("trapezoidal", 2),  # acceleration jumps at the two inner corners
        ("s_curve", 6),  # jerk jumps at the six inner phase edges
        ("triangular", 1),
        ("cubic", 0),
        ("quintic", 0),
        ("minimum_jerk", 0),
    ],
)
def test_derivatives_are_consistent(name: str, corners: int) -> None:
    """Integrating each derivative reproduces the one below it; on smooth profiles
    np.gradient also matches pointwise."""
    traj = CLASSICAL_PROFILES[name](Q0, Q1, DURATION, n_samples=4001)
    t = traj.t
    _assert_integrates_to(t, traj.q, traj.qd, 0)
    _assert_integrates_to(t, traj.qd, traj.qdd, corners if name != "s_curve" else 0)
    if name not in ("trapezoidal", "triangular"):  # their jerk is a Dirac at the corners
        _assert_integrates_to(t, traj.qdd, traj.jerk, corners)
    if corners == 0:
        for low, high in ((traj.q, traj.qd), (traj.qd, traj.qdd), (traj.qdd, traj.jerk)):
            grad = np.gradient(low, t, axis=0, edge_order=2)
            np.testing.assert_allclose(grad, high, atol=1e-4 * np.abs(high).max())


@pytest.mark.parametrize(
    ("factory", "peak_factor"),
    [
        (lambda q0, q1, T: trapezoidal(q0, q1, T, n_samples=1001, accel_fraction=0.25), 1 / 0.75),
        (lambda q0, q1, T: trapezoidal(q0, q1, T, n_samples=1001), 1.5),
        (lambda q0, q1, T: s_curve(q0, q1, T, n_samples=1001, accel_fraction=0.2), 1 / 0.8),
        (lambda q0, q1, T: triangular(q0, q1, T, n_samples=1001), 2.0),
        (lambda q0, q1, T: cubic(q0, q1, T, n_samples=1001), 1.5),
        (lambda q0, q1, T: quintic(q0, q1, T, n_samples=1001), 1.875),
        (lambda q0, q1, T: minimum_jerk(q0, q1, T, n_samples=1001), 1.875),
    ],
)
def test_peak_velocity_closed_forms(factory: object, peak_factor: float) -> None:
    """Trapezoid/S-curve Δ/(T(1−f)), triangular 2Δ/T, cubic 1.5Δ/T, quintic 1.875Δ/T at T/2."""
    traj = factory(Q0, Q1, DURATION)  # type: ignore[operator]
    expected = peak_factor * np.abs(DELTA) / DURATION
    np.testing.assert_allclose(np.abs(traj.qd).max(axis=0), expected, rtol=1e-9)
    mid = traj.t.size // 2  # 1001 samples: the middle one is exactly T/2
    np.testing.assert_allclose(traj.qd[mid], peak_factor * DELTA / DURATION, rtol=1e-9)


def test_minimum_jerk_equals_quintic_and_minimises_jerk() -> None:
    a = quintic(Q0, Q1, DURATION, n_samples=501)
    b = minimum_jerk(Q0, Q1, DURATION, n_samples=501)
    for x, y in ((a.q, b.q), (a.qd, b.qd), (a.qdd, b.qdd), (a.jerk, b.jerk)):
        np.testing.assert_allclose(x, y, rtol=1e-10, atol=1e-10)
    # Adding any perturbation with zero pos/vel/acc at both ends increases ∫ jerk² dt.
    # u^3 (1 - u)^3 = u^3 - 3u^4 + 3u^5 - u^6 vanishes with two derivatives at both ends.
    u = b.t / DURATION
    bump_jerk = (6 - 72 * u + 180 * u**2 - 120 * u**3) / DURATION**3
    base = np.trapezoid(b.jerk[:, 0] ** 2, b.t)
    for eps in (-0.5, 0.2, 1.0):
        assert np.trapezoid((b.jerk[:, 0] + eps * bump_jerk) ** 2, b.t) > base


def test_s_curve_jerk_bounded_and_continuous() -> None:
    fa, fj = 0.3, 0.25
    traj = s_curve(Q0, Q1, DURATION, n_samples=6001, accel_fraction=fa, jerk_fraction=fj)
    # j = a / Tj with a = v / (Ta − Tj), v = Δ / (T (1 − fa)), Ta = fa T, Tj = fj Ta.
    j_max = np.abs(DELTA) / (DURATION**3 * (1 - fa) * fa**2 * fj * (1 - fj))
    assert np.all(np.abs(traj.jerk) <= j_max * (1 + 1e-12))
    np.testing.assert_allclose(np.abs(traj.jerk).max(axis=0), j_max, rtol=1e-12)
    dt = traj.t[1]
    # Continuity: the largest step between samples shrinks with dt (no jumps).
    assert np.all(
        np.abs(np.diff(traj.qd, axis=0)).max(axis=0) <= 1.01 * np.abs(traj.qdd).max(0) * dt
    )
    assert np.all(np.abs(np.diff(traj.qdd, axis=0)).max(axis=0) <= 1.01 * j_max * dt)
    # Peak acceleration a = v / (Ta − Tj).
    a_max = np.abs(DELTA) / (DURATION * (1 - fa)) / (fa * DURATION * (1 - fj))
    np.testing.assert_allclose(np.abs(traj.qdd).max(axis=0), a_max, rtol=1e-9)


def test_trapezoid_acceleration_is_piecewise_constant() -> None:
    traj = trapezoidal(Q0, Q1, DURATION, n_samples=301, accel_fraction=0.2)
    a = DELTA / (DURATION**2 * 0.8 * 0.2)
    early = traj.t < 0.2 * DURATION - 1e-9
    cruise = (traj.t > 0.2 * DURATION + 1e-9) & (traj.t < 0.8 * DURATION - 1e-9)
    late = traj.t > 0.8 * DURATION + 1e-9
    np.testing.assert_allclose(traj.qdd[early], np.broadcast_to(a, traj.qdd[early].shape))
    np.testing.assert_allclose(traj.qdd[cruise], 0.0, atol=1e-9)
    np.testing.assert_allclose(traj.qdd[late], np.broadcast_to(-a, traj.qdd[late].shape))


def _knots() -> tuple[NDArray[np.float64], ...]:
    t = np.array([0.0, 0.35, 0.9, 1.5])
    q = np.array([[0.0, 1.0], [0.4, 0.8], [1.1, 0.2], [1.5, -0.3]])
    qd = np.array([[0.0, 0.0], [2.0, -1.0], [0.7, -0.5], [0.0, 0.0]])
    qdd = np.array([[0.0, 0.0], [1.5, 3.0], [-4.0, 0.5], [0.0, 0.0]])
    return t, q, qd, qdd


def test_piecewise_quintic_passes_knots_and_is_c2() -> None:
    tk, qk, qdk, qddk = _knots()
    traj = piecewise_quintic(tk, qk, qdk, qddk, n_samples=31, name="via")
    assert traj.name == "via" and traj.duration == tk[-1]
    # Evaluate exactly at the knots and a hair on either side of the interior ones.
    eps = 1e-7
    t_eval = np.sort(np.concatenate([tk, tk[1:-1] - eps, tk[1:-1] + eps]))
    q, qd, qdd = piecewise_quintic_batch(tk[None], qk[None], qdk[None], qddk[None], t_eval)
    at = np.searchsorted(t_eval, tk)
    np.testing.assert_allclose(q[0, at], qk, atol=1e-12)
    np.testing.assert_allclose(qd[0, at], qdk, atol=1e-11)
    np.testing.assert_allclose(qdd[0, at], qddk, atol=1e-9)
    left, right = at[1:-1] - 1, at[1:-1] + 1
    for arr, tol in ((q, 1e-6), (qd, 1e-5), (qdd, 1e-4)):
        np.testing.assert_allclose(arr[0, left], arr[0, right], atol=tol)
    # Derivatives are consistent: integration everywhere (jerk jumps at the two inner knots).
    fine = piecewise_quintic(tk, qk, qdk, qddk, n_samples=6001)
    _assert_integrates_to(fine.t, fine.q, fine.qd, 0)
    _assert_integrates_to(fine.t, fine.qd, fine.qdd, 0)
    _assert_integrates_to(fine.t, fine.qdd, fine.jerk, 2)


def test_single_segment_matches_direct_boundary_value_solve() -> None:
    """Independent reference: solve the 6x6 boundary-value system for a quintic directly."""
    t1 = 1.3
    p0, v0, a0, p1, v1, a1 = 0.2, -0.5, 1.0, 1.1, 0.3, -2.0
    rows = []
    for tt in (0.0, t1):
        rows.append([tt**k for k in range(6)])
        rows.append([k * tt ** (k - 1) if k else 0.0 for k in range(6)])
        rows.append([k * (k - 1) * tt ** (k - 2) if k > 1 else 0.0 for k in range(6)])
    coef = np.linalg.solve(np.array(rows), np.array([p0, v0, a0, p1, v1, a1]))
    traj = piecewise_quintic([0.0, t1], [[p0], [p1]], [[v0], [v1]], [[a0], [a1]], n_samples=57)
    poly = np.polynomial.Polynomial(coef)
    np.testing.assert_allclose(traj.q[:, 0], poly(traj.t), atol=1e-12)
    np.testing.assert_allclose(traj.qd[:, 0], poly.deriv(1)(traj.t), atol=1e-11)
    np.testing.assert_allclose(traj.qdd[:, 0], poly.deriv(2)(traj.t), atol=1e-10)
    np.testing.assert_allclose(traj.jerk[:, 0], poly.deriv(3)(traj.t), atol=1e-9)


def test_batch_equals_single_row_by_row() -> None:
    rng = np.random.default_rng(7)
    n_batch, n_knots, n_joints, duration = 6, 4, 3, 2.0
    inner = np.sort(rng.uniform(0.1, 1.9, size=(n_batch, n_knots - 2)), axis=1)
    tk = np.hstack([np.zeros((n_batch, 1)), inner, np.full((n_batch, 1), duration)])
    qk = rng.normal(size=(n_batch, n_knots, n_joints))
    qdk = rng.normal(size=(n_batch, n_knots, n_joints))
    qddk = rng.normal(size=(n_batch, n_knots, n_joints))
    t = time_grid(duration, 77)
    q, qd, qdd = piecewise_quintic_batch(tk, qk, qdk, qddk, t)
    assert q.shape == qd.shape == qdd.shape == (n_batch, 77, n_joints)
    for b in range(n_batch):
        single = piecewise_quintic(tk[b], qk[b], qdk[b], qddk[b], n_samples=77)
        np.testing.assert_allclose(q[b], single.q, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(qd[b], single.qd, rtol=1e-12, atol=1e-11)
        np.testing.assert_allclose(qdd[b], single.qdd, rtol=1e-12, atol=1e-10)


def test_batch_rejects_bad_knots_and_samples() -> None:
    tk, qk, qdk, qddk = _knots()
    t = time_grid(1.5, 10)
    bad_t = tk.copy()
    bad_t[2] = bad_t[1]
    with pytest.raises(ValueError, match="strictly increasing"):
        piecewise_quintic_batch(bad_t[None], qk[None], qdk[None], qddk[None], t)
    with pytest.raises(ValueError, match="knot span"):
        piecewise_quintic_batch(tk[None], qk[None], qdk[None], qddk[None], t + 0.1)
    with pytest.raises(ValueError, match="qd_knots"):
        piecewise_quintic_batch(tk[None], qk[None], qdk[None, :3], qddk[None], t)
    with pytest.raises(ValueError, match=r"t_knots\[0\] must be 0"):
        piecewise_quintic(tk + 0.1, qk, qdk, qddk)


def test_check_limits_finds_planted_violations() -> None:
    traj = quintic(Q0, Q1, DURATION, n_samples=101)
    peak = 1.875 * np.abs(DELTA) / DURATION
    assert check_limits(traj, qd_max=peak * 1.01, q_min=-5.0, q_max=5.0) == []
    limit = peak.copy()
    limit[1] = 0.9 * peak[1]  # only joint 2 (index 1) is too fast
    msgs = check_limits(traj, qd_max=limit * np.array([1.01, 1.0, 1.01]))
    assert len(msgs) == 1
    assert msgs[0].startswith("joint 2 velocity")
    assert "rad/s exceeds" in msgs[0]
    assert f"t={DURATION / 2:.3g} s" in msgs[0]
    msgs = check_limits(traj, q_max=[1.0, 5.0, 5.0], joint_names=["J1", "J2", "J3"])
    assert msgs == [f"J1 position {Q1[0]:.4g} rad exceeds 1 rad at t={DURATION:.3g} s"]
    assert check_limits(traj, q_min=np.array([-5.0, -5.0, -0.5]))[0].startswith("joint 3 position")
    a_peak = np.abs(traj.qdd).max(axis=0)
    assert len(check_limits(traj, qdd_max=0.5 * a_peak)) == 3


def test_check_limits_ignores_round_off_at_an_active_limit() -> None:
    """Found by a sweep from the page: on the human arm, whose elbow starts on its 0 rad stop,
    the physical bound dipped to -1.6e-10 rad (IPOPT's round-off) and a PSO plan to -3.3e-8
    rad, which made the cells "unstable". An excess below an encoder's resolution is not a
    violation; a real one still is."""
    traj = quintic(Q0, Q1, DURATION, n_samples=101)
    low = traj.q.min(axis=0)
    for dip in (1.6e-10, 3.3e-8, 9e-7):
        assert check_limits(traj, q_min=low + dip) == []
    assert len(check_limits(traj, q_min=low + 1e-5)) == 3
    high = traj.q.max(axis=0)
    assert check_limits(traj, q_max=high - 9e-7 * np.maximum(1.0, np.abs(high))) == []
    assert len(check_limits(traj, q_max=high - 1e-4)) == 3


def test_is_monotonic() -> None:
    traj = quintic(Q0, Q1, DURATION)
    assert is_monotonic(traj).tolist() == [True, True, True]
    # An overshooting via point makes joint 1 reverse.
    via = piecewise_quintic(
        [0.0, 0.5, 1.0], [[0.0, 0.0], [1.2, 0.5], [1.0, 1.0]], np.zeros((3, 2)), np.zeros((3, 2))
    )
    assert is_monotonic(via).tolist() == [False, True]
    still = Trajectory(
        t=np.linspace(0, 1, 5),
        q=np.array([[0.0], [1e-12], [0.0], [-1e-12], [0.0]]),
        qd=np.zeros((5, 1)),
        qdd=np.zeros((5, 1)),
        jerk=np.zeros((5, 1)),
    )
    assert is_monotonic(still).tolist() == [True]
    assert is_monotonic(still, tol=0.0).tolist() == [False]


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: trapezoidal(Q0, Q1, 0.0), "duration"),
        (lambda: trapezoidal(Q0, Q1, 1.0, accel_fraction=0.6), "accel_fraction"),
        (lambda: s_curve(Q0, Q1, 1.0, jerk_fraction=0.0), "jerk_fraction"),
        (lambda: cubic(Q0, Q1[:2], 1.0), "same length"),
        (lambda: quintic(Q0, Q1, 1.0, n_samples=1), "n_samples"),
        (lambda: minimum_jerk([np.nan], [1.0], 1.0), "finite"),
    ],
)
def test_bad_input_raises_clear_errors(call: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        call()  # type: ignore[operator]
