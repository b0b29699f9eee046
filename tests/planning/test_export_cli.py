"""The CLI side of export and onboarding: every option changes the result; bad input exits 2.

Commands run in-process through ``app.cli.main`` (the same parser and handlers as the console
script); stdout must hold exactly one JSON object with ``--json``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.cli import main
from tests.utils.example_robots import UR5, robot_file

FAST = ["--particles", "8", "--iterations", "5", "--method", "paper"]
SIDECAR = Path(__file__).resolve().parents[2] / "docs" / "examples" / "ur5.sidecar.yaml"


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, Any, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    data = json.loads(out) if "--json" in argv and code == 0 else None
    return code, data, err


def rows(path: Path) -> np.ndarray:
    """The CSV's numbers: after its ``#`` record lines and its one header line."""
    lines = [x for x in path.read_text().splitlines() if not x.startswith("#")]
    return np.loadtxt(lines[1:], delimiter=",")


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A human-arm plan saved with --out, and its --export CSV beside it."""
    folder = tmp_path_factory.mktemp("saved")
    assert main(["plan", "--robot", "human_arm_2dof", *FAST[:4], "--method", "paper,bound",
                 "--objective", "tau_sq", "--out", str(folder / "plan.json"),
                 "--export", str(folder / "plan.csv")]) == 0  # fmt: skip
    return folder


def test_plan_json_carries_joint_names_task_duration_and_motion(saved: Path) -> None:
    data = json.loads((saved / "plan.json").read_text())
    assert data["joint_names"] == ["shoulder_flexion", "elbow_flexion"]
    task = data["task"]
    assert task["start_deg"] == [0.0, 0.0] and task["goal_deg"] == pytest.approx([20.0, 150.0])
    # a curl lifts the arm and its load: its potential energy change is the |ΔPE| floor
    assert task["lifts"] is True
    assert task["delta_pe_j"] == pytest.approx(data["floors"]["delta_potential"], rel=1e-9)
    assert data["duration"] == 1.0
    assert set(data["motion"]["methods"]) == {"quintic", "paper", "bound"}


def test_optimal_control_method_exports_exactly_between_its_nodes(
    capsys: pytest.CaptureFixture[str], saved: Path
) -> None:
    """The bound is a constant-jerk cubic between IPOPT's nodes; its export at any rate must
    equal that cubic evaluated in closed form from the saved node states (q, qd, qdd)."""
    bound = json.loads((saved / "plan.json").read_text())["motion"]["methods"]["bound"]
    t_k, q_k = np.array(bound["t"]), np.array(bound["q"])
    qd_k, qdd_k = np.array(bound["qd"]), np.array(bound["qdd"])
    out = saved / "bound.csv"
    code, _, _ = run(capsys, "export", str(saved / "plan.json"), "--method", "bound",
                     "--rate", "733", "--out", str(out))  # fmt: skip
    assert code == 0
    data = rows(out)
    t = data[:, 0]
    inside = t <= t_k[-1]
    k = np.clip(np.searchsorted(t_k, t[inside], side="right") - 1, 0, t_k.size - 2)
    s = (t[inside] - t_k[k])[:, None]
    jerk = (qdd_k[k + 1] - qdd_k[k]) / (t_k[k + 1] - t_k[k])[:, None]
    q = q_k[k] + qd_k[k] * s + qdd_k[k] * s**2 / 2 + jerk * s**3 / 6
    assert np.max(np.abs(data[inside, 1:3] - q)) < 1e-9


def test_export_options_each_change_the_file(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    base = ["plan", "--robot", "human_arm_2dof", *FAST, "--json"]
    code, data, _ = run(capsys, *base, "--export", str(tmp_path / "a.csv"))
    assert code == 0 and "motion" in data
    run(capsys, *base, "--export", str(tmp_path / "b.csv"), "--export-rate", "100")
    run(capsys, *base, "--export", str(tmp_path / "c.csv"), "--export-method", "quintic")
    a, b, c = (rows(tmp_path / f"{x}.csv") for x in "abc")
    assert a.shape == (1001, 9) and b.shape == (101, 9) and c.shape == a.shape
    assert not np.allclose(a[:, 1:], c[:, 1:])  # paper vs quintic
    run(capsys, *base, "--export", str(tmp_path / "d.yaml"))
    assert (tmp_path / "d.yaml").read_text().count("time_from_start") == 101  # YAML: 100 Hz


def test_bioplan_export_rebuilds_the_saved_plan(
    capsys: pytest.CaptureFixture[str], saved: Path, tmp_path: Path
) -> None:
    result = str(saved / "plan.json")
    code, data, _ = run(capsys, "export", result, "--out", str(tmp_path / "x.csv"), "--json")
    assert code == 0 and data["format"] == "csv" and data["method"] == "paper"
    assert (tmp_path / "x.csv").read_bytes() == (saved / "plan.csv").read_bytes()
    run(capsys, "export", result, "--out", str(tmp_path / "y.csv"), "--method", "quintic")
    run(capsys, "export", result, "--out", str(tmp_path / "z.csv"), "--rate", "250")
    assert not np.allclose(rows(tmp_path / "y.csv"), rows(tmp_path / "x.csv"))
    assert rows(tmp_path / "z.csv").shape == (251, 9)
    code, data, _ = run(
        capsys, "export", result, "--format", "yaml", "--out", str(tmp_path / "t.yml"), "--json"
    )
    assert code == 0 and data["format"] == "yaml" and data["rate"] == 100.0


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--rate", "0"], "export rate is 0 Hz"),
        (["--rate", "1e9"], "export rate is 1e+09 Hz"),
        (["--method", "jerk_limited"], "method 'jerk_limited' is not in this result"),
        (["--format", "json"], "has extension .csv but --format is json"),
    ],
)
def test_bioplan_export_bad_input_exits_2_and_writes_nothing(
    capsys: pytest.CaptureFixture[str], saved: Path, tmp_path: Path, extra: list[str], message: str
) -> None:
    out = tmp_path / "x.csv"
    code, _, err = run(capsys, "export", str(saved / "plan.json"), "--out", str(out), *extra)
    assert code == 2 and message in err and err.count("\n") == 1
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_bioplan_export_refuses_what_is_not_a_result(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    (tmp_path / "notes.json").write_text('{"standard": {}}')
    (tmp_path / "broken.json").write_text("{")
    out = str(tmp_path / "x.csv")
    assert (
        "has no 'motion' block"
        in run(capsys, "export", str(tmp_path / "notes.json"), "--out", out)[2]
    )
    assert (
        "not JSON (line 1)" in run(capsys, "export", str(tmp_path / "broken.json"), "--out", out)[2]
    )
    assert (
        "cannot read the result"
        in run(capsys, "export", str(tmp_path / "no.json"), "--out", out)[2]
    )


def test_plan_refuses_a_bad_export_before_planning(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    base = ["plan", "--robot", "human_arm_2dof", *FAST]
    code, _, err = run(capsys, *base, "--export", str(tmp_path / "a.csv"), "--export-rate", "0")
    assert code == 2 and "export rate is 0 Hz" in err
    code, _, err = run(capsys, *base, "--export", str(tmp_path / "a.xlsx"))
    assert code == 2 and "unknown export extension '.xlsx'" in err
    code, _, err = run(capsys, *base, "--export", str(tmp_path / "no" / "a.csv"))
    assert code == 2 and "does not exist" in err
    assert list(tmp_path.iterdir()) == []


def test_onboarding_flags_on_a_ur5(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    urdf = str(robot_file(UR5))
    # The paper's method alone: these flags are about the robot, not the planning methods.
    base = ["plan", "--robot", urdf, "--duration", "2", "--payload", "1", "--particles", "10",
            "--iterations", "8", "--method", "paper", "--json"]  # fmt: skip
    code, plain, _ = run(capsys, *base)
    assert code == 0 and len(plain["joint_names"]) == 6
    assert plain["standard"]["electrical_energy"] is None  # no motor model: not modelled
    assert plain["improvement_pct"]["electrical_energy"] is None
    # The UR5's default task reaches below its mounting plane: the export must be allowed.
    code, locked, _ = run(capsys, *base, "--lock", "wrist_3_joint=30", "--export-allow-unsafe",
                          "--export", str(tmp_path / "ur5.script"))  # fmt: skip
    assert code == 0 and "wrist_3_joint" not in locked["joint_names"]
    assert locked["motion"]["locks"] == {"wrist_3_joint": pytest.approx(math.radians(30.0))}
    lines = [x for x in (tmp_path / "ur5.script").read_text().splitlines() if "servoj(" in x]
    assert float(lines[0].split("[")[1].split("]")[0].split(", ")[5]) == pytest.approx(
        math.radians(30.0), abs=1e-12
    )  # a URScript number: 12 decimals
    roles_args = ["--shoulder-joint", "shoulder_pan_joint", "--elbow-joint", "shoulder_lift_joint"]
    code, roles, _ = run(capsys, *base, *roles_args, "--goal-deg", "30,-60,0,0,0,0")
    assert code == 0 and roles["motion"]["robot_spec"]["elbow_joint"] == "shoulder_lift_joint"
    assert roles["standard"]["abs_work"] != plain["standard"]["abs_work"]
    code, modelled, _ = run(capsys, *base, "--sidecar", str(SIDECAR))
    assert code == 0 and modelled["standard"]["electrical_energy"] > 0.0
    assert len(modelled["joint_names"]) == 5  # the sidecar locks wrist 3


def test_onboarding_errors_name_the_joints(capsys: pytest.CaptureFixture[str]) -> None:
    urdf = str(robot_file(UR5))
    code, _, err = run(capsys, "plan", "--robot", urdf, "--elbow-joint", "knee")
    assert code == 2 and "elbow joint 'knee'" in err and "wrist_1_joint" in err
    code, _, err = run(capsys, "plan", "--robot", urdf, "--lock", "wrist_3_joint")
    assert code == 2 and "expected NAME=VALUE" in err
    code, _, err = run(capsys, "plan", "--robot", urdf, "--lock", "claw=1")
    assert code == 2 and "cannot lock 'claw'" in err
    code, _, err = run(capsys, "plan", "--robot", "curtain_wall_6dof", "--lock", "j1=0")
    assert code == 2 and "built-in robot" in err
    code, _, err = run(capsys, "plan", "--robot", urdf, "--lock", "wrist_3_joint=0",
                       "--start-deg", "0,0,0,0,0,0")  # fmt: skip
    assert code == 2 and "needs 5 angles" in err and "wrist_3_joint" not in err.split("(")[1]


def test_simulate_exports_and_honours_the_task(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    # A small swarm and the paper's method alone: this test is about the task and the export.
    base = ["simulate", "--robot", "human_arm_2dof", *FAST, "--json"]
    code, data, _ = run(capsys, *base, "--goal-deg", "10,120", "--export", str(tmp_path / "s.json"))
    assert code == 0 and data["conditions"]["goal_deg"] == pytest.approx([10.0, 120.0])
    exported = json.loads((tmp_path / "s.json").read_text())
    assert exported["task"]["goal_deg"] == pytest.approx([10.0, 120.0])
    assert data["motion"]["methods"]["paper"]["kind"] == "piecewise_quintic"


def test_help_shows_the_export_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["plan", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--export-method NAME" in text and "(default: the paper's method when planned" in text
    assert ".script 500 Hz" in text
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    assert "script 500 Hz" in " ".join(capsys.readouterr().out.split())


def test_a_refused_export_keeps_the_plan(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """A plan whose ``--export`` is refused after planning (URScript for a six-joint arm that
    is not a UR) still writes its ``--out`` JSON, says so, and exits 2 without the export;
    forced, the export is made."""
    out, script = tmp_path / "plan.json", tmp_path / "arm.script"
    argv = ["plan", "--robot", "curtain_wall_6dof", *FAST, "--out", str(out)]
    argv += ["--export", str(script)]
    code, _, err = run(capsys, *argv)
    assert code == 2 and not script.exists()
    assert "--export-force" in err, err
    assert f"the plan itself was written to {out}" in err
    saved = json.loads(out.read_text())
    assert set(saved["methods"]) == {"quintic", "paper"} and "motion" in saved
    assert run(capsys, *argv, "--export-force")[0] == 0 and script.is_file()
