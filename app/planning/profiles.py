"""Point-to-point joint trajectories on a time grid.

Every profile moves all joints from ``q0`` to ``q1`` in the same ``duration`` and returns a
:class:`Trajectory` with positions, velocities, accelerations and jerks sampled on
``time_grid(duration, n_samples)``. The classical rest-to-rest profiles are a normalised shape
``s(tau)`` with ``s(0) = 0``, ``s(1) = 1`` and ``tau = t / duration``, scaled per joint by the
stroke ``q1 - q0``; so every joint starts, peaks and stops at the same instants.

Piecewise quintic Hermite segments through via points (position, velocity and acceleration given at
each knot) are the planner's free-form trajectories; :func:`piecewise_quintic_batch` evaluates a
whole PSO swarm of them in one vectorised call.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.errors import BioPlanError

FloatArray = NDArray[np.float64]
#: A normalised profile s(tau) and its first three tau-derivatives, each (T,).
_Shape = tuple[FloatArray, FloatArray, FloatArray, FloatArray]

#: Default tolerance of :func:`is_monotonic` [rad].
MONOTONIC_TOL = 1e-9
#: Excess over a joint limit that is not a violation (in the limit's unit, times
#: max(1, |limit|)): below any encoder's resolution (a 20-bit encoder: 6e-6 rad). Motions
#: starting on a stop touch it: the physical bound dipped to -1.6e-10 rad (IPOPT's round-off)
#: and a PSO plan's first segment to -3.3e-8 rad from the human arm's 0 rad elbow stop.
LIMIT_TOL = 1e-6


@dataclass(frozen=True)
class Trajectory:
    """A joint-space trajectory sampled on a uniform time grid.

    Attributes:
        t: (T,) sample times [s], starting at 0.
        q: (T, n) joint positions [rad].
        qd: (T, n) joint velocities [rad/s].
        qdd: (T, n) joint accelerations [rad/s^2].
        jerk: (T, n) joint jerks [rad/s^3].
        name: profile name (e.g. ``"quintic"``, ``"bio_optimized"``).
        knots: for a piecewise quintic, its knots (t (K,) [s], q, qd, qdd each (K, n)), which
            define it exactly at any time (the exporter resamples from them); None otherwise.
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    qdd: NDArray[np.float64]
    jerk: NDArray[np.float64]
    name: str = ""
    knots: tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None = None

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def n_joints(self) -> int:
        return int(self.q.shape[1])


def stretched(traj: Trajectory, duration: float) -> Trajectory:
    """The same path in ``duration`` seconds: velocities scale by s = T / T', accelerations by
    s², jerks by s³ (a warm start for a neighbouring duration)."""
    s = traj.duration / duration
    return Trajectory(
        t=traj.t / s,
        q=traj.q,
        qd=traj.qd * s,
        qdd=traj.qdd * s**2,
        jerk=traj.jerk * s**3,
        name=traj.name,
    )


# ----------------------------------------------------------------------------------------------
# Input checks
# ----------------------------------------------------------------------------------------------


def _check_duration(duration: float) -> float:
    value = float(duration)
    if not np.isfinite(value) or value <= 0.0:
        raise BioPlanError(f"duration must be a finite number of seconds > 0, got {duration!r}")
    return value


def _check_n_samples(n_samples: int) -> int:
    if isinstance(n_samples, bool) or not isinstance(n_samples, int | np.integer):
        raise BioPlanError(f"n_samples must be an integer >= 2, got {n_samples!r}")
    if n_samples < 2:
        raise BioPlanError(f"n_samples must be >= 2 (both end points), got {n_samples}")
    return int(n_samples)


