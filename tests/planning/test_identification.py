"""Identification from synthetic logs with known inertia changes, payload, friction and noise.

The "measured" torques come from MuJoCo's inverse dynamics of a *true* URDF (link 2 20 % heavier,
a 1.5 kg payload bolted to the last link) plus planted friction, offsets and noise; the
identification starts from the nominal URDF and runs on Pinocchio. The floor every residual is
held to is the true model's own residual on the same filtered log (noise that survives the
filter, and Coulomb switching smoothed by it).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.planning.identification import (
    IdentificationError,
    IdentifyOptions,
    identify,
    write_sidecar,
)
from app.planning.robots import load_robot
from app.planning.validation import validate
from app.recordings.robot_logs import read_robot_log
from tests.utils.robot_logs import arm_urdf, excitation, mujoco_torques, write_generic_csv

N = 3
VISCOUS = np.array([0.6, 0.9, 0.4])
COULOMB = np.array([1.2, 0.8, 0.5])
OFFSET = np.array([0.2, -0.3, 0.1])
TORQUE_NOISE = 0.1  # [Nm] white, per sample
POSITION_NOISE = 1e-5  # [rad]


def _true_masses() -> list[float]:
    masses = [4.0 - 0.5 * j for j in range(N)]
    masses[1] *= 1.2
    return masses


@pytest.fixture(scope="module")
def case(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("ident")
    nominal = folder / "arm.urdf"
    nominal.write_text(arm_urdf(N))
    true = folder / "true" / "arm.urdf"
    true.parent.mkdir()
    true.write_text(arm_urdf(N, masses=_true_masses(), payload=1.5))
    robot = load_robot(str(true))
    t, q, qd, qdd = excitation(20.0, 500.0, N, seed=3)
    rng = np.random.default_rng(7)
    tau = mujoco_torques(robot, q, qd, qdd)
    tau = tau + VISCOUS * qd + COULOMB * np.tanh(qd / 0.01) + OFFSET
    tau = tau + rng.normal(0.0, TORQUE_NOISE, tau.shape)
    q_logged = q + rng.normal(0.0, POSITION_NOISE, q.shape)
    log = write_generic_csv(folder / "log.csv", t, robot.joint_names, q_logged, tau)
    truth = folder / "true" / "truth.yaml"
    truth.write_text(
        "friction:\n"
        + "".join(
            f"  joint{j + 1}: {{viscous: {VISCOUS[j]}, coulomb: {COULOMB[j]}, "
            f"offset: {OFFSET[j]}}}\n"
            for j in range(N)
        )
    )
    return {"folder": folder, "nominal": nominal, "true": true, "log": log, "truth": truth}


def _floor(case: dict[str, Path]) -> dict[str, float]:
    """The true model's residual rms per joint on the log (with its true friction sidecar)."""
    robot = load_robot(str(case["true"]), sidecar=case["truth"])
    result = validate(robot, read_robot_log(case["log"])).result
    return {name: row["residual_rms"] for name, row in result["joints"].items()}


def test_identify_recovers_friction_and_predicts_held_back_at_noise_level(case):
    robot = load_robot(str(case["nominal"]))
    result = identify(robot, [read_robot_log(case["log"])], IdentifyOptions(validate_fraction=0.2))
    floor = _floor(case)
    for j, name in enumerate(robot.joint_names):
        f = result.friction[name]
        assert f["viscous"] == pytest.approx(VISCOUS[j], abs=0.05)
        assert f["coulomb"] == pytest.approx(COULOMB[j], abs=0.05)
        assert f["offset"] == pytest.approx(OFFSET[j], abs=0.05)
        # Held-back residual at the noise floor of the true model (within 30 % + 0.02 Nm).
        assert result.held_back[name]["residual_rms"] <= 1.3 * floor[name] + 0.02
        assert result.fit[name]["r2"] > 0.99
    # Physically consistent: positive masses, positive-definite inertias.
    for body in result.links.values():
        assert body["mass"] > 0.0
        xx, xy, xz, yy, yz, zz = body["inertia"]
        assert np.linalg.eigvalsh(np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])).min() > 0
    # Link masses one by one are not identifiable (only base combinations are): the torques
    # are what is checked, here and against MuJoCo in the next test.
    assert 0 < result.n_base < 10 * N


