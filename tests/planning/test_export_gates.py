"""Issue 27 item 4: controller-ready exports.

Limits are checked on the exported samples against the real UR5's URDF limits (the paper's
trajectory exceeds elbow_joint's 3.15 rad/s, as the issue measured), and the value reported is
checked against the forced file read back by numpy. The safety gate is tested with planted
``safety`` blocks (so it does not depend on the checker's details) and once end to end. The
URScript is parsed by a small grammar of the subset it may use; the ROS 2 goal is turned into a
message with ``rosbags`` and the MCAP read back with ``rosbags``.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import re
from decimal import Decimal
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from app.cli import main
from app.planning import load_robot, plan
from app.planning.export import (
    ExportError,
    ExportRefused,
    PlanMotion,
    export_bytes,
    export_result,
    is_universal_robot,
    limit_exceedances,
    plan_motion,
    ur_number,
    write_export,
)
from tests.utils.example_robots import UR5, robot_file

UR_NAMES = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
]


@pytest.fixture(scope="module")
def ur5() -> Any:
    """The documented UR5 example (2 s, 1 kg), the paper's PSO at its default size: its
    trajectory exceeds elbow_joint's speed limit (3.151 > 3.15 rad/s, issue 27)."""
    robot = load_robot(robot_file(UR5), payload=1.0)
    result = plan(robot, duration=2.0, seed=0, methods=("quintic", "paper"))
    return robot, result, plan_motion(result, robot)


@pytest.fixture(scope="module")
def human() -> Any:
    robot = load_robot("human_arm_2dof")
    result = plan(robot, duration=1.0, particles=8, iterations=5, seed=3)
    return robot, result, dataclasses.replace(plan_motion(result, robot), safety=None)


def _without_safety(motion: PlanMotion) -> PlanMotion:
    return dataclasses.replace(motion, safety=None)


def _comments(text: str) -> list[str]:
    return [x for x in text.splitlines() if x.startswith("#")]


def _csv_table(text: str) -> tuple[list[str], np.ndarray]:
    body = [x for x in text.splitlines() if not x.startswith("#")]
    header = next(csv.reader(io.StringIO(body[0])))
    return header, np.loadtxt(body[1:], delimiter=",")


# ----------------------------------------------------------------------------------------------
# Limits
# ----------------------------------------------------------------------------------------------


def test_the_papers_ur5_trajectory_is_refused_naming_joint_limit_value_time(ur5: Any) -> None:
    robot, _, motion = ur5
    motion = _without_safety(motion)
    with pytest.raises(ExportRefused) as info:
        export_bytes(motion, "csv", method="paper", rate=1000.0, robot=robot)
    message = str(info.value)
    assert "\n" not in message
    found = re.search(
        r"method paper: joint 'elbow_joint' velocity ([0-9.]+) rad/s exceeds its limit "
        r"3\.15 rad/s at t=([0-9.]+) s",
        message,
    )
    assert found, message
    # The same numbers from the forced file itself, read back by numpy.
    text = export_bytes(motion, "csv", method="paper", rate=1000.0, robot=robot, force=True)
    header, table = _csv_table(text.decode())
    column = header.index("qd_elbow_joint [rad/s]")
    k = int(np.argmax(np.abs(table[:, column])))
    assert abs(table[k, column]) > robot.qd_max[2] == 3.15
    assert float(found.group(1)) == pytest.approx(abs(table[k, column]), rel=1e-5)
    assert float(found.group(2)) == pytest.approx(table[k, 0], abs=1e-3)
    assert round(abs(table[k, column]), 3) == 3.151  # the number
    # The forced file says it was forced and what was exceeded.
    record = _comments(text.decode())
    assert any("limits: FORCED past the robot's limits" in x and "elbow_joint" in x for x in record)
    # The quintic keeps every limit: exported, and the file says so.
    ok = export_bytes(motion, "csv", method="quintic", rate=1000.0, robot=robot).decode()
    assert "# limits: within the robot's limits" in _comments(ok)


