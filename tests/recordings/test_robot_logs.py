"""Robot logs: ROS 2 bags (MCAP, SQLite), UR RTDE CSV, generic CSV; checks and repairs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.planning.robots import load_robot
from app.recordings.robot_logs import read_robot_log, sniff_robot_log
from app.recordings.types import RecordingError
from tests.utils.robot_logs import excitation, write_bag, write_generic_csv, write_ur_csv

NAMES = ("joint1", "joint2", "joint3")


def _motion(rate: float = 100.0, duration: float = 2.0, n: int = 3):
    t, q, qd, _ = excitation(duration, rate, n, seed=4)
    tau = 10.0 * np.sin(q) + 0.5 * qd
    return t, q, qd, tau


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_ros2_bag_of_joint_states(tmp_path: Path, storage: str) -> None:
    t, q, qd, tau = _motion()
    bag = write_bag(tmp_path / f"bag_{storage}", t, NAMES, q, qd, tau, storage=storage)
    assert sniff_robot_log(bag) == "ros2_bag"
    log = read_robot_log(bag)
    assert log.format == "ros2_bag" and log.joint_names == NAMES
    assert np.allclose(log.t, t, atol=1e-6)
    assert np.allclose(log.position, q) and np.allclose(log.velocity, qd)
    assert np.allclose(log.effort, tau)
    # The storage file alone (its folder holds metadata.yaml) reads the same.
    storage_file = next(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))
    assert np.allclose(read_robot_log(storage_file).position, q)


def test_ros2_bag_without_velocity_and_topic_choice(tmp_path: Path) -> None:
    t, q, _, tau = _motion()
    bag = write_bag(tmp_path / "bag", t, NAMES, q, None, tau, topic="/arm/joint_states")
    log = read_robot_log(bag)
    assert log.velocity is None
    assert any("differentiated" in note for note in log.notes)
    with pytest.raises(RecordingError, match=r"no JointState topic '/other'.*'/arm/joint_states'"):
        read_robot_log(bag, topic="/other")


def test_generic_csv_with_and_without_velocity(tmp_path: Path) -> None:
    t, q, qd, tau = _motion()
    with_v = read_robot_log(write_generic_csv(tmp_path / "v.csv", t, NAMES, q, tau, qd))
    assert with_v.format == "csv" and np.allclose(with_v.velocity, qd)
    without = read_robot_log(write_generic_csv(tmp_path / "nov.csv", t, NAMES, q, tau))
    assert without.velocity is None and np.allclose(without.effort, tau)
    assert any("differentiated" in note for note in without.notes)


def test_ur_rtde_csv_currents_become_torque_through_the_sidecar_motors(tmp_path: Path) -> None:
    robot = load_robot("curtain_wall_6dof")  # six joints, motors modelled
    t, q, qd, tau = _motion(n=6)
    gain = np.array([m.gear_ratio * m.torque_constant for m in robot.motors])
    path = write_ur_csv(tmp_path / "robot_data.csv", t, q, qd, current=tau / gain)
    assert sniff_robot_log(path) == "ur_rtde_csv"
    log = read_robot_log(path)
    assert log.effort is None and log.current is not None
    matched = log.matched(robot.joint_names, motors=robot.motors)
    assert matched.joint_names == robot.joint_names
    assert np.allclose(matched.effort, tau, atol=1e-6)
    assert any("torque constant" in note for note in matched.notes)
    # target_moment (the controller's torque, Nm) is taken as it is; comma-separated too.
    moment = write_ur_csv(tmp_path / "m.csv", t, q, qd, moment=tau, delimiter=",")
    assert np.allclose(read_robot_log(moment).effort, tau)
    with pytest.raises(RecordingError, match=r"6 unnamed joints .* robot's 3 joints"):
        log.matched(NAMES)


def test_wrong_joint_names_list_both_sides(tmp_path: Path) -> None:
    t, q, _, tau = _motion()
    log = read_robot_log(write_generic_csv(tmp_path / "x.csv", t, ("a", "b", "c"), q, tau))
    with pytest.raises(RecordingError) as info:
        log.matched(NAMES)
    message = str(info.value)
    assert "x.csv" in message and "['a', 'b', 'c']" in message and "'joint1'" in message


def test_non_monotonic_time_is_refused_with_its_line(tmp_path: Path) -> None:
    t, q, _, tau = _motion()
    t = t.copy()
    t[10] = t[8]
    path = write_generic_csv(tmp_path / "back.csv", t, NAMES, q, tau)
    with pytest.raises(RecordingError, match=r"back.csv, line 12: time goes back or repeats"):
        read_robot_log(path)


def test_nan_runs_short_filled_long_refused(tmp_path: Path) -> None:
    t, q, _, tau = _motion()
    short = q.copy()
    short[50:53, 1] = np.nan
    log = read_robot_log(write_generic_csv(tmp_path / "short.csv", t, NAMES, short, tau))
    assert np.allclose(log.position[50:53, 1], q[50:53, 1], atol=3e-3)
    assert any("NaN run" in note for note in log.notes)
    long = q.copy()
    long[50:70, 2] = np.nan
    path = write_generic_csv(tmp_path / "long.csv", t, NAMES, long, tau)
    with pytest.raises(RecordingError, match=r"channel 'joint3/position': 20 missing or NaN"):
        read_robot_log(path)


def test_gap_refused_and_uneven_rate_resampled(tmp_path: Path) -> None:
    t, q, _, tau = _motion()
    gap = np.concatenate([t[:100], t[100:] + 0.5])
    with pytest.raises(RecordingError, match=r"gap of 0.51 s"):
        read_robot_log(write_generic_csv(tmp_path / "gap.csv", gap, NAMES, q, tau))
    jitter = t + np.random.default_rng(0).uniform(-0.002, 0.002, t.size)
    log = read_robot_log(write_generic_csv(tmp_path / "jitter.csv", jitter, NAMES, q, tau))
    assert np.allclose(np.diff(log.t), np.diff(log.t)[0])
    assert any("resampled" in note for note in log.notes)


def test_not_a_robot_log(tmp_path: Path) -> None:
    path = tmp_path / "emg.csv"
    path.write_text("time,biceps\n0,1\n")
    with pytest.raises(RecordingError, match=r"emg\.csv: not a robot log"):
        read_robot_log(path)
    bad = tmp_path / "bad.csv"
    bad.write_text("time,j/position,j/effort\n" + "".join(f"{k},{k},x\n" for k in range(12)))
    with pytest.raises(RecordingError, match=r"bad.csv, line 2, channel 'j/effort': 'x' is not"):
        read_robot_log(bad)


def test_ros2_bag_with_joints_at_different_rates_is_interpolated(tmp_path: Path) -> None:
    """Two publishers: joint1/joint2 at 100 Hz, joint3 at 50 Hz (a gripper-like stream)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    state = store.types["sensor_msgs/msg/JointState"]
    header, stamp_type = (
        store.types["std_msgs/msg/Header"],
        store.types["builtin_interfaces/msg/Time"],
    )
    t = np.arange(200) / 100.0
    with Writer(tmp_path / "bag", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection("/joint_states", state.__msgtype__, typestore=store)
        for k, time in enumerate(t):
            streams = [(["joint1", "joint2"], [time, 2 * time])]
            if k % 2 == 0:
                streams.append((["joint3"], [3 * time]))
            for names, values in streams:
                ns = round(time * 1e9) + 10**18
                message = state(
                    header=header(
                        stamp=stamp_type(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=""
                    ),
                    name=names,
                    position=np.array(values, float),
                    velocity=np.zeros(0),
                    effort=np.array(values, float),
                )
                writer.write(connection, ns, store.serialize_cdr(message, state.__msgtype__))
    log = read_robot_log(tmp_path / "bag")
    assert log.joint_names == NAMES
    assert any("different times" in note for note in log.notes)
    valid = log.t <= 1.98
    assert np.allclose(log.position[valid, 2], 3 * log.t[valid], atol=1e-9)