def _check_endpoints(q0: ArrayLike, q1: ArrayLike) -> tuple[FloatArray, FloatArray]:
    a = np.atleast_1d(np.asarray(q0, dtype=np.float64))
    b = np.atleast_1d(np.asarray(q1, dtype=np.float64))
    if a.ndim != 1 or b.ndim != 1 or a.shape != b.shape or a.size == 0:
        raise BioPlanError(
            f"q0 and q1 must be 1-D arrays of the same length n >= 1 [rad], "
            f"got shapes {a.shape} and {b.shape}"
        )
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise BioPlanError("q0 and q1 must be finite joint angles [rad]")
    return a, b


def _check_fraction(name: str, value: float, upper: float) -> float:
    f = float(value)
    if not (0.0 < f <= upper):
        raise BioPlanError(f"{name} must lie in (0, {upper}], got {value!r}")
    return f


def time_grid(duration: float, n_samples: int) -> FloatArray:
    """Uniform sample times from 0 to ``duration`` inclusive.

    Args:
        duration: motion time [s], > 0.
        n_samples: number of samples T, >= 2.

    Returns:
        (T,) times [s]; the first is exactly 0 and the last exactly ``duration``.
    """
    return np.linspace(0.0, _check_duration(duration), _check_n_samples(n_samples))


# ----------------------------------------------------------------------------------------------
# Classical rest-to-rest profiles
# ----------------------------------------------------------------------------------------------


def _rest_to_rest(
    q0: ArrayLike,
    q1: ArrayLike,
    duration: float,
    n_samples: int,
    shape_of: Callable[[FloatArray], _Shape],
    name: str,
) -> Trajectory:
    """Check the inputs, sample tau = t / duration and scale a normalised shape per joint.

    Args:
        q0: (n,) start [rad].
        q1: (n,) goal [rad].
        duration: motion time [s].
        n_samples: samples T on the time grid.
        shape_of: maps (T,) tau in [0, 1] to s(tau) and its first three tau-derivatives, each
            (T,), with s(0) = 0 and s(1) = 1.
        name: the trajectory's name.

    Returns:
        The trajectory (T samples, n joints).
    """
    a0, a1 = _check_endpoints(q0, q1)
    duration = _check_duration(duration)
    t = time_grid(duration, n_samples)
    s, ds, dds, ddds = (x[:, None] for x in shape_of(t / duration))
    delta = (a1 - a0)[None, :]
    # q0 (1 - s) + q1 s hits both end points exactly when s is exactly 0 and 1 there.
    q = a0[None, :] * (1.0 - s) + a1[None, :] * s
    return Trajectory(
        t=t,
        q=q,
        qd=ds * delta / duration,
        qdd=dds * delta / duration**2,
        jerk=ddds * delta / duration**3,
        name=name,
    )


def _piecewise_constant_jerk(
    tau: FloatArray, edges: Sequence[float], acc0: Sequence[float], jerk: Sequence[float]
) -> _Shape:
    """Evaluate a normalised profile made of phases with constant jerk.

    Args:
        tau: (T,) normalised times in [0, 1].
        edges: (M + 1,) phase boundaries, edges[0] = 0, edges[-1] = 1, non-decreasing.
        acc0: (M,) acceleration at the start of each phase.
        jerk: (M,) constant jerk in each phase.

    Returns:
        s, s', s'', s''' each (T,), starting from s(0) = s'(0) = 0.
    """
    e = np.asarray(edges, dtype=np.float64)
    a = np.asarray(acc0, dtype=np.float64)
    j = np.asarray(jerk, dtype=np.float64)
    m = j.size
    pos = np.zeros(m)
    vel = np.zeros(m)
    # A loop over the (at most seven) phases, not over samples: exact integration of each phase.
    for k in range(m - 1):
        h = e[k + 1] - e[k]
        vel[k + 1] = vel[k] + a[k] * h + j[k] * h**2 / 2.0
        pos[k + 1] = pos[k] + vel[k] * h + a[k] * h**2 / 2.0 + j[k] * h**3 / 6.0
    k_of = np.clip(np.searchsorted(e, tau, side="right") - 1, 0, m - 1)
    dt = tau - e[k_of]
    jk, ak, vk, pk = j[k_of], a[k_of], vel[k_of], pos[k_of]
    s = pk + vk * dt + ak * dt**2 / 2.0 + jk * dt**3 / 6.0
    ds = vk + ak * dt + jk * dt**2 / 2.0
    dds = ak + jk * dt
    return s, ds, dds, jk


