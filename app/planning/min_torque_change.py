"""Minimum-torque-change trajectories (Uno, Kawato & Suzuki 1989).

The human motor-control model the paper's 62 deg heuristic should be measured against: among all
rest-to-rest motions of a given duration, people's point-to-point arm movements are close to the
one that minimises the integrated squared rate of change of joint torque,

    J = ∫ Σ_j (dτ_j/dt)² dt.

With constant inertia and no gravity this is the minimum-jerk (quintic) trajectory; with gravity
and configuration-dependent inertia it is not. We solve it directly: each moving joint is the
quintic plus a correction c · φ_k(s), where φ_k(s) = s³(1-s)³ P_k(2s-1) (P_k Legendre
polynomials, s = t/T) vanish with their first and second derivatives at both ends, so position,
velocity and acceleration boundary conditions hold for every c. J is integrated by Gauss-Legendre
quadrature, with dτ/dt by a central difference of the analytic trajectory (not of a sampled
torque), so the discrete problem has the continuous one's minimiser. L-BFGS minimises J over c
with gradients by forward differences, all perturbed trajectories evaluated in one batched
inverse-dynamics call.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.polynomial import Polynomial
from numpy.polynomial import legendre as npleg
from numpy.typing import NDArray

from app.planning.profiles import Trajectory, time_grid

if TYPE_CHECKING:
    from app.planning.dynamics import Dynamics

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class MinTorqueChangeResult:
    """The optimised trajectory and how far the optimiser got.

    Attributes:
        trajectory: the minimum-torque-change trajectory on the requested grid.
        torque_change: J of the result [N² m² / s].
        quintic_torque_change: J of the quintic on the same task [N² m² / s].
        iterations: L-BFGS iterations.
        converged: whether L-BFGS reported convergence.
    """

    trajectory: Trajectory
    torque_change: float
    quintic_torque_change: float
    iterations: int
    converged: bool


def _basis(s: FloatArray, n_basis: int) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Basis functions and their s-derivatives up to third order, each (len(s), n_basis)."""
    bump = Polynomial([0.0, 0.0, 0.0, 1.0]) * Polynomial([1.0, -1.0]) ** 3  # s³(1-s)³
    cols: list[list[FloatArray]] = [[], [], [], []]
    for k in range(n_basis):
        leg = np.zeros(k + 1)
        leg[k] = 1.0
        # P_k(2s - 1) as a power series in s.
        pk = Polynomial(npleg.leg2poly(leg))(Polynomial([-1.0, 2.0]))
        phi = bump * pk
        for order in range(4):
            cols[order].append(phi.deriv(order)(s) if order else phi(s))
    b0, b1, b2, b3 = (np.stack(c, axis=1) for c in cols)
    return b0, b1, b2, b3


#: The rest-to-rest quintic's normalised shape 10s³ - 15s⁴ + 6s⁵.
_QUINTIC_SHAPE = Polynomial([0.0, 0.0, 0.0, 10.0, -15.0, 6.0])


@dataclass(frozen=True)
class _Family:
    """The trajectories searched: the quintic from ``start`` by ``delta`` (n,) [rad] in
    ``duration`` [s], plus ``n_basis`` correction terms per joint in ``moving`` (indices)."""

    start: FloatArray
    delta: FloatArray
    moving: NDArray[np.intp]
    duration: float
    n_basis: int

    def motion(self, coeffs: FloatArray, t: FloatArray) -> tuple[FloatArray, ...]:
        """Coefficient sets (B, dim) at times t (T,) -> q, qd, qdd, jerk each (B, T, n)."""
        start, delta, moving, duration = self.start, self.delta, self.moving, self.duration
        s = t / duration
        b0, b1, b2, b3 = _basis(s, self.n_basis)
        c = coeffs.reshape(coeffs.shape[0], moving.size, self.n_basis)
        shape = _QUINTIC_SHAPE
        out = []
        for order, bm in enumerate((b0, b1, b2, b3)):
            base = shape.deriv(order)(s) if order else shape(s)
            arr = np.empty((coeffs.shape[0], t.size, start.size))
            arr[:] = (start if order == 0 else 0.0) + np.outer(base, delta) / duration**order
            arr[:, :, moving] += np.einsum("tk,bjk->btj", bm, c) / duration**order
            out.append(arr)
        return tuple(out)


def minimum_torque_change(
    dynamics: Dynamics,
    start: FloatArray,
    goal: FloatArray,
    duration: float,
    *,
    n_samples: int = 100,
    n_basis: int = 6,
    quadrature_nodes: int = 48,
    max_iterations: int = 200,
) -> MinTorqueChangeResult:
    """Minimum-torque-change trajectory between two rest configurations.

    Args:
        dynamics: the robot's inverse dynamics (batched).
        start: (n,) start configuration [rad].
        goal: (n,) goal configuration [rad].
        duration: motion time [s].
        n_samples: samples of the returned trajectory.
        n_basis: correction terms per moving joint.
        quadrature_nodes: Gauss-Legendre nodes for the integral of the torque change.
        max_iterations: L-BFGS iteration limit.

    Returns:
        The trajectory (named ``"min_torque_change"``) and the objective values.
    """
    from scipy.optimize import minimize

    start = np.asarray(start, dtype=np.float64)
    goal = np.asarray(goal, dtype=np.float64)
    delta = goal - start
    moving = np.flatnonzero(np.abs(delta) > 0)
    dim = n_basis * moving.size

    build = _Family(start, delta, moving, duration, n_basis).motion

    # Gauss-Legendre nodes and weights on [0, T]; dτ/dt by central differences in time.
    x, w = npleg.leggauss(quadrature_nodes)
    nodes = 0.5 * duration * (x + 1.0)
    weights = 0.5 * duration * w
    h = 1e-5 * duration
    t_eval = np.concatenate([nodes - h, nodes + h])

    def torque_change(coeffs: FloatArray) -> FloatArray:
        tau = _inverse(dynamics, build(coeffs, t_eval))
        dtau = (tau[:, nodes.size :] - tau[:, : nodes.size]) / (2 * h)
        return np.asarray(np.sum(dtau**2, axis=-1) @ weights, dtype=np.float64)

    ref = float(torque_change(np.zeros((1, dim)))[0])
    scale = ref if ref > 0 else 1.0
    step = 1e-7

    def fun(c: FloatArray) -> tuple[float, FloatArray]:
        batch = np.vstack([c[None, :], c[None, :] + step * np.eye(dim)])
        j = torque_change(batch) / scale
        return float(j[0]), (j[1:] - j[0]) / step

    res = minimize(
        fun,
        np.zeros(dim),
        jac=True,
        method="L-BFGS-B",
        options={"maxiter": max_iterations, "gtol": 1e-9, "ftol": 1e-12},
    )
    best = np.asarray(res.x, dtype=np.float64)
    t = time_grid(duration, n_samples)
    q, qd, qdd, jerk = (a[0] for a in build(best[None, :], t))
    traj = Trajectory(t=t, q=q, qd=qd, qdd=qdd, jerk=jerk, name="min_torque_change")
    return MinTorqueChangeResult(
        trajectory=traj,
        torque_change=float(res.fun) * scale,
        quintic_torque_change=ref,
        iterations=int(res.nit),
        converged=bool(res.success),
    )


def _inverse(dynamics: Dynamics, qs: tuple[FloatArray, ...]) -> FloatArray:
    q, qd, qdd, _ = qs
    return np.asarray(dynamics.inverse_dynamics(q, qd, qdd), dtype=np.float64)
