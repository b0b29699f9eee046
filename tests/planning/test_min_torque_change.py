"""Minimum-torque-change baseline (Uno, Kawato & Suzuki 1989)."""

from __future__ import annotations

import numpy as np
import pytest

from app.planning.min_torque_change import minimum_torque_change
from app.planning.profiles import quintic
from app.planning.robots import load_robot


class _ConstantInertia:
    """τ = I q̈: no gravity, no coupling. Minimum torque change is then minimum jerk."""

    n_joints = 2
    inertia = np.array([2.0, 0.5])

    def inverse_dynamics(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        return qdd * self.inertia


def test_reduces_to_minimum_jerk_without_gravity() -> None:
    start, goal = np.zeros(2), np.radians([20.0, 150.0])
    res = minimum_torque_change(_ConstantInertia(), start, goal, 1.0, n_samples=201)
    ref = quintic(start, goal, 1.0, n_samples=201)
    np.testing.assert_allclose(res.trajectory.q, ref.q, atol=1e-5)
    assert res.torque_change == pytest.approx(res.quintic_torque_change, rel=1e-6)


def test_with_gravity_beats_the_quintic_and_keeps_boundary_conditions() -> None:
    robot = load_robot("human_arm_2dof")
    start, goal = robot.default_start, robot.default_goal
    res = minimum_torque_change(robot.dynamics(), start, goal, 1.0, n_samples=301)
    tr = res.trajectory
    np.testing.assert_allclose(tr.q[[0, -1]], np.stack([start, goal]), atol=1e-12)
    np.testing.assert_allclose(tr.qd[[0, -1]], 0.0, atol=1e-9)
    np.testing.assert_allclose(tr.qdd[[0, -1]], 0.0, atol=1e-7)
    # Strictly better than its own starting point (the quintic) under gravity.
    assert res.torque_change < 0.99 * res.quintic_torque_change
    # Independent evaluation of J on the returned trajectory agrees with the optimiser's value.
    tau = robot.dynamics().inverse_dynamics(tr.q, tr.qd, tr.qdd)
    j = np.trapezoid(np.sum(np.gradient(tau, tr.t, axis=0) ** 2, axis=1), tr.t)
    assert j == pytest.approx(res.torque_change, rel=0.02)