def trapezoidal(
    q0: ArrayLike,
    q1: ArrayLike,
    duration: float,
    *,
    n_samples: int = 100,
    accel_fraction: float = 1.0 / 3.0,
) -> Trajectory:
    """Trapezoidal velocity profile: constant acceleration, cruise, constant deceleration.

    The acceleration and the deceleration each last ``accel_fraction * duration``; the cruise
    velocity is ``(q1 - q0) / (duration * (1 - accel_fraction))``. The acceleration jumps at the
    phase corners, so the jerk there is a Dirac impulse; the sampled jerk is reported as 0 (its
    value between the corners).

    Args:
        q0: (n,) start [rad].
        q1: (n,) goal [rad].
        duration: motion time [s].
        n_samples: samples T on the time grid.
        accel_fraction: share of the duration spent accelerating, in (0, 0.5]; 0.5 is the
            triangular profile.

    Returns:
        The trajectory (T samples, n joints), name ``"trapezoidal"``.
    """
    f = _check_fraction("accel_fraction", accel_fraction, 0.5)
    v = 1.0 / (1.0 - f)
    a = v / f
    shape = partial(
        _piecewise_constant_jerk, edges=(0.0, f, 1.0 - f, 1.0), acc0=(a, 0.0, -a), jerk=(0, 0, 0)
    )
    return _rest_to_rest(q0, q1, duration, n_samples, shape, "trapezoidal")


def triangular(
    q0: ArrayLike, q1: ArrayLike, duration: float, *, n_samples: int = 100
) -> Trajectory:
    """Triangular velocity profile: accelerate for half the duration, decelerate for the rest.

    Peak velocity ``2 (q1 - q0) / duration`` at ``duration / 2``. Same as
    ``trapezoidal(..., accel_fraction=0.5)`` but named ``"triangular"``.

    Args:
        q0: (n,) start [rad].
        q1: (n,) goal [rad].
        duration: motion time [s].
        n_samples: samples T on the time grid.

    Returns:
        The trajectory (T samples, n joints), name ``"triangular"``.
    """
    traj = trapezoidal(q0, q1, duration, n_samples=n_samples, accel_fraction=0.5)
    return Trajectory(traj.t, traj.q, traj.qd, traj.qdd, traj.jerk, name="triangular")


def s_curve(
    q0: ArrayLike,
    q1: ArrayLike,
    duration: float,
    *,
    n_samples: int = 100,
    accel_fraction: float = 1.0 / 3.0,
    jerk_fraction: float = 1.0 / 3.0,
) -> Trajectory:
    """Seven-phase jerk-limited S-curve: jerk up, constant acceleration, jerk down, cruise, and the
    mirror image to stop.

    With ``Ta = accel_fraction * duration`` the acceleration phase (phases 1-3) and
    ``Tj = jerk_fraction * Ta`` each jerk phase, the cruise velocity is
    ``v = (q1 - q0) / (duration (1 - accel_fraction))`` (as for the trapezoid), the peak
    acceleration ``a = v / (Ta - Tj)`` and the jerk magnitude ``j = a / Tj``. Velocity and
    acceleration are continuous; the jerk is piecewise constant and bounded by ``j``.

    Args:
        q0: (n,) start [rad].
        q1: (n,) goal [rad].
        duration: motion time [s].
        n_samples: samples T on the time grid.
        accel_fraction: Ta / duration, in (0, 0.5] (0.5: no cruise).
        jerk_fraction: Tj / Ta, in (0, 0.5] (0.5: no constant-acceleration phase).

    Returns:
        The trajectory (T samples, n joints), name ``"s_curve"``.
    """
    fa = _check_fraction("accel_fraction", accel_fraction, 0.5)
    fj = _check_fraction("jerk_fraction", jerk_fraction, 0.5)
    ta = fa
    tj = fj * fa
    v = 1.0 / (1.0 - fa)
    a = v / (ta - tj)
    j = a / tj
    edges = (0.0, tj, ta - tj, ta, 1.0 - ta, 1.0 - ta + tj, 1.0 - tj, 1.0)
    acc0 = (0.0, a, a, 0.0, 0.0, -a, -a)
    jerk = (j, 0.0, -j, 0.0, -j, 0.0, j)
    shape = partial(_piecewise_constant_jerk, edges=edges, acc0=acc0, jerk=jerk)
    return _rest_to_rest(q0, q1, duration, n_samples, shape, "s_curve")