def test_identified_sidecar_changes_the_robot_and_matches_the_true_dynamics(case):
    nominal = load_robot(str(case["nominal"]))
    result = identify(nominal, [read_robot_log(case["log"])])
    sidecar = case["folder"] / "identified.yaml"
    write_sidecar(sidecar, nominal, result)
    identified = load_robot(str(case["nominal"]), sidecar=sidecar)
    true = load_robot(str(case["true"]))
    _, q, qd, qdd = excitation(3.0, 100.0, N, seed=11)  # a motion not in the log
    reference = mujoco_torques(true, q, qd, qdd)
    before = nominal.dynamics().inverse_dynamics(q, qd, qdd)
    after = identified.dynamics().inverse_dynamics(q, qd, qdd)
    error_before = np.sqrt(np.mean((before - reference) ** 2))
    error_after = np.sqrt(np.mean((after - reference) ** 2))
    assert error_after < 0.02 * error_before
    assert error_after < 0.05  # [Nm]; torques here reach tens of Nm (rms 6.8 Nm)
    # MuJoCo sees the same identified bodies as Pinocchio.
    simulated = mujoco_torques(identified, q, qd, qdd)
    assert np.allclose(simulated, after, atol=1e-6)
    # Friction reaches the motor model.
    assert [m.viscous_friction for m in identified.motors] == pytest.approx(
        [result.friction[n]["viscous"] for n in nominal.joint_names]
    )


def test_identify_payload(case):
    """Link 2 nominal, a payload identified at the last link instead of that link's inertia."""
    folder = case["folder"] / "payload"
    folder.mkdir()
    nominal = load_robot(str(case["nominal"]))
    masses = [4.0 - 0.5 * j for j in range(N)]
    true_path = folder / "arm.urdf"
    true_path.write_text(arm_urdf(N, masses=masses, payload=2.0))
    true = load_robot(str(true_path))
    t, q, qd, qdd = excitation(20.0, 200.0, N, seed=5)
    rng = np.random.default_rng(2)
    tau = mujoco_torques(true, q, qd, qdd) + rng.normal(0.0, TORQUE_NOISE, q.shape)
    log = write_generic_csv(folder / "log.csv", t, nominal.joint_names, q, tau)
    result = identify(nominal, [read_robot_log(log)], IdentifyOptions(identify_payload=True))
    assert result.payload is not None
    assert result.payload["mass"] == pytest.approx(2.0, rel=0.05)
    assert result.payload["com"] == pytest.approx([0.05, 0.0, 0.1], abs=0.02)
    assert "link3" not in result.links


def test_too_short_log_is_refused(case, tmp_path):
    robot = load_robot(str(case["nominal"]))
    t, q, qd, qdd = excitation(1.5, 200.0, N, seed=1)
    tau = mujoco_torques(robot, q, qd, qdd)
    log = write_generic_csv(tmp_path / "short.csv", t, robot.joint_names, q, tau)
    with pytest.raises(
        IdentificationError, match=r"short.csv: .* s of motion to fit: expected at least 2 s"
    ):
        identify(robot, [read_robot_log(log)])


def test_log_without_torque_is_refused(case, tmp_path):
    robot = load_robot(str(case["nominal"]))
    t, q, _, _ = excitation(5.0, 200.0, N)
    log = write_generic_csv(tmp_path / "no_effort.csv", t, robot.joint_names, q, None)
    with pytest.raises(IdentificationError, match=r"no_effort\.csv: no joint torque"):
        identify(robot, [read_robot_log(log)])


@pytest.mark.parametrize(
    ("section", "message"),
    [
        (
            "links:\n  link1: {mass: 1.0, com: [0, 0, 0], inertia: [1, 0, 0, 1, 0, 3]}\n",
            r"links\.link1\.inertia is .*: expected a positive-definite inertia",
        ),
        ("links:\n  link1: {mass: 1.0, com: [0, 0, 0]}\n", r"links\.link1 .*lacks inertia"),
        (
            "links:\n  nowhere: {mass: 1.0, com: [0, 0, 0], inertia: [1, 0, 0, 1, 0, 1]}\n",
            r"links\.nowhere is not a link of arm\.urdf",
        ),
        (
            "friction:\n  joint1: {viscous: -1}\n",
            r"friction\.joint1\.viscous is -1: expected a "
            r"number >= 0",
        ),
        ("friction:\n  joint9: {viscous: 1}\n", r"friction\.joint9 is not a free joint"),
    ],
)
def test_bad_identified_sidecar_sections_are_refused(case, tmp_path, section, message):
    from app.planning.robots import RobotError

    sidecar = tmp_path / "bad.yaml"
    sidecar.write_text(section)
    with pytest.raises(RobotError, match=r"bad\.yaml: " + message):
        load_robot(str(case["nominal"]), sidecar=sidecar)
