"""The honest cost of human-likeness per task (issue 25, item 4).

Run: ``.venv/bin/python benchmarks/human_likeness.py [--converge] [--json]``.

For each robot (``human_arm_2dof``, ``curtain_wall_6dof``) and task (the default task in 1 s
with the robot's default payload; the same in 1.5 s with 5 kg; the default task reversed,
lowering, in 1 s with the default payload) and each objective (``tau_sq``, ``peak_power``):
the physical ``bound`` (no human constraint) and ``human_optimal`` with ``peak`` (one clear
elbow-speed peak at the template's place) and with ``shape`` (the recorded lifts' elbow-speed
band). Human-likeness comes from the real template of the pyomeca upper-limb trial in
../shared/data (three curls with elbow kinematics, 2 kg), so ``peak`` puts its peak where those
lifts peak and ``shape`` follows their band. Reported: each objective value, the cost over the
bound [%], and the human-likeness score (RMS distance of the normalised elbow-speed profile to
the template's on the stroke; 0 = the same shape). A method the limits make infeasible is
reported as such.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

ROBOTS = ("human_arm_2dof", "curtain_wall_6dof")
OBJECTIVES = ("tau_sq", "peak_power")
KINDS = ("peak", "shape")
TRIAL = "pyomeca_upperlimb_c3d_emg/markers_analogs.c3d"


def _template() -> Any:
    from app.analysis import analyze_recordings
    from app.recordings import read_recording

    data = Path(__file__).resolve().parents[2] / "shared" / "data"
    return analyze_recordings([read_recording(data / TRIAL)], load_mass=2.0).template


def _tasks(robot_name: str) -> list[tuple[str, float, float | None, bool]]:
    """(label, duration [s], payload [kg] or None = the default, lowering)."""
    return [
        ("default, 1 s", 1.0, None, False),
        ("1.5 s, 5 kg", 1.5, 5.0, False),
        ("lowering, 1 s", 1.0, None, True),
    ]


def _one(robot: Any, task: Any, duration: float, objective: str, kind: str, **common: Any) -> Any:
    from app.errors import BioPlanError
    from app.planning.planner import plan

    method = "bound" if kind == "bound" else "human_optimal"
    try:
        result = plan(
            robot, task=task, duration=duration, objective=objective, methods=[method],
            human_constraint="none" if kind == "bound" else kind, safety=False, **common,
        )  # fmt: skip
    except BioPlanError as exc:  # the only method failed (SolverError too): say why
        return None, str(exc)
    if method not in result.methods:
        return None, result.method_errors[method].error
    return result, ""


def run(converge: bool) -> list[dict[str, Any]]:
    from app.planning.evaluation import PlanTask
    from app.planning.human_constraints import human_likeness_distance, template_speed_on_stroke
    from app.planning.robots import load_robot

    template = _template()
    rows = []
    for robot_name in ROBOTS:
        for label, duration, payload, lowering in _tasks(robot_name):
            robot = load_robot(robot_name) if payload is None else load_robot(
                robot_name, payload=payload
            )  # fmt: skip
            task = PlanTask.default(robot)
            if lowering:
                task = PlanTask(start=task.goal, goal=task.start)
            e = robot.elbow_joint
            q0, q1 = float(task.start[e]), float(task.goal[e])
            reference, _ = template_speed_on_stroke(template, q0, q1)
            for objective in OBJECTIVES:
                row: dict[str, Any] = {
                    "robot": robot_name, "task": label, "payload": robot.payload.mass,
                    "objective": objective,
                }  # fmt: skip
                for kind in ("bound", *KINDS):
                    result, error = _one(
                        robot, task, duration, objective, kind, template=template,
                        converge=converge,
                    )  # fmt: skip
                    if result is None:
                        row[kind] = {"error": error}
                        continue
                    method = "bound" if kind == "bound" else "human_optimal"
                    traj = result.methods[method].trajectory
                    row[kind] = {
                        "value": result.objective_values[method],
                        "score": human_likeness_distance(
                            traj.q[:, e], traj.qd[:, e], q0, q1, reference
                        ),
                        "seconds": result.methods[method].solver.get("seconds"),
                    }
                bound = row["bound"].get("value")
                for kind in KINDS:
                    value = row[kind].get("value")
                    if bound and value is not None:
                        row[kind]["cost_pct"] = 100.0 * (value / bound - 1.0)
                rows.append(row)
                _print(row)
    return rows


def _cell(entry: dict[str, Any], key: str, fmt: str) -> str:
    return "infeasible" if "error" in entry else format(entry[key], fmt)


def _print(row: dict[str, Any]) -> None:
    b, p, s = row["bound"], row["peak"], row["shape"]
    print(
        f"| {row['robot']} | {row['task']} ({row['payload']:g} kg) | {row['objective']} | "
        f"{_cell(b, 'value', '.4g')} | {_cell(p, 'value', '.4g')} | "
        f"{_cell(p, 'cost_pct', '+.1f') if 'value' in b else '-'} | "
        f"{_cell(s, 'value', '.4g')} | {_cell(s, 'cost_pct', '+.1f') if 'value' in b else '-'} | "
        f"{_cell(b, 'score', '.3f')} / {_cell(p, 'score', '.3f')} / {_cell(s, 'score', '.3f')} |",
        flush=True,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--converge", action="store_true", help="mesh-converged results")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON at the end")
    args = parser.parse_args()
    print(
        "| robot | task | objective | bound | peak | peak cost % | shape | shape cost % | "
        "score bound / peak / shape |\n|---|---|---|---|---|---|---|---|---|"
    )
    rows = run(args.converge)
    if args.json:
        print(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
