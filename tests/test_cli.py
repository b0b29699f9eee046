"""The CLI contract of DESIGN.md: --json prints one object; bad input exits 2, in one line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, timeout=300
    )


def test_plan_json_is_one_object_with_the_contract_keys() -> None:
    proc = run_cli(
        "plan",
        "--robot",
        "human_arm_2dof",
        "--duration",
        "1.0",
        "--payload",
        "12",
        "--objective",
        "abs_work",
        "--particles",
        "8",
        "--iterations",
        "5",
        "--json",
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)  # the whole of stdout is one JSON document
    assert {
        "standard",
        "optimized",
        "floors",
        "improvement_pct",
        "peak_velocity_angle_deg",
        "optimizer",
    } <= set(data)
    assert data["optimizer"]["seed"] == 0


def test_plan_writes_out_file(tmp_path: Path) -> None:
    out = tmp_path / "plan.json"
    proc = run_cli(
        "plan",
        "--robot",
        "human_arm_2dof",
        "--particles",
        "6",
        "--iterations",
        "3",
        "--out",
        str(out),
    )
    assert proc.returncode == 0, proc.stderr
    assert "standard quintic" in proc.stdout
    assert json.loads(out.read_text())["conditions"]["robot"] == "human_arm_2dof"


def test_profiles_lists_classical_and_min_torque_change() -> None:
    proc = run_cli("profiles", "--robot", "human_arm_2dof", "--duration", "1.0", "--json")
    assert proc.returncode == 0, proc.stderr
    names = set(json.loads(proc.stdout)["profiles"])
    expected = {"trapezoidal", "triangular", "s_curve", "cubic", "quintic", "minimum_jerk"}
    assert names == expected | {"min_torque_change"}


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["plan", "--robot", "no_such_robot"], "no_such_robot"),
        (["plan", "--robot", "human_arm_2dof", "--objective", "beauty"], "beauty"),
        (["plan", "--robot", "human_arm_2dof", "--duration", "-1"], "duration"),
        (["plan", "--robot", "human_arm_2dof", "--duration", "0"], "duration"),
        (
            ["plan", "--robot", "human_arm_2dof", "--start-deg", "0,90", "--goal-deg", "0,90"],
            "start equals goal",
        ),
        (["plan", "--robot", "human_arm_2dof", "--duration", "0.05"], "infeasible"),
        (["plan", "--robot", "human_arm_2dof", "--duration", "abc"], "duration"),
    ],
)
def test_bad_input_one_line_exit_2(args: list[str], needle: str) -> None:
    proc = run_cli(*args)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert needle in lines[0]
    assert "Traceback" not in proc.stderr


def test_malformed_urdf_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "broken.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot")
    proc = run_cli("plan", "--robot", str(bad))
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1
    assert "broken.urdf" in proc.stderr
