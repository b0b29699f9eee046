"""The per-point dynamics compiled once per machine (``app.planning.jit_cache``) against once per
process from ``optimal.COMPILE_FROM_POINTS`` points (the cache off).

Run: ``.venv/bin/python benchmarks/jit_cache.py [--runs 3] [--cases robot:objective,...]
[--converge both|off|on]``.

Each plan (``quintic``, ``paper``, ``human_optimal``, ``bound`` on the robot's default task, 1 s;
``human_arm_2dof`` 12 kg, ``curtain_wall_6dof`` 4 kg) runs in its own child process, three ways:

- ``off``: ``BIOPLAN_JIT_CACHE=off``, the dynamics compiled from ``COMPILE_FROM_POINTS`` points
  in every process (the behaviour before the cache);
- ``cold``: the cache on but empty (a fresh folder per run): the dynamics compiled at every
  mesh, the C compiler's first run paid;
- ``warm``: the cache on and filled by an earlier process (what every plan after the first of
  a chain structure on a machine sees).

Reported: CPU seconds of the child and of its own children (the C compiler and the cache's
wrapper), medians of ``runs``, the optima (they must agree to 1e-6) and the load.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_CASES = (
    "human_arm_2dof:tau_sq,curtain_wall_6dof:tau_sq,human_arm_2dof:peak_power,"
    "curtain_wall_6dof:peak_power"
)
PAYLOAD = {"human_arm_2dof": 12.0, "curtain_wall_6dof": 4.0}


def _child(robot_name: str, objective: str, converge: bool) -> None:
    """One plan in this process; one JSON line."""
    from app.planning.planner import plan
    from app.planning.robots import load_robot

    robot = load_robot(robot_name, payload=PAYLOAD[robot_name])
    t0, c0 = time.perf_counter(), time.process_time()
    result = plan(
        robot, objective=objective, methods=("quintic", "paper", "human_optimal", "bound"),
        converge=converge,
    )  # fmt: skip
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    methods = result.to_dict()["methods"]
    print(json.dumps({
        "cpu": time.process_time() - c0, "compiler": children.ru_utime + children.ru_stime,
        "wall": time.perf_counter() - t0, "load": os.getloadavg()[0],
        "values": {m: methods[m][objective] for m in ("human_optimal", "bound")},
    }), flush=True)  # fmt: skip


def run_plan(case: str, converge: bool, env_changes: dict[str, str | None]) -> dict[str, Any]:
    """One plan of ``robot:objective`` in a child process with these environment variables set
    (None: removed); the child's JSON line."""
    robot_name, objective = case.split(":")
    env = dict(os.environ)
    for name, value in env_changes.items():
        if value is None:
            env.pop(name, None)
        else:
            env[name] = value
    script = str(ROOT / "benchmarks" / "jit_cache.py")
    args = [sys.executable, script, "--child", robot_name, objective, str(int(converge))]
    out = subprocess.run(args, env=env, capture_output=True, text=True, check=True, cwd=ROOT)
    row: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return row


def _run(case: str, converge: bool, variant: str, folder: str) -> dict[str, Any]:
    off = "off" if variant == "off" else None
    return run_plan(case, converge, {"BIOPLAN_CACHE_DIR": folder, "BIOPLAN_JIT_CACHE": off})


def bench(cases: list[str], converge_modes: list[bool], runs: int) -> list[dict[str, Any]]:
    rows = []
    for case in cases:
        for converge in converge_modes:
            with tempfile.TemporaryDirectory() as warm_folder:
                _run(case, converge, "warm", warm_folder)  # fills the cache
                per: dict[str, list[dict[str, Any]]] = {"off": [], "cold": [], "warm": []}
                for _ in range(runs):
                    for variant in per:
                        if variant == "warm":
                            per[variant].append(_run(case, converge, variant, warm_folder))
                        else:
                            with tempfile.TemporaryDirectory() as fresh:
                                per[variant].append(_run(case, converge, variant, fresh))
            row: dict[str, Any] = {"case": case, "converge": converge}
            for variant, results in per.items():
                row[variant] = {
                    key: statistics.median(r[key] for r in results)
                    for key in ("cpu", "compiler", "wall", "load")
                }
                row[variant]["values"] = results[0]["values"]
            row["max_value_difference"] = max(
                abs(row[v]["values"][m] - row["off"]["values"][m]) / abs(row["off"]["values"][m])
                for v in ("cold", "warm")
                for m in ("human_optimal", "bound")
            )
            print(json.dumps(row), flush=True)
            rows.append(row)
    return rows


def _table(rows: list[dict[str, Any]]) -> None:
    print(
        "| case | converge | off: CPU + compiler | cold | warm | warm / off | optima differ "
        "| load |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for row in rows:
        cells = []
        totals = {}
        for variant in ("off", "cold", "warm"):
            r = row[variant]
            totals[variant] = r["cpu"] + r["compiler"]
            cells.append(f"{r['cpu']:.2f} + {r['compiler']:.2f} s")
        loads = [row[v]["load"] for v in ("off", "cold", "warm")]
        print(
            f"| {row['case']} | {'on' if row['converge'] else 'off'} | {' | '.join(cells)} | "
            f"{totals['warm'] / totals['off']:.2f}x | {row['max_value_difference']:.1e} | "
            f"{min(loads):.1f}-{max(loads):.1f} |"
        )


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        sys.path.insert(0, str(ROOT))
        _child(sys.argv[2], sys.argv[3], sys.argv[4] == "1")
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="runs per variant (median)")
    parser.add_argument("--cases", default=DEFAULT_CASES, help="robot:objective,...")
    parser.add_argument("--converge", choices=("both", "off", "on"), default="both")
    args = parser.parse_args()
    modes = {"both": [False, True], "off": [False], "on": [True]}[args.converge]
    rows = bench(args.cases.split(","), modes, args.runs)
    _table(rows)


if __name__ == "__main__":
    main()
