"""Optimal control beside the paper's method: speed, convergence evidence and the shares.

Run: ``.venv/bin/python benchmarks/bench_optimal.py [--runs 5] [--json] [--only speed]
[--cases robot:objective,...] [--variants before,after] [--cli-robots r1,r2] [--cli-converge]``.

1. ``speed``: ``human_optimal`` and ``bound`` on ``curtain_wall_6dof`` (default task, 1 s, 4 kg,
   default resolution) and ``human_arm_2dof`` (1 s, 12 kg), per objective, warm-started from the
   PSO plan; median of ``runs`` solves, each *cold* (the solver cache cleared: building the
   problem is included, as ``bioplan plan`` pays it) and *warm* (the same structure solved again,
   as in sweeps). Targets: 6-DOF < 3 s each, 2-DOF < 1 s.
2. ``convergence``: for each problem, the optimum reached from two initial guesses (the quintic
   and the PSO plan) agrees within 0.1 %; re-evaluated with Pinocchio on a grid 10x finer than
   the solver's points, it stays within the limits and within 0.5 % of the solver's objective.
3. ``shares``: the issue's table, share of the achievable saving the paper's method captures,
   (quintic − paper) / (quintic − bound), and the cost of the human constraint
   (human_optimal vs bound), per robot and objective; the minimum-torque-change baseline with
   the joint limits.
4. ``cli``: ``bioplan plan --objective peak_power`` with every method, process start to JSON,
   per robot of ``--cli-robots`` (default task and payload); ``--cli-converge``: also with
   ``--converge``.
5. ``converged`` (issue 25, items 1 and 6): ``plan(..., converge=True)`` with the paper's PSO,
   ``human_optimal`` and ``bound`` on each robot and objective of ``--cases``, each variant of
   ``--variants`` in its own child process (cold: nothing cached in memory):
   - ``before``: every refined mesh solved with IPOPT's default start, interpreted dynamics,
     the change-only stop;
   - ``separate_nodes``: the defaults, but every node evaluated twice, as one interval's end
     and the next one's start (``optimal.SHARE_NODES = False``);
   - ``auto_ordering``: the defaults, but MUMPS's automatic fill-reducing ordering
     (``mumps_pivot_order`` 7) instead of AMD;
   - ``after``: the defaults (small initial barrier parameter from the coarser optimum, the
     per-point dynamics compiled to C, the Richardson stop, each node evaluated once, AMD).
   CPU seconds of the process per method (the machine is shared: wall time counts the others'
   load) and of the C compiler (child processes, all methods together), the mesh sequences,
   and (human_optimal + bound) / PSO.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    name: ("tau_sq", "abs_work", "pos_work", "peak_power", "peak_torque", "electrical_energy")
    for name in ("curtain_wall_6dof", "human_arm_2dof")
}
TARGET_SECONDS = {"curtain_wall_6dof": 3.0, "human_arm_2dof": 1.0}


def _setup(robot_name: str, objective: str) -> tuple[Any, ...]:
    from app.planning.methods import human_spec
    from app.planning.planner import PlanTask, plan
    from app.planning.robots import load_robot

    robot = load_robot(robot_name)
    task = PlanTask.default(robot)
    base = plan(robot, objective=objective, methods=("quintic", "paper"))
    spec, _ = human_spec("peak", robot, task, base.template, np.radians(62.0))
    return robot, task, base, spec


def _solve(robot: Any, task: Any, objective: str, spec: Any, warm: Any) -> Any:
    from app.planning.optimal import solve_optimal

    return solve_optimal(
        robot, task.start, task.goal, 1.0, objective=objective, human=spec,
        warm_start=None if warm is None else warm.trajectory,
        warm_start_name="quintic" if warm is None else "paper",
    )  # fmt: skip


def bench_speed(runs: int) -> dict[str, Any]:
    from app.planning import optimal
    from app.planning.optimal import HumanSpec

    out: dict[str, Any] = {}
    for robot_name, objectives in CASES.items():
        for objective in objectives:
            robot, task, base, spec = _setup(robot_name, objective)
            warm = base.methods["paper"]
            bound = HumanSpec("none", robot.elbow_joint)
            for name, human in (("human_optimal", spec), ("bound", bound)):
                cold, hot, iters = [], [], []
                for _ in range(runs):
                    optimal._SOLVERS.clear()
                    t0 = time.perf_counter()
                    sol = _solve(robot, task, objective, human, warm)
                    cold.append(time.perf_counter() - t0)
                    iters.append(sol.solver.iterations)
                    t0 = time.perf_counter()
                    _solve(robot, task, objective, human, warm)
                    hot.append(time.perf_counter() - t0)
                key = f"{robot_name}/{objective}/{name}"
                out[key] = {
                    "median_cold_seconds": statistics.median(cold),
                    "median_warm_seconds": statistics.median(hot),
                    "iterations": iters,
                    "target_seconds": TARGET_SECONDS[robot_name],
                }
                print(f"{key}: cold {out[key]['median_cold_seconds']:.2f} s, warm "
                      f"{out[key]['median_warm_seconds']:.2f} s, {iters[0]} iterations",
                      flush=True)  # fmt: skip
    return out


def _fine_check(robot: Any, task: Any, objective: str, sol: Any) -> dict[str, Any]:
    """Re-evaluate on a grid 10x finer than the solver's evaluation points."""
    from app.planning.evaluation import evaluate_trajectory
    from app.planning.methods import objective_value
    from app.planning.profiles import time_grid

    points = 8 * sol.solver.n_intervals  # the densest rule: eighths of every interval
    traj = sol.knots.sample(time_grid(1.0, 10 * points + 1), name="fine")
    ev = evaluate_trajectory(robot, traj, task)
    fine = objective_value(robot, ev, objective)
    return {
        "solver_objective": sol.solver.objective,
        "fine_objective": fine,
        "fine_vs_solver_pct": 100.0 * (fine - sol.solver.objective) / abs(sol.solver.objective),
        "fine_samples": traj.t.size,
        "violations": list(ev.violations),
    }