def _cubic_shape(u: FloatArray) -> _Shape:
    """s = 3 u^2 - 2 u^3 and its first three u-derivatives, each (T,)."""
    return (u**2 * (3.0 - 2.0 * u), 6.0 * u * (1.0 - u), 6.0 - 12.0 * u, np.full_like(u, -12.0))


def _minimum_jerk_shape(u: FloatArray) -> _Shape:
    """s = 10 u^3 - 15 u^4 + 6 u^5 and its first three u-derivatives, each (T,)."""
    return (
        u**3 * (10.0 - 15.0 * u + 6.0 * u**2),
        30.0 * u**2 * (1.0 - u) ** 2,
        60.0 * u * (1.0 - u) * (1.0 - 2.0 * u),
        60.0 * (1.0 - 6.0 * u + 6.0 * u**2),
    )


def cubic(q0: ArrayLike, q1: ArrayLike, duration: float, *, n_samples: int = 100) -> Trajectory:
    """Cubic polynomial with zero velocity at both ends: s = 3 tau^2 - 2 tau^3.

    Peak velocity ``1.5 (q1 - q0) / duration`` at ``duration / 2``; the acceleration jumps from
    0 to its end values at start and stop.

    Args:
        q0: (n,) start [rad].
        q1: (n,) goal [rad].
        duration: motion time [s].
        n_samples: samples T on the time grid.

    Returns:
        The trajectory (T samples, n joints), name ``"cubic"``.
    """
    return _rest_to_rest(q0, q1, duration, n_samples, _cubic_shape, "cubic")


def quintic(q0: ArrayLike, q1: ArrayLike, duration: float, *, n_samples: int = 100) -> Trajectory:
    """Quintic polynomial with zero velocity and acceleration at both ends (the paper's standard).

    Built as a single quintic Hermite segment (see :func:`piecewise_quintic`); peak velocity
    ``1.875 (q1 - q0) / duration`` at ``duration / 2``.

    Args:
        q0: (n,) start [rad].
        q1: (n,) goal [rad].
        duration: motion time [s].
        n_samples: samples T on the time grid.

    Returns:
        The trajectory (T samples, n joints), name ``"quintic"``.
    """
    a0, a1 = _check_endpoints(q0, q1)
    duration = _check_duration(duration)
    zeros = np.zeros((2, a0.size))
    return piecewise_quintic(
        np.array([0.0, duration]),
        np.stack([a0, a1]),
        zeros,
        zeros,
        n_samples=n_samples,
        name="quintic",
    )


def minimum_jerk(
    q0: ArrayLike, q1: ArrayLike, duration: float, *, n_samples: int = 100
) -> Trajectory:
    """Minimum-jerk point-to-point motion (Flash & Hogan 1985): s = 10 tau^3 - 15 tau^4 + 6 tau^5.

    Minimising the integral of squared jerk gives the Euler-Lagrange equation q^(6) = 0, so the
    optimum is a quintic; with zero velocity and acceleration at both ends that quintic is unique,
    hence this profile equals :func:`quintic` (computed here from Flash & Hogan's closed form,
    there from the Hermite boundary-value solution).

    Args:
        q0: (n,) start [rad].
        q1: (n,) goal [rad].
        duration: motion time [s].
        n_samples: samples T on the time grid.

    Returns:
        The trajectory (T samples, n joints), name ``"minimum_jerk"``.
    """
    return _rest_to_rest(q0, q1, duration, n_samples, _minimum_jerk_shape, "minimum_jerk")


