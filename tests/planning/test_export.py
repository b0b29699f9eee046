"""Trajectory export: every format read back by an independent reader and compared with the plan.

References: the plan's own arrays (q, qd, qdd from the planner, tau from its inverse dynamics)
at its samples; Flash & Hogan's closed-form minimum-jerk curve (equal to the quintic) between
them; the ``csv`` module, PyYAML, ``rosbags`` and the project's OpenSim reader as parsers.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from app.planning import load_robot, plan
from app.planning.export import (
    FORMATS,
    ExportError,
    MethodMotion,
    PlanMotion,
    export_bytes,
    export_result,
    format_of,
    plan_motion,
    write_export,
)
from app.planning.profiles import minimum_jerk, quintic
from tests.utils.example_robots import UR5, robot_file

TOL = 1e-9


@pytest.fixture(scope="module")
def human() -> Any:
    """A human-arm plan of 1 s on a 1 ms grid (1001 samples: the 1 kHz export's times)."""
    robot = load_robot("human_arm_2dof")
    result = plan(robot, duration=1.0, particles=10, iterations=8, seed=3, report_samples=1001)
    return robot, result, _unchecked(plan_motion(result, robot))


@pytest.fixture(scope="module")
def ur5() -> Any:
    """A UR5 plan with wrist 3 locked at 30 deg (URScript must still send six joints)."""
    robot = load_robot(robot_file(UR5), payload=1.0, locks={"wrist_3_joint": math.radians(30.0)})
    result = plan(robot, duration=2.0, particles=10, iterations=8, seed=0, report_samples=1001)
    return robot, result, _unchecked(plan_motion(result, robot))


def _unchecked(motion: PlanMotion) -> PlanMotion:
    """The motion without the plan's safety check: these tests are about the numbers (the
    safety gate has its own tests in test_export_gates.py)."""
    return dataclasses.replace(motion, safety=None)


def _csv_rows(text: str) -> list[list[str]]:
    """The CSV's rows after its leading ``#`` comment lines (the export's record)."""
    lines = text.splitlines(keepends=True)
    assert lines[0].startswith("# BioPlan export: ")
    return list(csv.reader(io.StringIO("".join(x for x in lines if not x.startswith("#")))))


def _plan_arrays(result: Any, method: str) -> dict[str, np.ndarray]:
    ev = {"quintic": result.standard, "paper": result.optimized}[method]
    tr = ev.trajectory
    return {"t": tr.t, "q": tr.q, "qd": tr.qd, "qdd": tr.qdd, "tau": ev.tau}


def _assert_matches_plan(result: Any, method: str, got: dict[str, np.ndarray]) -> None:
    ref = _plan_arrays(result, method)
    assert got["t"].shape == ref["t"].shape
    for key in ("t", "q", "qd", "qdd", "tau"):
        np.testing.assert_allclose(got[key], ref[key], rtol=0, atol=TOL, err_msg=key)


@pytest.mark.parametrize("method", ["quintic", "paper"])
def test_csv_matches_the_plan_at_its_samples(human: Any, method: str) -> None:
    robot, result, motion = human
    text = export_bytes(motion, "csv", method=method, rate=1000.0, robot=robot).decode()
    rows = _csv_rows(text)
    header = rows[0]
    assert header[:3] == ["time [s]", "q_shoulder_flexion [rad]", "q_elbow_flexion [rad]"]
    assert header[-1] == "tau_elbow_flexion [Nm]" and "qdd_shoulder_flexion [rad/s^2]" in header
    table = np.array(rows[1:], dtype=float)
    got = {"t": table[:, 0]}
    for k, key in enumerate(("q", "qd", "qdd", "tau")):
        got[key] = table[:, 1 + 2 * k : 3 + 2 * k]
    _assert_matches_plan(result, method, got)


def test_json_carries_the_task_robot_method_and_metrics(human: Any) -> None:
    robot, result, motion = human
    data = json.loads(export_bytes(motion, "json", method="paper", rate=1000.0, robot=robot))
    assert data["joint_names"] == list(robot.joint_names) and data["method"] == "paper"
    assert data["task"]["goal_deg"] == pytest.approx([20.0, 150.0])
    assert data["metrics"]["abs_work"] == result.optimized.metrics.abs_work
    assert data["units"]["tau"] == "Nm" and data["robot_spec"]["source"] == "human_arm_2dof"
    _assert_matches_plan(
        result, "paper", {k: np.array(data[k]) for k in ("t", "q", "qd", "qdd", "tau")}
    )


def test_yaml_is_a_joint_trajectory_message(human: Any) -> None:
    robot, result, motion = human
    message = yaml.safe_load(export_bytes(motion, "yaml", method="paper", rate=1000.0, robot=robot))
    assert message["joint_names"] == list(robot.joint_names)
    points = message["points"]
    got = {
        "t": np.array(
            [p["time_from_start"]["sec"] + 1e-9 * p["time_from_start"]["nanosec"] for p in points]
        ),
        "q": np.array([p["positions"] for p in points]),
        "qd": np.array([p["velocities"] for p in points]),
        "qdd": np.array([p["accelerations"] for p in points]),
        "tau": np.array([p["effort"] for p in points]),
    }
    assert all(isinstance(v, float) for v in points[1]["positions"])  # never a YAML string
    _assert_matches_plan(result, "paper", got)


def test_mcap_bag_reads_back_with_rosbags(human: Any, tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    robot, result, motion = human
    path = write_export(tmp_path / "paper.mcap", motion, rate=1000.0, robot=robot)
    store = get_typestore(Stores.ROS2_HUMBLE)
    trajectories, states = [], []
    with Reader(path) as reader:
        for connection, _, raw in reader.messages():
            message = store.deserialize_cdr(raw, connection.msgtype)
            if connection.topic == "/joint_trajectory":
                trajectories.append(message)
            elif connection.topic == "/joint_states":
                states.append(message)
    assert len(trajectories) == 1 and len(states) == len(trajectories[0].points)
    points = trajectories[0].points
    got = {
        "t": np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in points]),
        "q": np.array([p.positions for p in points]),
        "qd": np.array([p.velocities for p in points]),
        "qdd": np.array([p.accelerations for p in points]),
        "tau": np.array([p.effort for p in points]),
    }
    _assert_matches_plan(result, "paper", got)
    assert list(trajectories[0].joint_names) == list(robot.joint_names)