def test_every_limit_kind_is_caught_on_planted_limits(human: Any) -> None:
    """Position, speed, acceleration (when given) and torque, each against a limit planted
    just below the exported samples' own extreme (computed here with numpy)."""
    robot, _, motion = human
    samples = motion.sample("quintic", 500.0, robot)
    assert limit_exceedances(samples, robot) == []
    peak_q = samples.q.max(axis=0)
    peak_qd = np.abs(samples.qd).max(axis=0)
    peak_qdd = np.abs(samples.qdd).max(axis=0)
    peak_tau = np.abs(samples.tau).max(axis=0)
    tight = robot.with_payload(robot.payload.mass)
    object.__setattr__(tight, "q_max", peak_q - 0.01)
    object.__setattr__(tight, "qd_max", peak_qd * 0.99)
    object.__setattr__(tight, "tau_max", peak_tau * 0.99)
    found = limit_exceedances(samples, tight, qdd_max=peak_qdd * 0.99)
    kinds = {(e.joint, e.limit) for e in found}
    for joint in robot.joint_names:
        for limit in ("position", "velocity", "acceleration", "effort"):
            assert (joint, limit) in kinds
    speed = next(e for e in found if e.limit == "velocity" and e.joint == robot.joint_names[1])
    k = int(np.argmax(np.abs(samples.qd[:, 1])))
    assert speed.value == pytest.approx(peak_qd[1]) and speed.time == samples.t[k]
    # Within round-off of a limit (LIMIT_TOL) is not an exceedance.
    object.__setattr__(tight, "qd_max", peak_qd * (1 - 1e-9))
    object.__setattr__(tight, "q_max", robot.q_max)
    object.__setattr__(tight, "tau_max", robot.tau_max)
    assert limit_exceedances(samples, tight) == []


