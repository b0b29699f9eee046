"""Human-lift energetics checked against physics identities (power balance, statics)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from app.analysis.energetics import ArmDynamics, human_arm_dynamics, lift_energetics
from app.analysis.segmentation import Lift, split_phases
from app.recordings.types import RecordingError

pytest.importorskip("app.planning.robots")


@pytest.fixture(scope="module")
def arm() -> ArmDynamics:
    return human_arm_dynamics(body_mass=80.0, body_height=1.80, load_mass=12.0)


def _min_jerk(
    t: NDArray[np.float64], q0: float, q1: float, dur: float
) -> tuple[NDArray[np.float64], ...]:
    s = np.clip(t / dur, 0, 1)
    d = q1 - q0
    q = q0 + d * (10 * s**3 - 15 * s**4 + 6 * s**5)
    qd = d * (30 * s**2 - 60 * s**3 + 30 * s**4) / dur
    qdd = d * (60 * s - 180 * s**2 + 120 * s**3) / dur**2
    return q, qd, qdd


def _curl(rate: float = 1000.0, dur: float = 1.2) -> tuple[NDArray[np.float64], ...]:
    t = np.arange(int(dur * rate) + 1) / rate
    sq, sqd, sqdd = _min_jerk(t, 0.05, 0.25, dur)
    eq, eqd, eqdd = _min_jerk(t, np.deg2rad(10.0), np.deg2rad(140.0), dur)
    return t, np.stack([sq, eq], 1), np.stack([sqd, eqd], 1), np.stack([sqdd, eqdd], 1)


def test_joint_work_equals_change_of_mechanical_energy(arm: ArmDynamics) -> None:
    t, q, qd, qdd = _curl()
    lift = Lift(start=0.0, top=float(t[-1]), end=float(t[-1]), source="angle")
    phases = split_phases(q[:, 1], t, lift)
    en = lift_energetics(t, q, qd, qdd, arm, phases=phases)
    total = np.sum(0.5 * (en.power[1:] + en.power[:-1]).sum(axis=1) * np.diff(t))
    gained = en.kinetic[-1] - en.kinetic[0] + en.potential[-1] - en.potential[0]
    assert total == pytest.approx(gained, rel=1e-4)
    assert [p.phase.name for p in en.phases] == ["A", "B", "C"]
    for flow in en.phases:
        assert sum(flow.work) == pytest.approx(
            flow.delta_kinetic + flow.delta_potential, rel=1e-3, abs=1e-3
        )
    # The energy floors of DESIGN.md hold for a rest-to-rest lift (this one, with both joints
    # moving one way only, sits on the positive-work floor up to the quadrature error).
    m = en.metrics
    assert m["pos_work"] >= m["delta_potential"] * (1 - 1e-6)
    assert m["delta_potential"] > 0
    assert m["peak_power"] >= m["min_peak_power"]
    # Phase C: the arm slows down while rising, kinetic energy becomes potential energy.
    c = en.phases[-1]
    assert c.delta_kinetic < 0 < c.delta_potential
    assert c.kinetic_to_potential == pytest.approx(min(-c.delta_kinetic, c.delta_potential))


def test_static_torque_is_the_gradient_of_potential_energy(arm: ArmDynamics) -> None:
    rng = np.random.default_rng(0)
    q = rng.uniform([0.0, 0.1], [1.0, 2.5], size=(20, 2))
    zero = np.zeros_like(q)
    en = lift_energetics(np.arange(20.0), q, zero, zero, arm)
    h = 1e-6
    grad = np.stack(
        [
            (arm.potential_energy(q + h * e) - arm.potential_energy(q - h * e)) / (2 * h)
            for e in np.eye(2)
        ],
        axis=1,
    )
    np.testing.assert_allclose(en.torque, grad, rtol=1e-6, atol=1e-6)
    assert np.all(en.kinetic == 0)


def test_interval_and_gaps_restrict_the_samples(arm: ArmDynamics) -> None:
    t, q, qd, qdd = _curl(rate=100.0)
    qd = qd.copy()
    qd[:10] = np.nan
    en = lift_energetics(t, q, qd, qdd, arm, interval=(0.2, 0.8))
    assert en.t[0] == pytest.approx(0.2)
    assert en.t[-1] == pytest.approx(0.8)
    with pytest.raises(RecordingError, match="fewer than 3"):
        lift_energetics(t, q, qd, qdd, arm, interval=(0.0, 0.05))
    with pytest.raises(RecordingError, match="shape"):
        lift_energetics(t, q[:, :1], qd, qdd, arm)
