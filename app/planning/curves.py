"""Derived curves the dashboard draws but never computes: per-joint mechanical power and its
running integral.

The Compare page plots, joint by joint, the power ``|τ_j ω_j|`` each motor delivers and the
energy it has spent so far; both are derived here on the full time grid (before any decimation
for plotting, so the integral is as fine as the trajectory), and served with the curves.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.errors import BioPlanError
from app.planning.energy import cumulative_energy

__all__ = ["JointPower", "joint_power"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class JointPower:
    """Per-joint power and cumulative energy of one trajectory.

    Attributes:
        power: (T, n) absolute mechanical power ``|τ_j q̇_j|`` per joint [W].
        energy: (T, n) its running integral over time (trapezoidal rule) [J], 0 at ``t[0]``.
    """

    power: FloatArray
    energy: FloatArray


def joint_power(t: ArrayLike, tau: ArrayLike, qd: ArrayLike) -> JointPower:
    """Absolute power per joint and its cumulative energy.

    Args:
        t: (T,) sample times [s], increasing.
        tau: (T, n) joint torques [Nm].
        qd: (T, n) joint velocities [rad/s].

    Returns:
        ``JointPower`` with (T, n) ``power`` [W] and ``energy`` [J]; ``energy[-1, j]`` equals
        ``np.trapezoid(power[:, j], t)``.

    Raises:
        BioPlanError: when ``tau`` and ``qd`` differ in shape or do not have ``len(t)`` rows.
    """
    tt = np.asarray(t, dtype=np.float64)
    torque = np.asarray(tau, dtype=np.float64)
    velocity = np.asarray(qd, dtype=np.float64)
    if torque.ndim != 2 or torque.shape != velocity.shape or torque.shape[0] != tt.size:
        raise BioPlanError(
            f"tau and qd must both have shape ({tt.size}, n) to match t, "
            f"got {torque.shape} and {velocity.shape}"
        )
    power = np.abs(torque * velocity)
    # cumulative_energy integrates along the last axis: joints first, then back to (T, n).
    energy = cumulative_energy(tt, power.T).T
    return JointPower(power=power, energy=np.ascontiguousarray(energy))
