"""MuJoCo tracking: torques vs Pinocchio, energy bookkeeping, bad input, divergence."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from app.planning.energy import energy_metrics
from app.planning.profiles import Trajectory, piecewise_quintic, quintic
from app.planning.robots import Robot, RobotError, load_robot
from app.simulation.tracking import (
    DEFAULT_TIMESTEP,
    SimulationError,
    TrackingResult,
    resample,
    simulate_batch,
    simulate_tracking,
)

SCALARS = ("tau_sq", "abs_work", "pos_work", "electrical_energy", "peak_power")


@pytest.fixture(scope="module")
def cw() -> Robot:
    return load_robot("curtain_wall_6dof")


def _bio_like(robot: Robot, duration: float = 1.0, n_samples: int = 1001) -> Trajectory:
    """A two-segment curl: the elbow passes 62 deg at 40 % of the time, fastest there."""
    start, goal = np.asarray(robot.default_start), np.asarray(robot.default_goal)
    via = start + 0.45 * (goal - start)
    via[robot.elbow_joint] = math.radians(62.0)
    speed = 1.6 * (goal - start) / duration
    tk = np.array([0.0, 0.4 * duration, duration])
    qk = np.stack([start, via, goal])
    qdk = np.stack([np.zeros_like(start), speed, np.zeros_like(start)])
    return piecewise_quintic(tk, qk, qdk, np.zeros_like(qk), n_samples=n_samples, name="bio")


@pytest.fixture(scope="module")
def runs(cw: Robot) -> tuple[list[Trajectory], list[TrackingResult]]:
    trajs = [
        quintic(cw.default_start, cw.default_goal, 1.0, n_samples=1001),
        _bio_like(cw),
    ]
    return trajs, simulate_batch(cw, trajs)


def test_applied_torque_is_pinocchio_inverse_dynamics_of_the_simulated_motion(
    cw: Robot, runs: tuple[list[Trajectory], list[TrackingResult]]
) -> None:
    # Semi-implicit Euler: v[k+1] = v[k] + dt a[k] with a[k] = M^-1 (tau[k] - bias), then
    # q[k+1] = q[k] + dt v[k+1]. So MuJoCo's velocity state is v[k] = (q[k] - q[k-1]) / dt, and
    # Pinocchio's RNEA at (q[k], v[k], a[k]) must return MuJoCo's applied torque.
    dt = DEFAULT_TIMESTEP
    for run in runs[1]:
        v = np.diff(run.q, axis=0) / dt  # v[1..T-1]
        a = np.diff(v, axis=0) / dt  # a[1..T-2]
        tau_id = cw.dynamics().inverse_dynamics(run.q[1:-1], v[:-1], a)
        assert np.abs(run.tau[1:-1] - tau_id).max() < 1e-5  # Nm, vs peaks of ~180 Nm
        # The reported velocity is the central difference of the positions.
        np.testing.assert_allclose(run.qd[1:-1], 0.5 * (v[:-1] + v[1:]), atol=1e-9)


def test_simulated_torque_agrees_with_planned_inverse_dynamics(cw: Robot) -> None:
    # Feed-forward from MuJoCo's own mj_inverse, so Pinocchio enters only as the reference.
    traj = _bio_like(cw)
    run = simulate_tracking(cw, traj, feedforward="mujoco")
    tau_plan = cw.dynamics().inverse_dynamics(traj.q, traj.qd, traj.qdd)
    peak = np.abs(tau_plan).max(axis=0)
    # Stated tolerance: 1 % of each joint's peak torque (+1e-6 Nm for joints that do not move).
    assert np.all(np.abs(run.tau - tau_plan).max(axis=0) <= 0.01 * peak + 1e-6)
    assert np.abs(run.tau_feedforward - tau_plan).max() < 1e-6  # mj_inverse == RNEA


def test_simulated_metrics_agree_with_planned_within_2_percent(
    cw: Robot, runs: tuple[list[Trajectory], list[TrackingResult]]
) -> None:
    for traj, run in zip(*runs, strict=True):
        assert run.tracking_ok
        tau_plan = cw.dynamics().inverse_dynamics(traj.q, traj.qd, traj.qdd)
        planned = energy_metrics(traj.t, traj.qd, tau_plan, motors=cw.motors)
        for name in SCALARS:
            sim, ref = getattr(run.metrics, name), getattr(planned, name)
            assert abs(sim - ref) <= 0.02 * abs(ref), (traj.name, name, sim, ref)


def test_tracking_error_is_small_and_reported_per_joint(
    runs: tuple[list[Trajectory], list[TrackingResult]],
) -> None:
    for traj, run in zip(*runs, strict=True):
        err = np.abs(traj.q - run.q)
        np.testing.assert_allclose(run.tracking_max, err.max(axis=0))
        np.testing.assert_allclose(run.tracking_rms, np.sqrt((err**2).mean(axis=0)))
        assert run.tracking_max.max() < math.radians(0.1)
        assert np.all(run.saturation == 0.0)
        assert run.warnings == ()


def test_work_equals_mechanical_energy_change(
    cw: Robot, runs: tuple[list[Trajectory], list[TrackingResult]]
) -> None:
    # Work-energy theorem on the simulated motion: int tau.qd dt = dKE + dPE (Pinocchio's
    # energies). Euler and the trapezoidal rule are first order: 0.5 % of |work| is stated.
    dyn = cw.dynamics()
    for run in runs[1]:
        work = float(np.trapezoid((run.tau * run.qd).sum(axis=1), run.t))
        ke = dyn.kinetic_energy(run.q[[0, -1]], run.qd[[0, -1]])
        pe = dyn.potential_energy(run.q[[0, -1]])
        assert work == pytest.approx(float(ke[1] - ke[0] + pe[1] - pe[0]), rel=5e-3)


def test_curves_integrate_to_the_metrics(
    runs: tuple[list[Trajectory], list[TrackingResult]],
) -> None:
    for run in runs[1]:
        assert run.energy[-1] == pytest.approx(run.metrics.abs_work, rel=1e-12)
        assert run.electrical_energy[-1] == pytest.approx(run.metrics.electrical_energy, rel=1e-12)
        np.testing.assert_allclose(run.joint_energy.sum(axis=1), run.energy, atol=1e-9)
        np.testing.assert_allclose(run.joint_power, run.tau * run.qd)
        np.testing.assert_allclose(
            run.joint_electrical_power.sum(axis=1), run.electrical_power, atol=1e-9
        )
        # Friction and copper losses: the drives draw more than the mechanical work.
        assert run.metrics.electrical_energy > run.metrics.pos_work


def test_rollout_and_python_loop_backends_agree(cw: Robot) -> None:
    traj = _bio_like(cw, n_samples=301)
    a = simulate_tracking(cw, traj, backend="rollout")
    b = simulate_tracking(cw, traj, backend="loop")
    assert (a.backend, b.backend) == ("rollout", "loop")
    np.testing.assert_allclose(a.q, b.q, atol=1e-12)
    np.testing.assert_allclose(a.tau, b.tau, atol=1e-8)


def test_same_input_gives_bit_identical_results(cw: Robot) -> None:
    traj = quintic(cw.default_start, cw.default_goal, 0.5, n_samples=501)
    a, b = simulate_tracking(cw, traj), simulate_tracking(cw, traj)
    assert np.array_equal(a.q, b.q) and np.array_equal(a.tau, b.tau)
    assert a.metrics == b.metrics


def test_resample_reproduces_a_quintic_exactly() -> None:
    q0, q1 = np.array([0.0, 0.2]), np.array([0.5, 2.6])
    coarse = quintic(q0, q1, 1.0, n_samples=11)
    fine = quintic(q0, q1, 1.0, n_samples=1001)
    out = resample(coarse, fine.t)
    for name in ("q", "qd", "qdd", "jerk"):
        np.testing.assert_allclose(getattr(out, name), getattr(fine, name), atol=1e-9)
    held = resample(coarse, np.array([1.2, 1.5]))  # after the end: at rest at the goal
    np.testing.assert_allclose(held.q, np.stack([coarse.q[-1], coarse.q[-1]]), rtol=0, atol=0)
    assert np.all(held.qd == 0.0) and np.all(held.qdd == 0.0)


def test_other_grids_and_durations_are_resampled_onto_the_1khz_grid(cw: Robot) -> None:
    traj = quintic(cw.default_start, cw.default_goal, 0.7505, n_samples=37)
    run = simulate_tracking(cw, traj)
    assert run.t.size == 752  # ceil(0.7505 / 1 ms) + 1 samples; the goal is held at the end
    assert np.allclose(np.diff(run.t), DEFAULT_TIMESTEP)
    assert run.tracking_ok


def test_human_arm_is_simulated_too() -> None:
    arm = load_robot("human_arm_2dof")
    traj = quintic(arm.default_start, arm.default_goal, 1.0, n_samples=1001)
    run = simulate_tracking(arm, traj)
    assert run.tracking_ok
    tau_plan = arm.dynamics().inverse_dynamics(traj.q, traj.qd, traj.qdd)
    planned = energy_metrics(traj.t, traj.qd, tau_plan, motors=arm.motors)
    assert run.metrics.abs_work == pytest.approx(planned.abs_work, rel=0.02)


# ----------------------------------------------------------------------------------------------
# Bad input and instability: clear errors or warnings, never NaN, never stray output
# ----------------------------------------------------------------------------------------------


def test_runaway_simulation_is_a_clear_error_without_stray_output(
    cw: Robot, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    # Absurd gains and no torque limit: explicit feedback with kp dt^2 / m >> 4 blows up.
    monkeypatch.chdir(tmp_path)
    unlimited = dataclasses.replace(cw, tau_max=np.full(6, 1e30))
    traj = quintic(cw.default_start, cw.default_goal, 0.3, n_samples=301)
    for backend in ("rollout", "loop"):
        with pytest.raises(SimulationError, match="diverged at t=") as info:
            simulate_tracking(unlimited, traj, kp=1e9, kd=1e7, backend=backend)  # type: ignore[arg-type]
        assert "expected a stable closed loop" in str(info.value)
    out, err = capfd.readouterr()
    assert out == "" and err == ""  # MuJoCo's warnings are captured, not printed
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_absurd_gains_within_torque_limits_saturate_and_warn(cw: Robot) -> None:
    traj = quintic(cw.default_start, cw.default_goal, 1.0, n_samples=1001)
    run = simulate_tracking(cw, traj, kp=1e9, kd=1e7)
    assert run.saturation.max() > 0.5
    assert any("torque limit" in w and "of the run" in w for w in run.warnings)
    assert all(np.all(np.isfinite(a)) for a in run.arrays().values())


def test_payload_that_cannot_be_held_warns_with_finite_numbers(cw: Robot) -> None:
    heavy = cw.with_payload(400.0)
    traj = quintic(heavy.default_start, heavy.default_goal, 1.0, n_samples=1001)
    run = simulate_tracking(heavy, traj)
    assert run.saturation.max() > 0.5
    text = " ".join(run.warnings)
    assert "torque limit" in text and "poor tracking" in text
    for name, arr in run.arrays().items():
        assert np.all(np.isfinite(arr)), name
    assert all(math.isfinite(v) for v in run.metrics.to_dict()["peak_torque"])  # type: ignore[union-attr]
    assert np.all(np.abs(run.tau) <= np.asarray(heavy.tau_max) + 1e-9)


def test_robot_without_mjcf_is_a_clear_error(cw: Robot) -> None:
    bare = dataclasses.replace(cw, mjcf_path=None)
    traj = quintic(cw.default_start, cw.default_goal, 1.0, n_samples=101)
    with pytest.raises(RobotError, match="no MJCF"):
        simulate_tracking(bare, traj)


def test_commanded_motion_outside_joint_limits_is_refused(cw: Robot) -> None:
    goal = np.array(cw.default_goal)
    goal[cw.elbow_joint] = math.radians(175.0)  # the elbow stops at 160 deg
    traj = quintic(cw.default_start, goal, 1.0, n_samples=101)
    with pytest.raises(SimulationError, match=r"joint position limits.*j3_elbow_pitch"):
        simulate_tracking(cw, traj)


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        (lambda tr: dataclasses.replace(tr, q=tr.q[:, :2]), "expected (101, 6)"),
        (lambda tr: dataclasses.replace(tr, qd=tr.qd * np.nan), "NaN"),
        (lambda tr: dataclasses.replace(tr, t=tr.t + 0.5), "expected t=0"),
    ],
)
def test_malformed_trajectories_are_refused(cw: Robot, change: object, needle: str) -> None:
    traj = quintic(cw.default_start, cw.default_goal, 1.0, n_samples=101)
    with pytest.raises(SimulationError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        simulate_tracking(cw, change(traj))  # type: ignore[operator]


def test_bad_options_are_refused(cw: Robot) -> None:
    traj = quintic(cw.default_start, cw.default_goal, 1.0, n_samples=101)
    with pytest.raises(SimulationError, match="timestep"):
        simulate_tracking(cw, traj, timestep=0.0)
    with pytest.raises(SimulationError, match="kp"):
        simulate_tracking(cw, traj, kp=[1.0, 2.0])
    with pytest.raises(SimulationError, match="feedforward"):
        simulate_tracking(cw, traj, feedforward="magic")  # type: ignore[arg-type]


def test_user_mjcf_without_actuators_falls_back_to_the_python_loop(
    cw: Robot, tmp_path: Path
) -> None:
    assert cw.mjcf_path is not None
    text = cw.mjcf_path.read_text(encoding="utf-8")
    start, end = text.index("<actuator>"), text.index("</actuator>") + len("</actuator>")
    bare_xml = tmp_path / "no_actuators.xml"
    bare_xml.write_text(text[:start] + text[end:], encoding="utf-8")
    with_act = load_robot(cw.urdf_path, mjcf=cw.mjcf_path, payload=4.0)
    without = load_robot(cw.urdf_path, mjcf=bare_xml, payload=4.0)
    traj = _bio_like(cw, n_samples=201)
    a = simulate_tracking(with_act, traj)
    b = simulate_tracking(without, traj)
    assert (a.backend, b.backend) == ("rollout", "loop")
    np.testing.assert_allclose(a.q, b.q, atol=1e-12)
    np.testing.assert_allclose(a.tau, b.tau, atol=1e-8)
    with pytest.raises(SimulationError, match="one joint actuator per joint"):
        simulate_tracking(without, traj, backend="rollout")