CLASSICAL_PROFILES: dict[str, Callable[..., Trajectory]] = {
    "trapezoidal": trapezoidal,
    "s_curve": s_curve,
    "triangular": triangular,
    "cubic": cubic,
    "quintic": quintic,
    "minimum_jerk": minimum_jerk,
}
"""The classical profiles by name, each ``f(q0, q1, duration, *, n_samples=...)``."""


# ----------------------------------------------------------------------------------------------
# Piecewise quintic Hermite through via points
# ----------------------------------------------------------------------------------------------


#: Maps a segment's Hermite data [p0, v0 h, a0 h^2, p1, v1 h, a1 h^2] to the power-basis
#: coefficients c_0..c_5 of q(u) = sum_m c_m u^m, u = (t - t_k) / h in [0, 1].
_HERMITE_TO_POWER = np.array(
    [
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.5, 0.0, 0.0, 0.0],
        [-10.0, -6.0, -1.5, 10.0, -4.0, 0.5],
        [15.0, 8.0, 1.5, -15.0, 7.0, -1.0],
        [-6.0, -3.0, -0.5, 6.0, -3.0, 0.5],
    ]
)


def _check_knots(
    t_knots: ArrayLike, q_knots: ArrayLike, qd_knots: ArrayLike, qdd_knots: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Validate batched knots: t (B, K) strictly increasing, states (B, K, n), all finite."""
    tk = np.asarray(t_knots, dtype=np.float64)
    qk = np.asarray(q_knots, dtype=np.float64)
    qdk = np.asarray(qd_knots, dtype=np.float64)
    qddk = np.asarray(qdd_knots, dtype=np.float64)
    if tk.ndim != 2 or tk.shape[1] < 2:
        raise BioPlanError(f"t_knots must have shape (B, K) with K >= 2 knots, got {tk.shape}")
    expected = (*tk.shape, qk.shape[-1] if qk.ndim == 3 else -1)
    for label, arr in (("q_knots", qk), ("qd_knots", qdk), ("qdd_knots", qddk)):
        if arr.ndim != 3 or arr.shape != expected or arr.shape[2] < 1:
            raise BioPlanError(
                f"{label} must have shape (B, K, n) = {expected[:2]} + (n,) matching t_knots "
                f"and q_knots, got {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise BioPlanError(f"{label} must be finite")
    if not np.all(np.isfinite(tk)):
        raise BioPlanError("t_knots must be finite times [s]")
    steps = np.diff(tk, axis=1)
    if not np.all(steps > 0.0):
        row = int(np.flatnonzero(~np.all(steps > 0.0, axis=1))[0])
        raise BioPlanError(
            f"t_knots must be strictly increasing in every row; row {row} is {tk[row].tolist()}"
        )
    return tk, qk, qdk, qddk


#: Falling factorials m! / (m - d)! that turn power coefficients c_m into those of the d-th
#: derivative in u: d^d/du^d sum_m c_m u^m = sum_k FALLING[d][k] c_(k+d) u^k.
_FALLING = (
    np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0]),
    np.array([1.0, 2.0, 3.0, 4.0, 5.0]),
    np.array([2.0, 6.0, 12.0, 20.0]),
    np.array([6.0, 24.0, 60.0]),
)


def _evaluate_quintic_segments(
    tk: FloatArray,
    qk: FloatArray,
    qdk: FloatArray,
    qddk: FloatArray,
    t: FloatArray,
    *,
    with_jerk: bool,
) -> tuple[FloatArray, ...]:
    """Evaluate validated batched quintic Hermite splines on the grid t (T,) -> each (B, T, n).

    Segment s has the local time u = (t - t_s) / h_s. Per segment the powers u^0..u^5 of its
    own samples fill six rows of a zero-padded basis (B, 6 S, T); the derivatives are the same
    powers times derivative coefficients c_(k+d) (k+d)! / k! / h_s^d, which depend on the row and
    segment only. One batched matrix product then gives q, qd, qdd (and jerk) together. The
    cost is dominated by per-call numpy overhead and memory traffic, not arithmetic, so no
    per-sample gathers are made and only a few large arrays are allocated.
    """
    n_batch, n_knots = tk.shape
    n_seg = n_knots - 1
    n_t = t.size
    n_joints = qk.shape[-1]
    h = np.diff(tk, axis=1)  # (B, S)
    powers = np.zeros((n_batch, 6 * n_seg, n_t))
    for s in range(n_seg):  # (B, T)-sized work per segment; S is small
        u = (t[None, :] - tk[:, s, None]) / h[:, s, None]
        # The first segment takes everything before its end, the last everything after its start
        # (both within the knot span, as validated); a sample on an interior knot goes right.
        inside = np.ones(u.shape, dtype=bool)
        if s > 0:
            inside &= t[None, :] >= tk[:, s, None]
        if s < n_seg - 1:
            inside &= t[None, :] < tk[:, s + 1, None]
        m = inside.astype(np.float64)
        um = u * m
        u2 = um * u
        u3 = u2 * u
        o = 6 * s
        powers[:, o] = m
        powers[:, o + 1] = um
        powers[:, o + 2] = u2
        powers[:, o + 3] = u3
        powers[:, o + 4] = u3 * u
        powers[:, o + 5] = u3 * u2
    hh = h[:, :, None]
    hermite = np.stack(
        [
            qk[:, :-1],
            qdk[:, :-1] * hh,
            qddk[:, :-1] * hh**2,
            qk[:, 1:],
            qdk[:, 1:] * hh,
            qddk[:, 1:] * hh**2,
        ],
        axis=2,
    )  # (B, S, 6, n)
    c = np.matmul(_HERMITE_TO_POWER, hermite)  # (B, S, 6, n): q = sum_m c_m u^m
    n_der = 4 if with_jerk else 3
    coeffs = np.zeros((n_der, n_batch, n_seg, 6, n_joints))
    inv_h = (1.0 / h)[:, :, None, None]
    scale = np.ones_like(inv_h)
    for d in range(n_der):
        coeffs[d, :, :, : 6 - d] = c[:, :, d:] * (_FALLING[d][:, None] * scale)
        scale = scale * inv_h
    coeffs = coeffs.reshape(n_der, n_batch, 6 * n_seg, n_joints)
    out = np.matmul(powers.transpose(0, 2, 1), coeffs)  # (n_der, B, T, n)
    return tuple(out)


def piecewise_quintic_batch(
    t_knots: ArrayLike,
    q_knots: ArrayLike,
    qd_knots: ArrayLike,
    qdd_knots: ArrayLike,
    t: ArrayLike,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Evaluate B piecewise quintic Hermite splines (one per PSO particle) on a common grid.

    Segment k joins knot k and k + 1 with the unique quintic matching position, velocity and
    acceleration at both knots, so every spline is C2. Knot times may differ between rows; all
    rows are evaluated together (no Python loop over rows, samples or segments).

    Args:
        t_knots: (B, K) knot times [s], strictly increasing in each row, K >= 2.
        q_knots: (B, K, n) positions at the knots [rad].
        qd_knots: (B, K, n) velocities at the knots [rad/s].
        qdd_knots: (B, K, n) accelerations at the knots [rad/s^2].
        t: (T,) sample times [s], inside every row's [t_knots[b, 0], t_knots[b, -1]].

    Returns:
        q, qd, qdd, each (B, T, n) [rad, rad/s, rad/s^2].

    Raises:
        ValueError: on mismatched shapes, non-finite values, knots that do not increase, or
            samples outside a row's knot span.
    """
    tk, qk, qdk, qddk = _check_knots(t_knots, q_knots, qd_knots, qdd_knots)
    tt = np.asarray(t, dtype=np.float64)
    if tt.ndim != 1 or tt.size == 0 or not np.all(np.isfinite(tt)):
        raise BioPlanError(f"t must be a non-empty 1-D array of finite times [s], got {tt.shape}")
    # Round-off slack: a grid built as linspace(0, duration) may miss the last knot by an ulp.
    slack = 1e-9 * (tk[:, -1] - tk[:, 0])
    outside = (tt.min() < tk[:, 0] - slack) | (tt.max() > tk[:, -1] + slack)
    if np.any(outside):
        row = int(np.flatnonzero(outside)[0])
        raise BioPlanError(
            f"t spans [{tt.min():.6g}, {tt.max():.6g}] s but row {row}'s knots span only "
            f"[{tk[row, 0]:.6g}, {tk[row, -1]:.6g}] s (expected samples inside the knot span)"
        )
    q, qd, qdd = _evaluate_quintic_segments(tk, qk, qdk, qddk, tt, with_jerk=False)
    return q, qd, qdd


def piecewise_quintic(
    t_knots: ArrayLike,
    q_knots: ArrayLike,
    qd_knots: ArrayLike,
    qdd_knots: ArrayLike,
    *,
    n_samples: int = 100,
    name: str = "piecewise_quintic",
) -> Trajectory:
    """A C2 trajectory of quintic Hermite segments through via points.

    Args:
        t_knots: (K,) knot times [s], strictly increasing, t_knots[0] = 0; the duration is
            t_knots[-1].
        q_knots: (K, n) positions at the knots [rad] ((K,) for a single joint).
        qd_knots: (K, n) velocities at the knots [rad/s].
        qdd_knots: (K, n) accelerations at the knots [rad/s^2].
        n_samples: samples T on ``time_grid(t_knots[-1], n_samples)``.
        name: the trajectory's name.

    Returns:
        The trajectory (T samples, n joints), passing every knot with the given position,
        velocity and acceleration.
    """
    tk = np.asarray(t_knots, dtype=np.float64)
    if tk.ndim != 1 or tk.size < 2:
        raise BioPlanError(f"t_knots must be a 1-D array of K >= 2 times [s], got shape {tk.shape}")
    if tk[0] != 0.0:
        raise BioPlanError(f"t_knots[0] must be 0 s (trajectories start at t = 0), got {tk[0]!r}")

    def as_states(label: str, x: ArrayLike) -> FloatArray:
        arr = np.asarray(x, dtype=np.float64)
        if arr.ndim == 1:
            arr = arr[:, None]
        if arr.ndim != 2 or arr.shape[0] != tk.size:
            raise BioPlanError(
                f"{label} must have shape (K, n) with K = {tk.size} knots, got {arr.shape}"
            )
        return arr[None]

    qk, qdk, qddk = (
        as_states(lbl, x)
        for lbl, x in (("q_knots", q_knots), ("qd_knots", qd_knots), ("qdd_knots", qdd_knots))
    )
    btk, qk, qdk, qddk = _check_knots(tk[None], qk, qdk, qddk)
    t = time_grid(float(tk[-1]), n_samples)
    q, qd, qdd, jerk = _evaluate_quintic_segments(btk, qk, qdk, qddk, t, with_jerk=True)
    knots = (btk[0].copy(), qk[0].copy(), qdk[0].copy(), qddk[0].copy())
    return Trajectory(t=t, q=q[0], qd=qd[0], qdd=qdd[0], jerk=jerk[0], name=name, knots=knots)


# ----------------------------------------------------------------------------------------------
# Checks
# ----------------------------------------------------------------------------------------------


def _per_joint(label: str, value: ArrayLike, n: int) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,) or np.any(np.isnan(arr)):
        raise BioPlanError(f"{label} must be a number or a ({n},) array (one per joint), got {arr}")
    return arr