def test_opensim_motion_file_reads_back_in_radians(human: Any, tmp_path: Path) -> None:
    from app.recordings import read_recording

    robot, result, motion = human
    path = write_export(tmp_path / "arm.mot", motion, method="quintic", rate=1000.0, robot=robot)
    recording = read_recording(path)
    ref = _plan_arrays(result, "quintic")
    for j, name in enumerate(robot.joint_names):
        channel = recording.channels[name]
        assert channel.unit == "rad"  # inDegrees=yes, converted back by the reader
        np.testing.assert_allclose(channel.data, ref["q"][:, j], atol=TOL)


def _servoj(text: str) -> np.ndarray:
    rows = [line for line in text.splitlines() if line.strip().startswith("servoj(")]
    return np.array([[float(v) for v in r.split("[")[1].split("]")[0].split(",")] for r in rows])


def test_urscript_sends_all_six_joints_at_the_controller_rate(ur5: Any) -> None:
    robot, result, motion = ur5
    text = export_bytes(motion, "script", method="paper", rate=500.0, robot=robot).decode()
    lines = text.splitlines()
    assert "def bioplan_trajectory():" in lines and lines[-2:] == ["end", "bioplan_trajectory()"]
    q = _servoj(text)
    assert q.shape == (1001, 6)  # 2 s at 500 Hz = the plan's 1001 samples
    np.testing.assert_allclose(q[:, :5], result.optimized.trajectory.q, atol=TOL)
    np.testing.assert_allclose(q[:, 5], math.radians(30.0), atol=TOL)  # locked, still sent
    first = next(x for x in lines if x.strip().startswith("servoj("))
    assert first.endswith(", 0, 0, 0.002, 0.1, 300)")
    assert len(_servoj(export_bytes(motion, "script", rate=125.0, robot=robot).decode())) == 251
    with pytest.raises(ExportError, match="500 Hz divided by a whole number"):
        export_bytes(motion, "script", rate=300.0, robot=robot)


def test_urscript_refuses_a_robot_without_six_joints(human: Any) -> None:
    robot, _, motion = human
    with pytest.raises(ExportError, match="needs a 6-joint Universal Robots arm"):
        export_bytes(motion, "script", robot=robot)


