"""Names from a robot file cannot inject code, formulas, keys or header lines into exports.

The robot of :mod:`tests.utils.hostile` carries URScript statements, spreadsheet formulas,
YAML keys and newlines in its ``<robot name>`` and joint names. Each format is read back by
an independent reader (line structure, the ``csv`` module, PyYAML, ``json``) and must hold
exactly what the format itself writes, the names as data (or comments) only.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from app.cli import main
from app.planning import load_robot, plan
from app.planning.export import export_bytes, plan_motion
from tests.utils.hostile import ELBOW, JOINT_NAMES, ROBOT_NAME, SHOULDER, hostile_urdf

RATE = 100.0  # 201 samples over 2 s; a whole fraction of the UR controller's 500 Hz


@pytest.fixture(scope="module")
def hostile(tmp_path_factory: pytest.TempPathFactory) -> Any:
    folder = tmp_path_factory.mktemp("hostile")
    path = folder / "hostile.urdf"
    path.write_text(hostile_urdf(), encoding="utf-8")
    robot = load_robot(path, shoulder_joint=SHOULDER, elbow_joint=ELBOW)
    assert robot.name == ROBOT_NAME and robot.joint_names == JOINT_NAMES  # read as written
    result = plan(robot, duration=2.0, seed=0, methods=("quintic", "jerk_limited"))
    return robot, plan_motion(result, robot), folder


def _export(hostile: Any, fmt: str) -> str:
    robot, motion, _ = hostile
    # The hostile arm's joints are not a UR's: its URScript is written only when forced.
    return export_bytes(motion, fmt, rate=RATE, robot=robot, force=fmt == "script").decode()


def _urscript_structure(text: str) -> None:
    """The program is one ``def ... end`` block and its call; outside them only comments."""
    lines = text.splitlines()
    defs = [i for i, line in enumerate(lines) if line.startswith("def ")]
    assert [lines[i] for i in defs] == ["def bioplan_trajectory():"]
    end = lines.index("end")
    assert lines[end + 1 :] == ["bioplan_trajectory()"]  # the one call, after the def
    outside = lines[: defs[0]]
    assert all(not x.strip() or x.startswith("#") for x in outside), outside
    inside = lines[defs[0] + 1 : end]
    assert all(x.startswith("  ") for x in inside)
    calls = {x.strip().split("(")[0] for x in inside}
    assert calls == {"movej", "servoj", "stopj"}
    assert "popup" not in text.replace("popup(1)", "").split("def ")[1]  # only in comments


def test_urscript_has_one_top_level_statement(hostile: Any) -> None:
    text = _export(hostile, "script")
    _urscript_structure(text)
    # the header comments: export, limits, the limits not stated (not checked), safety, the
    # forced non-UR note, joints
    assert text.count("\n# ") + text.startswith("# ") == 6
    assert "\n# limits not stated by the robot (not checked)" in text
    assert "\r" not in text


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def test_csv_has_no_formula_cell_and_one_header_line(hostile: Any) -> None:
    text = _export(hostile, "csv")
    lines = text.splitlines(keepends=True)
    comments = [x for x in lines if x.startswith("#")]
    assert lines[: len(comments)] == comments  # the export's record comes first
    for line in comments:  # each one cell starting with "#", however hostile the names
        assert next(csv.reader(io.StringIO(line))) == [line.rstrip("\n")]
    rows = list(csv.reader(io.StringIO("".join(lines[len(comments) :]))))
    assert len(rows[0]) == 1 + 4 * len(JOINT_NAMES)  # no name split a cell or a row
    assert len(rows) == 1 + 201 and text.count("\n") == len(comments) + 1 + 201
    for row in rows:
        for cell in row:
            assert _is_number(cell) or not cell.startswith(("=", "+", "-", "@", "\t", "\r")), cell
    body = [float(c) for row in rows[1:] for c in row]
    assert any(v < 0 for v in body) or all(v >= 0 for v in body)  # numbers stay numbers
    assert rows[0][1] == "q_=cmd|' /C calc'!A0 [rad]"


def test_csv_neutralises_a_formula_in_a_text_cell() -> None:
    from app.planning.export import csv_cell

    assert [csv_cell(x) for x in ("=1+1", "+1", "-x", "@SUM(A1)", "\tx", "\rx")] == [
        "'=1+1",
        "'+1",
        "'-x",
        "'@SUM(A1)",
        "'\tx",
        "'\rx",
    ]
    assert csv_cell("time [s]") == "time [s]" and csv_cell("q_a") == "q_a"


def test_yaml_keys_are_the_messages_and_names_round_trip(hostile: Any) -> None:
    document = yaml.safe_load(_export(hostile, "yaml"))
    assert set(document) == {"header", "joint_names", "points"}
    assert document["joint_names"] == list(JOINT_NAMES)
    assert all(isinstance(n, str) for n in document["joint_names"])
    assert set(document["header"]) == {"stamp", "frame_id"}
    assert len(document["points"]) == 201


def test_mot_header_has_exactly_its_lines(hostile: Any) -> None:
    lines = _export(hostile, "mot").split("\n")
    end = lines.index("endheader")
    assert end == 7
    assert lines[0].startswith("bioplan_") and lines[0].endswith("_jerk_limited")
    assert lines[1:5] == ["version=1", "nRows=201", "nColumns=7", "inDegrees=yes"]
    assert lines[5].startswith("bioplan_limits=") and lines[6].startswith("bioplan_safety=")
    labels = lines[end + 1].split("\t")
    assert len(labels) == 7 and labels[0] == "time"
    assert all(not x.startswith(("=", "+", "-", "@")) for x in labels)
    assert all(len(row.split("\t")) == 7 for row in lines[end + 2 : -1])


def test_json_keeps_the_names_as_data_and_no_server_folder(hostile: Any) -> None:
    _, _, folder = hostile
    text = _export(hostile, "json")
    data = json.loads(text)
    assert data["robot"] == ROBOT_NAME and data["joint_names"] == list(JOINT_NAMES)
    assert data["robot_spec"]["source"] == "hostile.urdf"
    assert str(folder) not in text and "/tmp" not in text


def test_bioplan_export_writes_a_safe_urscript(
    hostile: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, motion, _ = hostile
    saved = tmp_path / "plan.json"
    saved.write_text(json.dumps({"motion": motion.to_dict()}), encoding="utf-8")
    out = tmp_path / "arm.script"
    assert main(["export", str(saved), "--out", str(out), "--rate", "100", "--force"]) == 0
    _urscript_structure(out.read_text())
    printed = capsys.readouterr().out
    assert printed.count("\n") == 1 and "popup" in printed  # the name, on one line
    csv_out = tmp_path / "arm.csv"
    assert main(["export", str(saved), "--out", str(csv_out), "--rate", "100"]) == 0
    body = [x for x in csv_out.read_text().splitlines() if not x.startswith("#")]
    header = next(csv.reader(io.StringIO(body[0])))
    assert all(not c.startswith(("=", "+", "-", "@")) for c in header)
