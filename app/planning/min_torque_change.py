"""Minimum-torque-change trajectories (Uno, Kawato & Suzuki 1989).

The human motor-control model the paper's 62 deg heuristic should be measured against: among all
rest-to-rest motions of a given duration, people's point-to-point arm movements are close to the
one that minimises the integrated squared rate of change of joint torque,

    J = ∫ Σ_j (dτ_j/dt)² dt.

With constant inertia and no gravity this is the minimum-jerk (quintic) trajectory; with gravity
and configuration-dependent inertia it is not. We solve it directly: each moving joint is the
quintic plus a correction c · φ_k(s), where φ_k(s) = s³(1-s)³ P_k(2s-1) (P_k Legendre
polynomials, s = t/T) vanish with their first and second derivatives at both ends, so position,
velocity and acceleration boundary conditions hold for every c. L-BFGS minimises J over c with
gradients by forward differences, all perturbed trajectories evaluated in one batched
inverse-dynamics call.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.polynomial import Polynomial
from numpy.polynomial import legendre as npleg
from numpy.typing import NDArray

from app.planning.profiles import Trajectory, quintic, time_grid

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


def _torque_change(t: FloatArray, tau: FloatArray) -> FloatArray:
    """∫ Σ_j (dτ_j/dt)² dt for (..., T, n) torques on grid t (T,) -> (...,)."""
    dtau = np.gradient(tau, t, axis=-2)
    integrand = np.sum(dtau**2, axis=-1)
    return np.asarray(np.trapezoid(integrand, t, axis=-1), dtype=np.float64)


def minimum_torque_change(
    dynamics: Dynamics,
    start: FloatArray,
    goal: FloatArray,
    duration: float,
    *,
    n_samples: int = 100,
    n_basis: int = 6,
    solve_samples: int = 201,
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
        solve_samples: time samples used while optimising.
        max_iterations: L-BFGS iteration limit.

    Returns:
        The trajectory (named ``"min_torque_change"``) and the objective values.
    """
    from scipy.optimize import minimize

    start = np.asarray(start, dtype=np.float64)
    goal = np.asarray(goal, dtype=np.float64)
    moving = np.flatnonzero(np.abs(goal - start) > 0)
    n = start.size
    dim = n_basis * moving.size

    def build(coeffs: FloatArray, t: FloatArray) -> tuple[FloatArray, ...]:
        """Coefficient sets (B, dim) -> q, qd, qdd, jerk each (B, T, n)."""
        base = quintic(start, goal, duration, n_samples=t.size)
        s = t / duration
        b0, b1, b2, b3 = _basis(s, n_basis)
        c = coeffs.reshape(coeffs.shape[0], moving.size, n_basis)
        out = []
        for order, (bm, ref) in enumerate(
            zip((b0, b1, b2, b3), (base.q, base.qd, base.qdd, base.jerk), strict=True)
        ):
            arr = np.broadcast_to(ref, (coeffs.shape[0], *ref.shape)).copy()
            arr[:, :, moving] += np.einsum("tk,bjk->btj", bm, c) / duration**order
            out.append(arr)
        return tuple(out)

    t_solve = time_grid(duration, solve_samples)
    ref = float(_torque_change(t_solve, _inverse(dynamics, build(np.zeros((1, dim)), t_solve)))[0])
    scale = ref if ref > 0 else 1.0
    step = 1e-6

    def fun(c: FloatArray) -> tuple[float, FloatArray]:
        batch = np.vstack([c[None, :], c[None, :] + step * np.eye(dim)])
        j = _torque_change(t_solve, _inverse(dynamics, build(batch, t_solve))) / scale
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