def test_cli_refuses_with_exit_2_and_force_writes_the_record(
    ur5: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, _, motion = ur5
    saved = tmp_path / "plan.json"
    saved.write_text(json.dumps({"motion": motion.to_dict()}), encoding="utf-8")  # no safety
    out = tmp_path / "paper.yaml"
    assert main(["export", str(saved), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "elbow_joint" in err and "velocity" in err
    assert "3.15 rad/s" in err and "--force" in err and not out.exists()
    assert main(["export", str(saved), "--out", str(out), "--force", "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["export"]["forced"] is True
    assert payload["export"]["exceeded"][0]["joint"] == "elbow_joint"
    assert payload["export"]["safety"]["state"] == "not checked"
    text = out.read_text()
    assert "# limits: FORCED" in text and "# safety: not checked" in text


# ----------------------------------------------------------------------------------------------
# Safety (planted blocks, then end to end)
# ----------------------------------------------------------------------------------------------

PLANTED = {
    "ok": False,
    "checked": True,
    "min_clearance": -0.429,
    "findings": [
        {
            "method": "quintic",
            "time": 0.5,
            "kind": "plane",
            "links": ["forearm"],
            "obstacle": "mount plane",
            "depth": 0.429,
        },
        {
            "method": "quintic",
            "time": 0.31,
            "kind": "self",
            "links": ["upper_arm", "hand"],
            "obstacle": None,
            "depth": 0.012,
        },
    ],
}


def _saved(motion: PlanMotion, safety: Any) -> dict[str, Any]:
    out: dict[str, Any] = {"motion": motion.to_dict()}
    if safety is not None:
        out["safety"] = safety
    return json.loads(json.dumps(out))


def test_an_unsafe_method_is_refused_naming_its_first_contact(human: Any) -> None:
    robot, _, motion = human
    result = _saved(motion, PLANTED)
    with pytest.raises(ExportRefused) as info:
        export_result(result, "yaml", method="quintic", robot=robot)
    message = str(info.value)
    assert "method quintic is not safe to run" in message
    assert "at t=0.31 s: links upper_arm and hand (self), 12.0 mm deep" in message  # the first
    assert "--allow-unsafe" in message
    # allow_unsafe writes it, and the file records it.
    text = export_result(result, "yaml", method="quintic", robot=robot, allow_unsafe=True)
    record = _comments(text.decode())
    assert "# safety: UNSAFE, exported with allow_unsafe: first contact at t=0.31 s" in "\n".join(
        record
    )
    # A method without a finding of its own is exported and said to be checked.
    paper = export_result(result, "json", method="paper", robot=robot)
    assert json.loads(paper)["export"]["safety"]["state"] == "ok"
    assert json.loads(paper)["export"]["safety"]["allow_unsafe"] is False


@pytest.mark.parametrize(
    ("safety", "expected"),
    [
        (None, "# safety: not checked"),
        ({"ok": None, "checked": False, "reason": "no collision geometry"}, "not checked (no coll"),
        ({"ok": True, "checked": True, "min_clearance": 0.0123, "findings": []}, "no contact"),
    ],
)
def test_the_file_records_the_safety_state(human: Any, safety: Any, expected: str) -> None:
    robot, _, motion = human
    text = export_result(_saved(motion, safety), "yaml", robot=robot)
    assert any(expected in line for line in _comments(text.decode()))


def test_end_to_end_the_planners_safety_block_gates_the_export(
    ur5: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The UR5's default task as planned, with the planner's own safety check."""
    _, result, motion = ur5
    block = result.to_dict().get("safety")
    if block is None:
        pytest.skip("PlanResult.to_dict() has no 'safety' block yet (the collision check)")
    saved = tmp_path / "plan.json"
    saved.write_text(json.dumps({"motion": motion.to_dict(), "safety": block}), encoding="utf-8")
    out = tmp_path / "quintic.script"
    findings = [f for f in block["findings"] if f["method"] == "quintic"]
    if block["ok"] is False and findings:  # the issue: below the mounting plane
        assert main(["export", str(saved), "--method", "quintic", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        first = min(findings, key=lambda f: f["time"])
        assert f"at t={first['time']:.4g} s" in err and first["links"][0] in err
        argv = ["export", str(saved), "--method", "quintic", "--out", str(out)]
        assert main([*argv, "--allow-unsafe"]) == 0
        assert "# safety: UNSAFE, exported with allow_unsafe" in out.read_text()
    else:
        assert main(["export", str(saved), "--method", "quintic", "--out", str(out)]) == 0
        assert "# safety: checked, no contact" in out.read_text()


# ----------------------------------------------------------------------------------------------
# URScript
# ----------------------------------------------------------------------------------------------

_TOKEN = re.compile(
    r"\s*(?:(?P<number>-?\d+(?:\.\d+)?)(?![\w.])|(?P<name>[A-Za-z_]\w*)|(?P<punct>[()\[\],=:]))"
)


def _tokens(line: str) -> list[tuple[str, str]]:
    out, pos = [], 0
    line = line.rstrip()
    while pos < len(line):
        m = _TOKEN.match(line, pos)
        assert m and m.end() > pos, f"not URScript of the subset: {line[pos:]!r} in {line!r}"
        kind = m.lastgroup or ""
        out.append((kind, m.group(kind)))
        pos = m.end()
    return out


def _value(tokens: list[tuple[str, str]], i: int) -> tuple[Any, int]:
    """number | [number, ...] -> (value, next index)."""
    kind, text = tokens[i]
    if kind == "number":
        return Decimal(text), i + 1
    assert text == "[", tokens
    items, i = [], i + 1
    while True:
        value, i = _value(tokens, i)
        items.append(value)
        if tokens[i][1] == "]":
            return items, i + 1
        assert tokens[i][1] == ",", tokens
        i += 1


def _call(line: str) -> tuple[str, list[Any], dict[str, Any]]:
    """``name(arg, ..., key=arg)`` -> (name, positional, keywords); anything else fails."""
    tokens = _tokens(line)
    assert tokens[0][0] == "name" and tokens[1][1] == "(", line
    args: list[Any] = []
    keywords: dict[str, Any] = {}
    i = 2
    while tokens[i][1] != ")":
        if tokens[i][0] == "name" and tokens[i + 1][1] == "=":
            keywords[tokens[i][1]], i = _value(tokens, i + 2)
        else:
            value, i = _value(tokens, i)
            args.append(value)
        if tokens[i][1] == ",":
            i += 1
    assert i == len(tokens) - 1, f"trailing tokens in {line!r}"
    return tokens[0][1], args, keywords


def _parse_urscript(text: str) -> dict[str, Any]:
    """The subset BioPlan writes: comments; ``def NAME():``; indented movej/servoj/sleep/stopj
    calls with decimal numbers and lists of them; ``end``; then the call ``NAME()``."""
    lines = [x for x in text.splitlines() if x.strip() and not x.startswith("#")]
    head = _tokens(lines[0])
    words = [t for _, t in head]
    assert words[0] == "def" and words[2:] == ["(", ")", ":"]
    name = head[1][1]
    end = lines.index("end")
    body = [_call(x) for x in lines[1:end]]
    assert all(x.startswith("  ") for x in lines[1:end])
    assert {c for c, _, _ in body} <= {"movej", "servoj", "sleep", "stopj"}
    assert lines[end + 1 :] == [f"{name}()"], "the program must call its def"
    return {"name": name, "body": body}


def test_urscript_runs_when_sent_with_decimals_and_an_approach_movej(ur5: Any) -> None:
    robot, result, motion = ur5
    motion = _without_safety(motion)
    text = export_bytes(motion, "script", method="quintic", rate=125.0, robot=robot).decode()
    assert "e-" not in text.split("def ", 1)[1] and "e+" not in text.split("def ", 1)[1]
    program = _parse_urscript(text)
    body = program["body"]
    assert body[0][0] == "movej" and body[-1][0] == "stopj"
    servo = [args for call, args, _ in body if call == "servoj"]
    assert len(servo) == 251  # 2 s at 125 Hz
    assert body[0][1][0] == servo[0][0]  # the approach movej goes to the first point
    q = np.array([[float(v) for v in args[0]] for args in servo])
    planned = result.methods["quintic"].evaluated.trajectory
    np.testing.assert_allclose(q[0], planned.q[0], atol=1e-12)
    np.testing.assert_allclose(q[-1], planned.q[-1], atol=1e-12)
    assert all(args[3] == Decimal("0.008") for args in servo)  # t = 1 / 125 Hz


def test_ur_numbers_are_plain_decimals_to_twelve_places() -> None:
    for x in (1.17e-06, -3.2e-9, 2.617993877991, -0.0, 1e-20, 123.5, math.pi):
        text = ur_number(x)
        assert re.fullmatch(r"-?\d+\.\d+", text), text
        assert abs(Decimal(text) - Decimal(repr(x))) <= Decimal("5e-13")  # 12 places
    assert ur_number(1.17e-06) == "0.00000117" and ur_number(-0.0) == "0.0"


def test_urscript_is_for_universal_robots_unless_forced() -> None:
    assert is_universal_robot(UR_NAMES)
    assert is_universal_robot([f"ur5e_{n}" for n in UR_NAMES])  # a prefixed description
    assert not is_universal_robot(UR_NAMES[::-1])
    assert not is_universal_robot(UR_NAMES[:5])
    robot = load_robot("curtain_wall_6dof")
    assert not is_universal_robot(robot.all_joint_names)
    result = plan(robot, duration=1.0, particles=6, iterations=3, seed=0, methods=("quintic",))
    motion = _without_safety(plan_motion(result, robot))
    with pytest.raises(ExportError, match=r"is for Universal Robots arms.*shoulder_pan_joint"):
        export_bytes(motion, "script", robot=robot)
    text = export_bytes(motion, "script", robot=robot, force=True).decode()
    assert "# FORCED: the joints are not a Universal Robots arm's" in text
    _parse_urscript(text)


# ----------------------------------------------------------------------------------------------
# ROS 2
# ----------------------------------------------------------------------------------------------

#: control_msgs/action/FollowJointTrajectory's goal, the fields this test fills (written here
#: from the interface's field list; the nested types are in rosbags' Humble store).
GOAL_MSG = """
trajectory_msgs/JointTrajectory trajectory
builtin_interfaces/Duration goal_time_tolerance
"""
GOAL_TYPE = "control_msgs/action/FollowJointTrajectory_Goal"
GOAL_FIELDS = {
    "trajectory",
    "multi_dof_trajectory",
    "path_tolerance",
    "component_path_tolerance",
    "goal_tolerance",
    "component_goal_tolerance",
    "goal_time_tolerance",
}


def _goal_store() -> Any:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(GOAL_MSG, GOAL_TYPE))
    return store


def _trajectory_message(store: Any, data: dict[str, Any]) -> Any:
    types = store.types
    duration_t = types["builtin_interfaces/msg/Duration"]
    point_t = types["trajectory_msgs/msg/JointTrajectoryPoint"]
    points = [
        point_t(
            positions=np.array(p["positions"]),
            velocities=np.array(p["velocities"]),
            accelerations=np.array(p["accelerations"]),
            effort=np.array(p["effort"]),
            time_from_start=duration_t(**p["time_from_start"]),
        )
        for p in data["points"]
    ]
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](**data["header"]["stamp"]),
        frame_id=data["header"]["frame_id"],
    )
    return types["trajectory_msgs/msg/JointTrajectory"](
        header=header, joint_names=data["joint_names"], points=points
    )


def test_the_goal_yaml_is_a_follow_joint_trajectory_goal(human: Any) -> None:
    robot, _, motion = human
    bare = yaml.safe_load(export_bytes(motion, "yaml", rate=50.0, robot=robot))
    raw = export_bytes(motion, "yaml", rate=50.0, robot=robot, goal=True).decode()
    goal = yaml.safe_load(raw)
    assert set(goal) <= GOAL_FIELDS and goal["trajectory"] == bare  # the message, wrapped
    assert "# action: /joint_trajectory_controller/follow_joint_trajectory" in raw
    store = _goal_store()
    types = store.types
    message = types[GOAL_TYPE](
        trajectory=_trajectory_message(store, goal["trajectory"]),
        goal_time_tolerance=types["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
    )
    back = store.deserialize_cdr(store.serialize_cdr(message, GOAL_TYPE), GOAL_TYPE)
    samples = motion.sample(None, 50.0, robot)
    assert list(back.trajectory.joint_names) == list(robot.joint_names)
    np.testing.assert_array_equal([p.positions for p in back.trajectory.points], samples.q)
    last = back.trajectory.points[-1].time_from_start
    assert last.sec + 1e-9 * last.nanosec == pytest.approx(samples.t[-1])
    # --topic names the action of a goal and the topic of a message.
    named = export_bytes(motion, "yaml", rate=50.0, robot=robot, goal=True, topic="/arm/fjt")
    assert b"# action: /arm/fjt (control_msgs/action/FollowJointTrajectory goal)" in named
    topic = "/scaled_joint_trajectory_controller/joint_trajectory"
    message_yaml = export_bytes(motion, "yaml", rate=50.0, robot=robot, topic=topic)
    assert f"# topic: {topic} (trajectory_msgs/msg/JointTrajectory)".encode() in message_yaml


def test_the_mcap_carries_joint_states_over_time_and_the_topic(human: Any, tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    robot, _, motion = human
    topic = "/scaled_joint_trajectory_controller/joint_trajectory"
    path = write_export(tmp_path / "p.mcap", motion, rate=200.0, robot=robot, topic=topic)
    store = get_typestore(Stores.ROS2_HUMBLE)
    by_topic: dict[str, list[tuple[int, Any]]] = {}
    with Reader(path) as reader:
        for connection, stamp, raw in reader.messages():
            message = store.deserialize_cdr(raw, connection.msgtype)
            by_topic.setdefault(connection.topic, []).append((stamp, message))
    assert set(by_topic) == {topic, "/joint_states", "/bioplan/export"}
    samples = motion.sample(None, 200.0, robot)
    states = by_topic["/joint_states"]
    assert len(states) == samples.t.size == 201
    stamps = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for _, m in states])
    assert np.all(np.diff(stamps) > 0)
    np.testing.assert_allclose(stamps, samples.t, atol=1e-9)
    np.testing.assert_allclose([s for s, _ in states], np.round(samples.t * 1e9), atol=1)
    np.testing.assert_array_equal([m.position for _, m in states], samples.q)
    np.testing.assert_array_equal([m.effort for _, m in states], samples.tau)
    assert list(states[0][1].name) == list(robot.joint_names)
    record = json.loads(by_topic["/bioplan/export"][0][1].data)
    assert record["safety"]["state"] == "not checked" and record["forced"] is False


def test_an_approach_from_a_given_position(human: Any) -> None:
    robot, _, motion = human
    rate = 100.0
    here = np.radians([10.0, 20.0])
    plain = yaml.safe_load(export_bytes(motion, "yaml", rate=rate, robot=robot))
    raw = export_bytes(motion, "yaml", rate=rate, robot=robot, from_position=here.tolist())
    moved = yaml.safe_load(raw)
    points = moved["points"]
    extra = len(points) - len(plain["points"])
    # Closed form of the approach's length: a rest-to-rest quintic peaks at 1.875 d / T in
    # speed and 10 / sqrt(3) d / T^2 in acceleration; half of each limit, at least 1 s.
    d = np.abs(np.array(plain["points"][0]["positions"]) - here)
    span = max(
        1.0,
        float(np.max(1.875 * d / (0.5 * robot.qd_max))),
        float(np.max(np.sqrt(10 / math.sqrt(3) * d / (0.5 * robot.qdd_max)))),
    )
    assert extra == math.ceil(span * rate - 1e-9)
    assert f"approach: {extra / rate:g} s" in raw.decode()
    np.testing.assert_allclose(points[0]["positions"], here, atol=1e-15)
    assert points[extra]["positions"] == plain["points"][0]["positions"]
    t = [p["time_from_start"]["sec"] + 1e-9 * p["time_from_start"]["nanosec"] for p in points]
    assert t[extra] == pytest.approx(extra / rate, abs=1e-9) and np.all(np.diff(t) > 0)
    speed = np.abs([p["velocities"] for p in points[:extra]])
    assert np.all(speed <= 0.5 * robot.qd_max + 1e-12)
    with pytest.raises(ExportError, match="from_position has 3 values: expected 2"):
        export_bytes(motion, "yaml", robot=robot, from_position=[0.0, 0.0, 0.0])
    with pytest.raises(ExportError, match=r"joint 'elbow_flexion' at .* outside its limits"):
        export_bytes(motion, "yaml", robot=robot, from_position=[0.0, math.radians(-170.0)])


def test_ros_options_are_refused_where_they_do_not_apply(human: Any) -> None:
    robot, _, motion = human
    with pytest.raises(ExportError, match=r"goal .* is for format yaml"):
        export_bytes(motion, "mcap", robot=robot, goal=True)
    with pytest.raises(ExportError, match="topic is for formats yaml and mcap"):
        export_bytes(motion, "csv", robot=robot, topic="/x")
    with pytest.raises(ExportError, match="topic '/9bad name': expected a ROS 2 name"):
        export_bytes(motion, "yaml", robot=robot, topic="/9bad name")
    with pytest.raises(ExportError, match=r"from_position .* is for formats yaml and mcap"):
        export_bytes(motion, "script", robot=robot, from_position=[0.0, 0.0])


def test_cli_ros_options_each_change_the_file(
    human: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, _, motion = human
    saved = tmp_path / "plan.json"
    saved.write_text(json.dumps({"motion": motion.to_dict()}), encoding="utf-8")

    def export(name: str, *options: str) -> str:
        out = tmp_path / name
        assert main(["export", str(saved), "--out", str(out), "--rate", "50", *options]) == 0
        return out.read_text()

    plain = export("a.yaml")
    goal = export("b.yaml", "--goal")
    topic = export("c.yaml", "--topic", "/scaled_joint_trajectory_controller/joint_trajectory")
    approach = export("d.yaml", "--from-position", "10,20")
    assert "trajectory" in yaml.safe_load(goal) and "trajectory" not in yaml.safe_load(plain)
    assert "/scaled_joint_trajectory_controller/joint_trajectory" in topic
    assert "/scaled_joint_trajectory_controller" not in plain
    first = yaml.safe_load(approach)["points"][0]["positions"]
    np.testing.assert_allclose(first, np.radians([10.0, 20.0]), atol=1e-15)
    capsys.readouterr()
    assert main(["export", str(saved), "--out", str(tmp_path / "e.csv"), "--goal"]) == 2
    assert "goal" in capsys.readouterr().err
    assert (
        main(["export", str(saved), "--out", str(tmp_path / "f.yaml"), "--from-position", "1"]) == 2
    )
    assert "--from-position has 1 angles: expected 2" in capsys.readouterr().err


def test_help_lists_every_export_option(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for flag in ("--force", "--allow-unsafe", "--goal", "--topic", "--from-position"):
        assert flag in text
    docs = (Path(__file__).parents[2] / "docs" / "export.md").read_text()
    for flag in ("--force", "--allow-unsafe", "--goal", "--topic", "--from-position"):
        assert flag in docs


def test_plan_export_options_let_an_unsafe_and_too_fast_plan_through(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``bioplan plan --export``: the UR5's default task is refused for its contact, then for
    elbow_joint's speed, and written with both overrides, which the file records."""
    out = tmp_path / "paper.yaml"
    base = ["plan", "--robot", str(robot_file(UR5)), "--duration", "2", "--payload", "1",
            "--method", "paper", "--export", str(out)]  # fmt: skip
    assert main(base) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--export {out}: method paper" in err
    if "not safe to run" not in err:  # the planner's collision check found nothing here
        assert "elbow_joint" in err
    else:
        assert "--export-allow-unsafe" in err  # this command's flag, not bioplan export's
        assert main([*base, "--export-allow-unsafe"]) == 2
        err = capsys.readouterr().err
        assert "joint 'elbow_joint' velocity" in err and "--export-force" in err
        base.append("--export-allow-unsafe")
    assert not out.exists()
    assert main([*base, "--export-force"]) == 0
    text = out.read_text()
    assert "# limits: FORCED past the robot's limits: joint 'elbow_joint' velocity" in text


def test_an_approach_round_many_turns_of_a_continuous_joint_is_refused(human: Any) -> None:
    robot, _, motion = human
    endless = robot.with_payload(robot.payload.mass)
    object.__setattr__(endless, "q_min", np.full(2, -np.inf))  # continuous joints
    object.__setattr__(endless, "q_max", np.full(2, np.inf))
    with pytest.raises(ExportError, match=r"from_position: the approach would take .* samples"):
        export_bytes(motion, "mcap", robot=endless, from_position=[1e9, 0.0])