def check_limits(
    traj: Trajectory,
    *,
    q_min: ArrayLike | None = None,
    q_max: ArrayLike | None = None,
    qd_max: ArrayLike | None = None,
    qdd_max: ArrayLike | None = None,
    joint_names: Sequence[str] | None = None,
) -> list[str]:
    """Find the samples where a trajectory leaves its joint limits.

    Each limit is a number (all joints) or an (n,) array; velocity and acceleration limits bound
    the magnitude. For every joint and limit the worst violation is reported, e.g.
    ``"joint 2 velocity 3.4 rad/s exceeds 3.0 rad/s at t=0.41 s"``. Joints are numbered from 1
    (J1, J2, ... as on the robot) unless ``joint_names`` are given. Only samples are checked;
    an excess within ``LIMIT_TOL * max(1, |limit|)`` is round-off and not reported.

    Args:
        traj: the trajectory.
        q_min: lower position limits [rad].
        q_max: upper position limits [rad].
        qd_max: velocity magnitude limits [rad/s].
        qdd_max: acceleration magnitude limits [rad/s^2].
        joint_names: (n,) names used in the messages.

    Returns:
        Human-readable violations; empty when the trajectory respects every limit.
    """
    n = traj.n_joints
    if joint_names is not None and len(joint_names) != n:
        raise BioPlanError(f"joint_names must name all {n} joints, got {len(joint_names)}")
    names = list(joint_names) if joint_names is not None else [f"joint {j + 1}" for j in range(n)]
    out: list[str] = []

    def report(
        values: FloatArray, limit: ArrayLike | None, label: str, unit: str, kind: str
    ) -> None:
        if limit is None:
            return
        lim = _per_joint(f"{label} limit", limit, n)
        excess = lim[None, :] - values if kind == "min" else values - lim[None, :]
        worst = np.argmax(excess, axis=0)
        for j in range(n):
            k = int(worst[j])
            if excess[k, j] > LIMIT_TOL * max(1.0, abs(float(lim[j]))):
                verb = "is below" if kind == "min" else "exceeds"
                out.append(
                    f"{names[j]} {label} {values[k, j]:.4g} {unit} {verb} {lim[j]:.4g} {unit} "
                    f"at t={traj.t[k]:.3g} s"
                )

    report(traj.q, q_min, "position", "rad", "min")
    report(traj.q, q_max, "position", "rad", "max")
    report(np.abs(traj.qd), qd_max, "velocity", "rad/s", "max")
    report(np.abs(traj.qdd), qdd_max, "acceleration", "rad/s^2", "max")
    return out


def is_monotonic(traj: Trajectory, *, tol: float = MONOTONIC_TOL) -> NDArray[np.bool_]:
    """Per joint: does q never reverse direction?

    A joint is monotonic when it is non-decreasing or non-increasing over the samples, allowing
    it to fall back by at most ``tol`` from the furthest position reached so far (so round-off
    at a standstill does not count as a reversal, and many tiny reversals cannot add up).
    A joint that does not move is monotonic.

    Args:
        traj: the trajectory.
        tol: allowed setback [rad], >= 0.

    Returns:
        (n,) booleans.
    """
    if not tol >= 0.0:
        raise BioPlanError(f"tol must be >= 0 rad, got {tol!r}")
    q = traj.q
    rising = np.all(q >= np.maximum.accumulate(q, axis=0) - tol, axis=0)
    falling = np.all(q <= np.minimum.accumulate(q, axis=0) + tol, axis=0)
    result: NDArray[np.bool_] = rising | falling
    return result