def bench_convergence() -> dict[str, Any]:
    from app.planning.optimal import HumanSpec

    out: dict[str, Any] = {}
    for robot_name, objectives in CASES.items():
        for objective in objectives:
            robot, task, base, spec = _setup(robot_name, objective)
            for name, human in (("human_optimal", spec),
                                ("bound", HumanSpec("none", robot.elbow_joint))):  # fmt: skip
                from_paper = _solve(robot, task, objective, human, base.methods["paper"])
                from_quintic = _solve(robot, task, objective, human, None)
                a, b = from_paper.solver.objective, from_quintic.solver.objective
                key = f"{robot_name}/{objective}/{name}"
                out[key] = {
                    "from_paper": a,
                    "from_quintic": b,
                    "difference_pct": 100.0 * abs(a - b) / abs(a),
                    **_fine_check(robot, task, objective, from_paper),
                }
                print(f"{key}: guesses differ {out[key]['difference_pct']:.4f} %, fine grid "
                      f"{out[key]['fine_vs_solver_pct']:+.3f} %, "
                      f"{len(out[key]['violations'])} violations", flush=True)  # fmt: skip
    return out


def bench_shares() -> dict[str, Any]:
    from app.planning.comparison import compare_profiles
    from app.planning.methods import ALL_METHODS
    from app.planning.min_torque_change import minimum_torque_change
    from app.planning.planner import PlanTask, plan
    from app.planning.robots import load_robot

    out: dict[str, Any] = {}
    for robot_name, objectives in CASES.items():
        robot = load_robot(robot_name)
        for objective in (*objectives, "peak_torque"):
            res = plan(robot, objective=objective, methods=ALL_METHODS)
            values = res.objective_values
            q = values["quintic"]
            out[f"{robot_name}/{objective}"] = {
                "values": values,
                "saving_pct": {n: 100.0 * (q - v) / abs(q) for n, v in values.items()},
                "share_of_achievable_pct": res.share_of_achievable_pct,
                "human_constraint_cost_pct": 100.0
                * (values["human_optimal"] - values["bound"])
                / abs(values["bound"]),
            }
            s = res.share_of_achievable_pct
            print(f"{robot_name}/{objective}: paper {s['paper']:.1f} %, human-like "
                  f"{s['human_optimal']:.1f} %, jerk-limited {s['jerk_limited']:.1f} % of the "
                  "achievable saving", flush=True)  # fmt: skip
    human = load_robot("human_arm_2dof")
    task = PlanTask.default(human)
    basis = minimum_torque_change(human.dynamics(), task.start, task.goal, 1.0, n_samples=1001)
    limited = compare_profiles(human, duration=1.0)
    mtc = limited.profiles["min_torque_change"]
    out["min_torque_change/human_arm_2dof"] = {
        "basis_unlimited_J": basis.torque_change,
        "basis_shoulder_min_deg": float(np.degrees(basis.trajectory.q[:, 0].min())),
        "limited_J": limited.min_torque_change.objective if limited.min_torque_change else None,
        "limited_shoulder_min_deg": float(np.degrees(mtc.trajectory.q[:, 0].min())),
        "limited_violations": list(mtc.violations),
    }
    print(f"minimum torque change: {out['min_torque_change/human_arm_2dof']}", flush=True)
    return out


