"""Identification and validation speed: 20 s of a 7-joint arm logged at 1 kHz.

The arm is a synthetic 7-joint serial URDF (example-robot-data's Panda is not installed in this
environment): yaw and pitch joints alternating, 0.3 m links. The "true" arm has link 3 20 %
heavier and a 2 kg payload; its torques come from MuJoCo's inverse dynamics of an excitation
(five sines per joint) plus viscous and Coulomb friction, offsets and 0.2 Nm noise, written as a
generic robot-log CSV. Timed are ``identify`` (from reading the CSV to the consistent fit and the
held-back check) and ``validate`` (reading, filtering, inverse dynamics, comparison); the JSON
also gives the held-back residuals.

Run ``python benchmarks/identify.py [--repeat N]``; prints one JSON object with the medians.
Targets: identify <= 10 s, validate <= 3 s.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

N_JOINTS = 7
RATE = 1000.0
SECONDS = 20.0


def build(folder: Path) -> tuple[Path, Path]:
    """(nominal URDF, log CSV) in ``folder``."""
    from app.planning.robots import load_robot
    from tests.utils.robot_logs import arm_urdf, excitation, mujoco_torques, write_generic_csv

    nominal = folder / "arm7.urdf"
    nominal.write_text(arm_urdf(N_JOINTS, name="arm7"))
    masses = [4.0 - 0.5 * j for j in range(N_JOINTS)]
    masses[2] *= 1.2
    true_path = folder / "true" / "arm7.urdf"
    true_path.parent.mkdir(exist_ok=True)
    true_path.write_text(arm_urdf(N_JOINTS, name="arm7", masses=masses, payload=2.0))
    true = load_robot(str(true_path))
    t, q, qd, qdd = excitation(SECONDS, RATE, N_JOINTS, seed=1)
    rng = np.random.default_rng(0)
    tau = mujoco_torques(true, q, qd, qdd)
    tau += np.linspace(0.5, 1.5, N_JOINTS) * qd + np.linspace(1.0, 2.0, N_JOINTS) * np.tanh(
        qd / 0.01
    )
    tau += np.linspace(-0.3, 0.3, N_JOINTS) + rng.normal(0.0, 0.2, tau.shape)
    q_logged = q + rng.normal(0.0, 1e-5, q.shape)
    log = write_generic_csv(folder / "log.csv", t, true.joint_names, q_logged, tau)
    return nominal, log


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    from app.planning.identification import identify
    from app.planning.robots import load_robot
    from app.planning.validation import validate
    from app.recordings.robot_logs import read_robot_log

    with tempfile.TemporaryDirectory() as tmp:
        nominal, log_path = build(Path(tmp))
        robot = load_robot(str(nominal))
        identify_s, validate_s = [], []
        result = None
        for _ in range(args.repeat):
            start = time.perf_counter()
            result = identify(robot, [read_robot_log(log_path)])
            identify_s.append(time.perf_counter() - start)
            start = time.perf_counter()
            validate(robot, read_robot_log(log_path))
            validate_s.append(time.perf_counter() - start)
        assert result is not None
        print(
            json.dumps(
                {
                    "joints": N_JOINTS,
                    "samples": int(SECONDS * RATE) + 1,
                    "identify_s": identify_s,
                    "identify_median_s": statistics.median(identify_s),
                    "validate_s": validate_s,
                    "validate_median_s": statistics.median(validate_s),
                    "n_base": result.n_base,
                    "fit_note": result.notes[-1],
                    "held_back_residual_rms": {
                        k: v["residual_rms"] for k, v in result.held_back.items()
                    },
                    "load_average": os.getloadavg(),
                },
                indent=1,
            )
        )


if __name__ == "__main__":
    main()