def test_between_samples_the_quintic_is_the_closed_form(human: Any) -> None:
    # At 333 Hz no export time but 0 lies on the plan's 1 ms grid; the polynomial is exact
    # there too: compare with Flash & Hogan's closed form (a separate formula, same curve).
    robot, _, motion = human
    data = json.loads(export_bytes(motion, "json", method="quintic", rate=333.0, robot=robot))
    t = np.array(data["t"])
    assert t[-1] >= 1.0 and t[-2] < 1.0 and t.size == 334  # the goal is held past T
    inside = t <= 1.0
    ref = minimum_jerk(motion.start, motion.goal, 1.0, n_samples=1001)
    for k in np.flatnonzero(inside)[::37]:
        u = t[k]
        s = u**3 * (10 - 15 * u + 6 * u**2)
        np.testing.assert_allclose(
            data["q"][k], motion.start + s * (motion.goal - motion.start), atol=1e-12
        )
    np.testing.assert_allclose(data["q"][-1], ref.q[-1], atol=1e-12)
    np.testing.assert_allclose(data["qd"][-1], 0.0, atol=1e-12)


def test_samples_are_joined_by_quintic_hermite_which_is_exact_for_a_quintic() -> None:
    # A method known only at samples (no knots): exact at them; between them the quintic
    # Hermite spline reproduces any quintic exactly, so a coarse sampling of the quintic
    # profile resamples onto the fine one.
    coarse = quintic(np.zeros(2), np.array([0.3, 2.0]), 1.0, n_samples=11)
    fine = quintic(np.zeros(2), np.array([0.3, 2.0]), 1.0, n_samples=1001)
    motion = MethodMotion("sampled", "samples", coarse.t, coarse.q, coarse.qd, coarse.qdd)
    q, qd, qdd = motion.evaluate(fine.t)
    np.testing.assert_allclose(q, fine.q, atol=1e-12)
    np.testing.assert_allclose(qd, fine.qd, atol=1e-11)
    np.testing.assert_allclose(qdd, fine.qdd, atol=1e-10)
    exact, _, _ = motion.evaluate(coarse.t)
    np.testing.assert_array_equal(exact, coarse.q)


def test_the_json_result_rebuilds_every_method_bit_for_bit(human: Any) -> None:
    robot, _, motion = human
    saved = json.loads(json.dumps({"motion": motion.to_dict(), "safety": motion.safety}))
    for method in motion.methods:
        for fmt in ("csv", "yaml"):
            assert export_result(saved, fmt, method=method) == export_bytes(
                motion, fmt, method=method, robot=robot
            )
    again = PlanMotion.from_dict(saved["motion"])
    assert again.methods["paper"].kind == "piecewise_quintic"
    assert len(again.methods["paper"].t) == 3  # start, via point, goal


def test_a_changed_robot_is_refused(human: Any) -> None:
    _, _, motion = human
    heavier = load_robot("human_arm_2dof", payload=20.0)
    with pytest.raises(ExportError, match="differs from the planned one"):
        export_bytes(motion, "csv", robot=heavier)


@pytest.mark.parametrize("rate", [0.0, -5.0, 1e9, math.nan])
def test_bad_rates_are_refused_and_nothing_is_written(
    human: Any, tmp_path: Path, rate: float
) -> None:
    robot, _, motion = human
    with pytest.raises(ExportError, match="export rate"):
        write_export(tmp_path / "x.csv", motion, rate=rate, robot=robot)
    assert list(tmp_path.iterdir()) == []


def test_unknown_method_format_and_extension(human: Any) -> None:
    robot, _, motion = human
    with pytest.raises(ExportError, match="expected one of quintic, paper"):
        export_bytes(motion, "csv", method="bound", robot=robot)
    with pytest.raises(ExportError, match="export format 'xlsx'"):
        export_bytes(motion, "xlsx", robot=robot)
    with pytest.raises(ExportError, match=r"unknown export extension '\.txt'"):
        format_of("plan.txt")
    assert {format_of(f"a{f.extension}") for f in FORMATS.values()} == set(FORMATS)
    assert format_of("a.yml") == "yaml"


def test_each_rate_changes_the_sample_count(human: Any) -> None:
    robot, _, motion = human
    counts = {
        rate: len(json.loads(export_bytes(motion, "json", rate=rate, robot=robot))["t"])
        for rate in (50.0, 100.0, 1000.0)
    }
    assert counts == {50.0: 51, 100.0: 101, 1000.0: 1001}


def test_numbers_are_written_short_and_read_back_exactly(human: Any) -> None:
    """Issue 29: times printed as 0.0030000000000000001 (17 digits whatever the number);
    each number is now the shortest text that reads back as the same float."""
    robot, _result, motion = human
    text = export_bytes(motion, "csv", method="quintic", rate=1000.0, robot=robot).decode()
    rows = _csv_rows(text)[1:]
    times = [row[0] for row in rows]
    assert times[:4] == ["0.0", "0.001", "0.002", "0.003"]
    for row in rows[:50]:
        for cell in row:
            assert cell == repr(float(cell))  # shortest round-trip text