def bench_cli(runs: int, robots: str, converge: bool) -> dict[str, Any]:
    """``bioplan plan`` (every method, ``peak_power``, the robot's default task and payload),
    process start to JSON, per robot; with ``converge`` also with ``--converge``."""
    from benchmarks.bench_planner import json_command_seconds

    exe = ROOT / ".venv" / "bin" / "bioplan"
    out: dict[str, Any] = {}
    for robot in robots.split(","):
        for flags in ([], ["--converge"]) if converge else ([],):
            cmd = [str(exe) if exe.exists() else "bioplan", "plan", "--robot", robot,
                   "--objective", "peak_power", "--json", *flags]  # fmt: skip
            times = json_command_seconds(cmd, runs)
            label = " ".join(cmd[1:])
            print(f"bioplan {label}: median {statistics.median(times):.2f} s "
                  f"(load {os.getloadavg()[0]:.1f})", flush=True)  # fmt: skip
            out[label] = {"seconds": times, "median_seconds": statistics.median(times)}
    return out


#: ``--only converged`` cases: robot, payload [kg], objective.
CONVERGED_CASES = (
    ("human_arm_2dof", 12.0, "tau_sq"),
    ("human_arm_2dof", 12.0, "peak_power"),
    ("curtain_wall_6dof", 4.0, "tau_sq"),
    ("curtain_wall_6dof", 4.0, "peak_power"),
)


def _converged_child(robot_name: str, payload: float, objective: str, variant: str) -> None:
    """One converged plan in this process; prints one JSON line."""
    from app.planning import methods, optimal, planner
    from app.planning.robots import load_robot

    if variant == "separate_nodes":
        optimal.SHARE_NODES = False
    if variant == "auto_ordering":
        optimal._IPOPT_OPTIONS["ipopt.mumps_pivot_order"] = 7
    if variant == "before":
        optimal.COMPILE_FROM_POINTS = 10**12
        optimal._WARM.clear()  # the warm-flagged solve then runs with IPOPT's defaults

        def change_only(values: Any) -> tuple[float, bool]:
            return abs(values[-1] - values[-2]) / max(abs(values[-2]), abs(values[-1])), False

        methods.mesh_error_estimate = change_only  # type: ignore[assignment]
    cpu: dict[str, float] = {}

    def timed(fn: Any, key: Any) -> Any:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            name = key(args, kwargs)
            t0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                cpu[name] = cpu.get(name, 0.0) + time.process_time() - t0

        return wrapper

    planner.run_paper = timed(planner.run_paper, lambda a, k: "paper")
    for fn_name in ("run_optimal", "run_bound", "refine_to_convergence"):
        original = getattr(planner, fn_name)
        setattr(planner, fn_name, timed(original, lambda a, k: k.get("name") or a[2].name))
    robot = load_robot(robot_name, payload=payload)
    t0, c0 = time.perf_counter(), time.process_time()
    result = planner.plan(
        robot, objective=objective, methods=("quintic", "paper", "human_optimal", "bound"),
        converge=True,
    )  # fmt: skip
    wall, total = time.perf_counter() - t0, time.process_time() - c0
    # The C compiler runs in child processes: its CPU time is not in process_time().
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    data = result.to_dict()["methods"]
    out = {"robot": robot_name, "objective": objective, "variant": variant, "cpu": cpu,
           "cpu_total": total, "cpu_compiler": children.ru_utime + children.ru_stime,
           "wall_total": wall, "load": os.getloadavg()[0]}  # fmt: skip
    for name in ("human_optimal", "bound"):
        conv = (data[name].get("solver") or {}).get("convergence") or {}
        out[name] = {"value": data[name][objective], **conv}
    print(json.dumps(out, default=float), flush=True)


