"""Adaptive (non-uniform) against uniform mesh refinement of the optimal control (issue 25).

``.venv/bin/python benchmarks/adaptive_mesh.py [--runs 3] [--cases robot:objective,...]
[--reference]``: ``plan(..., methods=quintic,paper,human_optimal,bound, converge=True)`` on the
default task (1 s; ``human_arm_2dof`` 12 kg, ``curtain_wall_6dof`` 4 kg), each run in its own
child process (cold), per ``--variants``: ``uniform`` (uniform doubling of equal intervals,
``optimal.END_GRADING = 0``), ``graded`` (uniform doubling, every segment's end intervals graded:
the default, ``optimal.END_GRADING = 5`` capped by the report grid) and ``adaptive``
(``methods.ADAPTIVE_MESH = True`` on equal intervals).
Prints CPU seconds per method (the refinement included), the mesh
sequence, the final value and, with ``--reference``, its error against one more mesh of 640
intervals (graded with L = 5 on a report grid of :data:`REFERENCE_SAMPLES` when the ``graded``
variant runs, else equal) solved from that variant's final optimum (the reference, re-evaluated
with Pinocchio on its report grid like every value here); then the adaptive runs' CPU until
each method first reaches the uniform runs' final value (each row's ``cpu_at_mesh``: the
method's CPU at the end of each mesh of its sequence).
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: Cases: robot, payload [kg], objective.
CASES = (
    ("human_arm_2dof", 12.0, "tau_sq"),
    ("human_arm_2dof", 12.0, "peak_power"),
    ("curtain_wall_6dof", 4.0, "tau_sq"),
    ("curtain_wall_6dof", 4.0, "peak_power"),
)
METHODS = ("human_optimal", "bound")
#: The ``graded`` variant's end grading (``optimal.END_GRADING``).
GRADED_LEVELS = 5
#: The reference mesh [intervals].
REFERENCE_INTERVALS = 640
#: The reference's report grid [samples]: fine enough that L = 5 is not capped at 640 intervals.
REFERENCE_SAMPLES = 640 * 32 + 1


def _child(robot_name: str, payload: float, objective: str, variant: str, reference: bool) -> None:
    """One converged plan in this process; prints one JSON line."""
    from app.planning import methods, optimal, planner
    from app.planning.robots import load_robot

    methods.ADAPTIVE_MESH = variant == "adaptive"
    optimal.END_GRADING = GRADED_LEVELS if variant == "graded" else 0
    cpu: dict[str, float] = {}
    began: dict[str, float] = {}  # CPU clock when each method's first solve began [s]
    ended: dict[str, float] = {}  # ... and when it returned
    solves: list[tuple[str, float]] = []  # every mesh solve's method and end on that clock

    def timed(fn: Any, key: Any) -> Any:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            name = key(args, kwargs)
            t0 = time.process_time()
            began.setdefault(name, t0)
            try:
                return fn(*args, **kwargs)
            finally:
                cpu[name] = cpu.get(name, 0.0) + time.process_time() - t0
                ended.setdefault(name, time.process_time())

        return wrapper

    solve_mesh = methods.run_optimal

    def recorded(*args: Any, **kwargs: Any) -> Any:
        try:
            return solve_mesh(*args, **kwargs)
        finally:
            solves.append((str(kwargs.get("name")), time.process_time()))

    methods.run_optimal = recorded  # the refinement's solves (refine_to_convergence calls it)

    planner.run_paper = timed(planner.run_paper, lambda a, k: "paper")
    for fn_name in ("run_optimal", "run_bound"):
        original = getattr(planner, fn_name)
        setattr(planner, fn_name, timed(original, lambda a, k: k.get("name") or a[2].name))
    calls: dict[str, dict[str, Any]] = {}  # each refinement's arguments, for the reference

    def keep(a: Any, k: Any) -> str:
        calls[a[2].name] = {"task": a[1], **k}
        return str(a[2].name)

    planner.refine_to_convergence = timed(planner.refine_to_convergence, keep)
    robot = load_robot(robot_name, payload=payload)
    t0 = time.perf_counter()
    result = planner.plan(
        robot, objective=objective, methods=("quintic", "paper", *METHODS), converge=True
    )
    wall = time.perf_counter() - t0
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    out: dict[str, Any] = {
        "robot": robot_name, "objective": objective, "variant": variant, "cpu": cpu,
        "cpu_compiler": children.ru_utime + children.ru_stime, "wall": wall,
        "load": os.getloadavg()[0],
    }  # fmt: skip
    for name in METHODS:
        method = result.methods[name]
        conv = (method.solver or {}).get("convergence") or {}
        out[name] = {"value": methods.objective_value(robot, method.evaluated, objective), **conv}
        # Cumulative CPU [s] of the method at the end of each mesh of its sequence: the first
        # mesh when the planner's call returned, the others at their refinement solve's end.
        finer = [end for who, end in solves if who == name and end > ended[name]]
        marks = [ended[name], *finer][: len(conv.get("sequence", []))]
        out[name]["cpu_at_mesh"] = [m - began[name] for m in marks]
        if reference:
            call = calls[name]
            t1 = time.process_time()
            fine = methods.run_optimal(
                robot, call["task"], name=name, duration=call["duration"], objective=objective,
                spec=call["spec"], warm=method, n_intervals=REFERENCE_INTERVALS,
                no_reversal=call["no_reversal"],
                report_samples=max(call["report_samples"], REFERENCE_SAMPLES),
                near_optimum=True,
            )  # fmt: skip
            out[name]["reference"] = methods.objective_value(robot, fine.evaluated, objective)
            out[name]["reference_cpu"] = time.process_time() - t1
    print(json.dumps(out, default=float), flush=True)


def _run(case: tuple[str, float, str], variant: str, reference: bool) -> dict[str, Any]:
    robot_name, payload, objective = case
    flag = f"{robot_name}:{payload}:{objective}:{variant}:{int(reference)}"
    cmd = [sys.executable, __file__, "--child", flag]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    row: dict[str, Any] = json.loads(proc.stdout.strip().splitlines()[-1])
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="runs per case and variant")
    parser.add_argument("--cases", default=None, help="robot:objective pairs, comma-separated")
    parser.add_argument("--variants", default="uniform,graded,adaptive")
    parser.add_argument(
        "--reference", action="store_true", help="solve the 640-interval reference (uniform run)"
    )
    parser.add_argument("--out", default=None, help="also write every row as JSON lines here")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        robot_name, payload, objective, variant, ref = args.child.split(":")
        _child(robot_name, float(payload), objective, variant, ref == "1")
        return
    reference_variant = "graded" if "graded" in args.variants.split(",") else "uniform"
    chosen = [c for c in CASES if args.cases is None or f"{c[0]}:{c[2]}" in args.cases.split(",")]
    for case in chosen:
        refs: dict[str, float] = {}
        by_variant: dict[str, list[dict[str, Any]]] = {}
        for variant in args.variants.split(","):
            rows = by_variant.setdefault(variant, [])
            for run in range(args.runs):
                # The reference on the finest mesh the variants have: graded when asked for.
                ref = args.reference and run == 0 and variant == reference_variant
                row = _run(case, variant, ref)
                rows.append(row)
                for m in METHODS:
                    if "reference" in row[m]:
                        refs[m] = row[m]["reference"]
                if args.out:
                    with open(args.out, "a", encoding="utf-8") as fh:
                        fh.write(json.dumps(row, default=float) + "\n")
            _summary(case, variant, rows, refs)
        if "uniform" in by_variant and "adaptive" in by_variant:
            _to_uniform_value(case, by_variant["uniform"], by_variant["adaptive"])


def _to_uniform_value(
    case: tuple[str, float, str], uniform: list[dict[str, Any]], adaptive: list[dict[str, Any]]
) -> None:
    """The adaptive runs' CPU until each method's sequence first reaches the uniform runs'
    (median) final value, at most 0.01 % above it (NaN if it never does)."""
    parts = []
    for m in METHODS:
        target = statistics.median(r[m]["value"] for r in uniform)
        reach = []
        for r in adaptive:
            cpu = float("nan")
            for step, at in zip(
                r[m].get("sequence", []), r[m].get("cpu_at_mesh", []), strict=False
            ):
                if step.get("objective", float("inf")) <= target * (1 + 1e-4):
                    cpu = at
                    break
            reach.append(cpu)
        uni = statistics.median(r["cpu"].get(m, 0.0) for r in uniform)
        parts.append(f"{m} {statistics.median(reach):.2f} s (uniform {uni:.2f} s)")
    print(f"{case[0]} {case[2]} adaptive to the uniform's final value: " + "; ".join(parts))


def _summary(
    case: tuple[str, float, str], variant: str, rows: list[dict[str, Any]], refs: dict[str, float]
) -> None:
    def med(key: str) -> float:
        return statistics.median(r["cpu"].get(key, 0.0) for r in rows)

    pso = med("paper")
    total = statistics.median(
        r["cpu"].get("human_optimal", 0.0) + r["cpu"].get("bound", 0.0) for r in rows
    )
    parts = []
    for m in METHODS:
        last = rows[-1][m]
        seq = [s.get("n_intervals") for s in last.get("sequence", [])]
        small = min((s.get("smallest_interval", float("nan")) for s in last.get("sequence", [])),
                    default=float("nan"))  # fmt: skip
        err = ""
        if m in refs:
            err = f", vs ref {100 * (last['value'] - refs[m]) / refs[m]:+.3f} %"
        parts.append(
            f"{m} {med(m):.2f} s meshes {seq} h_min {1e3 * small:.2f} ms value "
            f"{last['value']:.6g} est {last.get('error_estimate', float('nan')):.2g}{err}"
        )
    loads = ", ".join(f"{r['load']:.1f}" for r in rows)
    print(
        f"{case[0]} {case[2]} {variant}: PSO {pso:.2f} s; (h_o + bound) {total:.2f} s = "
        f"{total / max(pso, 1e-9):.1f}x PSO; " + "; ".join(parts) + f"; load {loads}",
        flush=True,
    )


if __name__ == "__main__":
    main()
