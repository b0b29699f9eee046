"""Energy metrics: hand-computed cases, analytic integrals, invariants, floors, the motor model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from app.planning.energy import (
    FRICTION_VELOCITY_SCALE,
    OBJECTIVES,
    EnergyMetrics,
    MotorModel,
    cumulative_energy,
    electrical_power,
    energy_metrics,
    floors,
    improvement_pct,
    joint_power,
    objective_values,
    power_curve,
)
from app.planning.profiles import quintic

IDEAL = MotorModel(
    gear_ratio=1.0,
    torque_constant=1.0,
    winding_resistance=0.0,
    rotor_inertia=0.0,
    viscous_friction=0.0,
    coulomb_friction=0.0,
    regen_efficiency=0.0,
)


def _motor(**changes: float) -> MotorModel:
    values = {
        "gear_ratio": 1.0,
        "torque_constant": 1.0,
        "winding_resistance": 0.0,
        "rotor_inertia": 0.0,
        "viscous_friction": 0.0,
        "coulomb_friction": 0.0,
        "regen_efficiency": 0.0,
    }
    values.update(changes)
    return MotorModel(**values)


def test_objectives_are_the_designed_six() -> None:
    assert OBJECTIVES == (
        "tau_sq",
        "abs_work",
        "pos_work",
        "electrical_energy",
        "peak_power",
        "peak_torque",
    )


def test_constant_torque_and_velocity_by_hand() -> None:
    # Joint 1 drives (2 Nm x 0.5 rad/s = +1 W), joint 2 brakes (-3 Nm x 0.5 rad/s = -1.5 W).
    t = np.linspace(0.0, 2.0, 9)
    qd = np.tile([0.5, 0.5], (9, 1))
    tau = np.tile([2.0, -3.0], (9, 1))
    m = energy_metrics(t, qd, tau)
    assert m.tau_sq == pytest.approx((4 + 9) * 2.0)
    assert m.abs_work == pytest.approx(2.5 * 2.0)
    assert m.pos_work == pytest.approx(1.0 * 2.0)
    assert m.peak_power == pytest.approx(2.5)
    assert m.peak_torque == pytest.approx((2.0, 3.0))
    # Ideal actuators share the bus: +1 W - 1.5 W = -0.5 W, nothing drawn.
    assert m.electrical_energy == 0.0
    # N k_t = 1 Nm/A, so i = tau [A]; copper loss R i^2 = 2 (4 + 9) = 26 W on top.
    motors = [_motor(gear_ratio=10.0, torque_constant=0.1, winding_resistance=2.0)] * 2
    me = energy_metrics(t, qd, tau, motors=motors)
    assert me.electrical_energy == pytest.approx((-0.5 + 26.0) * 2.0)
    np.testing.assert_allclose(electrical_power(qd, tau, motors), 25.5)
    assert me.to_dict()["peak_torque"] == [2.0, 3.0]


# A sinusoidal swing over one period: q = A sin(wt), qd = A w cos(wt).
A, B, W = 0.8, 3.0, 2 * math.pi / 1.5
T_PERIOD = 2 * math.pi / W
T = np.linspace(0.0, T_PERIOD, 20001)
QD = (A * W * np.cos(W * T))[:, None]


def test_sinusoid_in_phase_analytic_integrals() -> None:
    tau = (B * np.cos(W * T))[:, None]  # P = A B w cos^2 >= 0
    m = energy_metrics(T, QD, tau)
    assert m.tau_sq == pytest.approx(B**2 * T_PERIOD / 2, rel=1e-7)
    assert m.abs_work == pytest.approx(A * B * math.pi, rel=1e-7)
    assert m.pos_work == pytest.approx(A * B * math.pi, rel=1e-7)
    assert m.peak_power == pytest.approx(A * B * W, rel=1e-9)
    assert m.peak_torque == pytest.approx((B,))
    assert m.electrical_energy == pytest.approx(A * B * math.pi, rel=1e-7)


def test_sinusoid_quadrature_analytic_integrals_and_curves() -> None:
    tau = (B * np.sin(W * T))[:, None]  # P = (A B w / 2) sin(2wt): net zero
    m = energy_metrics(T, QD, tau)
    assert m.abs_work == pytest.approx(2 * A * B, rel=1e-6)
    assert m.pos_work == pytest.approx(A * B, rel=1e-6)
    assert m.peak_power == pytest.approx(A * B * W / 2, rel=1e-6)
    expected_power = A * B * W / 2 * np.sin(2 * W * T)
    np.testing.assert_allclose(joint_power(QD, tau)[:, 0], expected_power, atol=1e-12)
    np.testing.assert_allclose(power_curve(QD, tau), np.abs(expected_power), atol=1e-12)
    # ∫0^t (A B w / 2) sin(2 w s) ds = A B (1 - cos 2wt) / 4
    energy = cumulative_energy(T, joint_power(QD, tau)[:, 0])
    assert energy[0] == 0.0
    np.testing.assert_allclose(energy, A * B * (1 - np.cos(2 * W * T)) / 4, atol=1e-7)
    assert energy[-1] == pytest.approx(np.trapezoid(expected_power, T), abs=1e-12)


def test_cumulative_energy_is_batched() -> None:
    p = np.stack([np.ones_like(T), 2 * T])
    e = cumulative_energy(T, p)
    assert e.shape == (2, T.size)
    np.testing.assert_allclose(e[0], T, atol=1e-12)
    np.testing.assert_allclose(e[1], T**2, atol=1e-6)


def test_ideal_actuator_is_pos_work_of_bus_power() -> None:
    # Joint 1 delivers A B w cos^2, joint 2 absorbs half of it: the bus nets A B w cos^2 / 2.
    qd = np.hstack([QD, QD])
    tau = np.hstack([(B * np.cos(W * T))[:, None], (-B / 2 * np.cos(W * T))[:, None]])
    m = energy_metrics(T, qd, tau, motors=[IDEAL, IDEAL])
    assert m.electrical_energy == pytest.approx(A * B * math.pi / 2, rel=1e-7)
    assert m.pos_work == pytest.approx(A * B * math.pi, rel=1e-7)  # per joint, no sharing
    assert energy_metrics(T, qd, tau).electrical_energy == m.electrical_energy  # None = ideal
    # One joint: the bus is that joint, so electrical energy equals pos_work.
    tau1 = (B * np.sin(W * T))[:, None]
    m1 = energy_metrics(T, QD, tau1, motors=[IDEAL])
    assert m1.electrical_energy == pytest.approx(m1.pos_work, rel=1e-12)


def test_winding_resistance_adds_copper_loss() -> None:
    tau = (B * np.cos(W * T))[:, None]
    gear, kt, res = 50.0, 0.05, 0.8
    m = energy_metrics(
        T, QD, tau, motors=[_motor(gear_ratio=gear, torque_constant=kt, winding_resistance=res)]
    )
    copper = res * (B / (gear * kt)) ** 2 * T_PERIOD / 2  # ∫ R i^2 dt, i = B cos / (N k_t)
    assert m.electrical_energy == pytest.approx(A * B * math.pi + copper, rel=1e-7)


def test_friction_adds_viscous_and_coulomb_losses() -> None:
    b, c = 0.7, 0.4
    zero = np.zeros_like(QD)
    m = energy_metrics(T, QD, zero, motors=[_motor(viscous_friction=b, coulomb_friction=c)])
    # ∫ b qd^2 = b A^2 w^2 T / 2; ∫ c |qd| = c A w (2 T / pi) = 4 c A (tanh smoothing aside).
    expected = b * A**2 * W**2 * T_PERIOD / 2 + 4 * c * A
    assert m.electrical_energy == pytest.approx(expected, rel=1e-3)
    assert FRICTION_VELOCITY_SCALE > 0
    # Friction only ever costs energy.
    assert np.all(electrical_power(QD, zero, [_motor(viscous_friction=b, coulomb_friction=c)]) >= 0)


def test_regeneration_uses_the_smallest_joint_efficiency() -> None:
    tau = (B * np.sin(W * T))[:, None]  # gives back as much as it takes: +A B, -A B
    m = energy_metrics(T, QD, tau, motors=[_motor(regen_efficiency=0.5)])
    assert m.electrical_energy == pytest.approx(A * B - 0.5 * A * B, rel=1e-6)
    qd2 = np.hstack([QD, np.zeros_like(QD)])
    tau2 = np.hstack([tau, np.zeros_like(tau)])
    motors = [_motor(regen_efficiency=0.9), _motor(regen_efficiency=0.25)]
    m2 = energy_metrics(T, qd2, tau2, motors=motors)
    assert m2.electrical_energy == pytest.approx(A * B * (1 - 0.25), rel=1e-6)


def test_pendulum_lift_respects_floors() -> None:
    """A point mass m on a massless rod l lifted from hanging (q = 0) to horizontal (pi / 2)
    along a quintic: tau = m l^2 qdd + m g l sin q (closed form), ΔPE = m g l."""
    mass, length, g, duration = 4.0, 0.45, 9.81, 1.2
    traj = quintic([0.0], [math.pi / 2], duration, n_samples=4001)
    tau = mass * length**2 * traj.qdd + mass * g * length * np.sin(traj.q)
    fl = floors(mass * g * length, duration)
    assert fl.delta_potential == pytest.approx(mass * g * length)
    assert fl.min_peak_power == pytest.approx(mass * g * length / duration)
    m = energy_metrics(traj.t, traj.qd, tau)
    net = np.trapezoid((traj.qd * tau).sum(axis=1), traj.t)
    assert net == pytest.approx(fl.delta_potential, rel=1e-6)  # rest to rest: ΔKE = 0
    assert m.abs_work >= m.pos_work >= fl.delta_potential * (1 - 1e-9)
    assert m.peak_power >= fl.min_peak_power
    # Lowering: |ΔPE| of absolute work and |ΔPE|/T of peak power are still unavoidable (the
    # arm must absorb the energy); positive work and (without friction) bus energy can be 0.
    lowering = floors(-3.0, 2.0).to_dict()
    assert lowering["delta_potential"] == -3.0
    assert lowering["min_peak_power"] == lowering["peak_power"] == 1.5
    assert lowering["abs_work"] == 3.0
    assert lowering["pos_work"] == 0.0
    assert lowering["electrical_energy"] == 0.0


def test_floors_reject_bad_input() -> None:
    with pytest.raises(ValueError, match="duration"):
        floors(1.0, 0.0)
    with pytest.raises(ValueError, match="delta_potential"):
        floors(math.nan, 1.0)


_finite = st.floats(-50.0, 50.0, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None)
@given(
    qd=hnp.arrays(np.float64, (12, 3), elements=_finite),
    tau=hnp.arrays(np.float64, (12, 3), elements=_finite),
    steps=hnp.arrays(np.float64, (11,), elements=st.floats(1e-3, 1.0)),
)
def test_metric_invariants(qd: np.ndarray, tau: np.ndarray, steps: np.ndarray) -> None:
    t = np.concatenate([[0.0], np.cumsum(steps)])
    m = energy_metrics(t, qd, tau)
    net = float(np.trapezoid((qd * tau).sum(axis=1), t))
    slack = 1e-9 * (1.0 + m.abs_work)
    assert m.abs_work >= m.pos_work - slack
    assert m.pos_work >= net - slack
    assert m.peak_power * (t[-1] - t[0]) >= m.abs_work - slack
    # Sharing the bus can only reduce what ideal actuators draw.
    assert 0.0 <= m.electrical_energy <= m.pos_work + slack


def test_objective_values_batched_match_metrics() -> None:
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.0, 50)
    qd = rng.normal(size=(4, 50, 2))
    tau = rng.normal(size=(4, 50, 2)) * 5
    motors = [_motor(gear_ratio=20.0, torque_constant=0.1, winding_resistance=0.5)] * 2
    for name in OBJECTIVES:
        if name == "peak_torque":
            continue
        batch = objective_values(name, t, qd, tau, motors=motors)
        assert batch.shape == (4,)
        for b in range(4):
            single = energy_metrics(t, qd[b], tau[b], motors=motors)
            assert batch[b] == pytest.approx(getattr(single, name), rel=1e-12)
    peak = objective_values("peak_torque", t, qd, tau)
    np.testing.assert_allclose(peak, np.abs(tau).max(axis=(1, 2)))
    limits = np.array([10.0, 2.0])
    rel = objective_values("peak_torque", t, qd, tau, tau_max=limits)
    np.testing.assert_allclose(rel, (np.abs(tau) / limits).max(axis=(1, 2)))
    assert objective_values("abs_work", t, qd[0], tau[0]).shape == ()


def test_objective_values_rejects_bad_input() -> None:
    t = np.linspace(0.0, 1.0, 5)
    x = np.ones((5, 2))
    with pytest.raises(ValueError, match="expected one of: tau_sq, abs_work"):
        objective_values("energy", t, x, x)
    with pytest.raises(ValueError, match="samples along axis -2"):
        objective_values("abs_work", t[:4], x, x)
    with pytest.raises(ValueError, match="same shape"):
        objective_values("abs_work", t, x, x[:, :1])
    with pytest.raises(ValueError, match="one MotorModel per joint"):
        objective_values("electrical_energy", t, x, x, motors=[IDEAL])
    with pytest.raises(ValueError, match="tau_max"):
        objective_values("peak_torque", t, x, x, tau_max=[1.0, 0.0])
    with pytest.raises(ValueError, match="strictly increasing"):
        energy_metrics(t[::-1], x, x)


def _metrics(value: float, torques: tuple[float, ...] = (1.0, 2.0)) -> EnergyMetrics:
    return EnergyMetrics(value, value, value, value, value, torques)


def test_improvement_pct_signs() -> None:
    better = improvement_pct(_metrics(10.0, (4.0, 2.0)), _metrics(8.0, (5.0, 1.0)))
    assert better["abs_work"] == pytest.approx(20.0)
    assert better["peak_torque"] == pytest.approx([-25.0, 50.0])
    worse = improvement_pct(_metrics(10.0), _metrics(12.0))
    assert worse["tau_sq"] == pytest.approx(-20.0)
    # Net regeneration (negative standard): less negative is worse, so still negative.
    regen = improvement_pct(_metrics(-10.0), _metrics(-5.0))
    assert regen["electrical_energy"] == pytest.approx(-50.0)
    zero = improvement_pct(_metrics(0.0, (0.0, 0.0)), _metrics(0.0, (0.0, 1.0)))
    assert zero["pos_work"] == 0.0
    assert zero["peak_torque"][0] == 0.0  # type: ignore[index]
    assert math.isnan(zero["peak_torque"][1])  # type: ignore[index]