def bench_converged(runs: int, cases: str | None, variants: str) -> list[dict[str, Any]]:
    chosen = [c for c in CONVERGED_CASES if cases is None or f"{c[0]}:{c[2]}" in cases.split(",")]
    rows: list[dict[str, Any]] = []
    for robot_name, payload, objective in chosen:
        for variant in variants.split(","):
            for _ in range(runs):
                cmd = [sys.executable, __file__, "--converged-child",
                       f"{robot_name}:{payload}:{objective}:{variant}"]  # fmt: skip
                proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
                row = json.loads(proc.stdout.strip().splitlines()[-1])
                rows.append(row)
                cpu = row["cpu"]
                oc = cpu.get("human_optimal", 0.0) + cpu.get("bound", 0.0)
                pso = max(cpu.get("paper", 0.0), 1e-9)
                meshes = {
                    m: (
                        [st.get("n_intervals") for st in row[m]["sequence"]],
                        f"{row[m]['value']:.6g}",
                        f"est {row[m]['error_estimate']:.2g}",
                    )
                    for m in ("human_optimal", "bound")
                }
                print(
                    f"{robot_name} {objective} {variant}: CPU human_optimal "
                    f"{cpu.get('human_optimal', 0):.1f} s, bound {cpu.get('bound', 0):.1f} s, "
                    f"PSO {pso:.2f} s, ratio {oc / pso:.1f}x; C compiler "
                    f"{row.get('cpu_compiler', 0.0):.1f} s; wall {row['wall_total']:.1f} s "
                    f"(load {row['load']:.1f}); {meshes}",
                    flush=True,
                )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="repetitions per timing")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument(
        "--only", choices=("speed", "convergence", "shares", "cli", "converged"), default=None,
        help="run one part only",
    )  # fmt: skip
    parser.add_argument(
        "--cases", default=None,
        help="converged: robot:objective pairs, comma-separated (default: all four)",
    )  # fmt: skip
    parser.add_argument(
        "--variants", default="before,after",
        help="converged: before (no compiled dynamics, cold refinement, change-only stop), "
        "separate_nodes (each node evaluated as two points, the transcription before "
        "optimal.SHARE_NODES), auto_ordering (MUMPS's automatic ordering instead of AMD), "
        "after (the defaults); comma-separated",
    )  # fmt: skip
    parser.add_argument(
        "--cli-robots", default="curtain_wall_6dof",
        help="cli: the robots, comma-separated",
    )  # fmt: skip
    parser.add_argument(
        "--cli-converge", action="store_true",
        help="cli: also time each plan with --converge",
    )  # fmt: skip
    parser.add_argument("--converged-child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.converged_child:
        robot_name, payload, objective, variant = args.converged_child.split(":")
        _converged_child(robot_name, float(payload), objective, variant)
        return
    print(f"load average {os.getloadavg()[0]:.2f}", flush=True)
    parts = {
        "speed": lambda: bench_speed(args.runs),
        "convergence": bench_convergence,
        "shares": bench_shares,
        "cli": lambda: bench_cli(args.runs, args.cli_robots, args.cli_converge),
        "converged": lambda: bench_converged(args.runs, args.cases, args.variants),
    }
    results = {
        name: fn()
        for name, fn in parts.items()
        if (args.only is None and name != "converged") or args.only == name
    }
    if args.json:
        print(json.dumps(results, indent=2, default=float))


if __name__ == "__main__":
    main()
