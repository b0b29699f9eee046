"""IPOPT with a limited-memory (L-BFGS / L-SR1) Hessian on the optimal control (issue 25, item 6).

Run: ``.venv/bin/python benchmarks/lbfgs.py [--variants exact,lm6,lm20,lm50,lm20_sr1]
[--cases curtain_wall_6dof:peak_power,...] [--intervals 40,160,320]
[--methods human_optimal,bound] [--runs 3] [--jobs 1] [--timeout 900] [--out FILE]``;
prints one JSON line per solve as it finishes, then a text table.

Why: a converged plan's time is IPOPT evaluating the exact Hessian of the Lagrangian (the RNEA's
second derivatives at every evaluation point; "Converged results: where the time goes" in
benchmarks/RESULTS.md). ``hessian_approximation: limited-memory`` needs first derivatives only,
at the price of more iterations and a quasi-Newton model of an indefinite, degenerate problem.

Cases: ``human_optimal`` (peak constraint at 62 deg) and ``bound`` on ``curtain_wall_6dof``
(default task, 1 s, 4 kg) and ``human_arm_2dof`` (default task, 1 s, 12 kg), objectives
``peak_power`` and ``tau_sq``, warm-started from the paper's PSO plan (default budget, seed 0),
on N equal constant-jerk intervals (``n_intervals``). Everything but the IPOPT options is the
project's own ``solve_optimal`` (transcription, scaling, per-point dynamics compiled to C from
``optimal.COMPILE_FROM_POINTS`` points, status check); the options are swapped in the child by
replacing ``optimal._IPOPT_OPTIONS`` (``_solver`` reads it when it builds).

Variants (names ``lm<history>[_sr1][_scalar<k>|_constant][_lowrank]``):
- ``exact``: the project's default (exact Hessian);
- ``lm<H>``: ``hessian_approximation limited-memory``, ``limited_memory_max_history`` H,
  ``limited_memory_update_type`` bfgs (``_sr1``: sr1), ``limited_memory_initialization``
  scalar1 (IPOPT's default; ``_scalar2``... or ``_constant`` to change it),
  ``limited_memory_aug_solver`` sherman-morrison (IPOPT's default; ``_lowrank``: low-rank-aug,
  the low-rank term as extra rows of the augmented system instead of extra back-solves).

Each (variant, robot, objective, method, N) runs in its own child process. In it, every run is
cold: the solver and compiled-dynamics caches cleared (building and compiling included, as one
``bioplan plan`` pays it); ``--runs`` runs, but one only if the first takes 30 s of CPU or more.
Reported per run: CPU seconds of the process and its waited-for children (the C compiler),
wall seconds, the 1-minute load before and after, IPOPT's status and iterations, the CPU of the
solve call alone and CasADi's CPU per function IPOPT evaluated (``t_proc``: the Hessian, the
Jacobian, ...), the solver's objective, the graded ends used, and the objective re-evaluated
with Pinocchio on the 1000-sample report grid (``evaluate_trajectory`` + ``objective_value``)
with its violations. The table gives medians per (case, method, N) and variant: CPU
(iterations), CPU relative to ``exact`` and the re-evaluated objective against ``exact``'s.

``--converged``: ``plan(..., methods=quintic,paper,human_optimal,bound, converge=True)`` per
case and variant instead (``bench_optimal.py --only converged``'s child, the options swapped
in), each run in its own process; CPU per method.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

ROOT = Path(__file__).resolve().parents[1]
PAYLOADS = {"curtain_wall_6dof": 4.0, "human_arm_2dof": 12.0}
CASES = tuple(f"{r}:{o}" for r in PAYLOADS for o in ("peak_power", "tau_sq"))
VARIANTS = ("exact", "lm6", "lm20", "lm50", "lm20_sr1")
#: One run only when the first run of a child takes at least this much CPU [s].
ONE_RUN_ABOVE = 30.0
#: "The same optimum": re-evaluated objectives within this fraction of ``exact``'s [-].
SAME_OPTIMUM = 1e-4
_VARIANT = re.compile(r"^lm(\d+)(?:_(bfgs|sr1))?(?:_(scalar[1-4]|constant))?(_lowrank)?$")


def variant_options(variant: str) -> dict[str, Any]:
    """The IPOPT options a variant adds to the project's (empty for ``exact``)."""
    if variant == "exact":
        return {}
    match = _VARIANT.match(variant)
    if match is None:
        raise ValueError(
            f"unknown variant {variant!r}: expected 'exact' or "
            "lm<history>[_sr1][_scalar<k>|_constant][_lowrank]"
        )
    history, update, init, lowrank = match.groups()
    return {
        "ipopt.hessian_approximation": "limited-memory",
        "ipopt.limited_memory_max_history": int(history),
        "ipopt.limited_memory_update_type": update or "bfgs",
        "ipopt.limited_memory_initialization": init or "scalar1",
        "ipopt.limited_memory_aug_solver": "low-rank-aug" if lowrank else "sherman-morrison",
    }


def _cpu() -> float:
    """CPU seconds of this process and its waited-for children (the C compiler) [s]."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


class _Timed:
    """A built solver that counts the CPU of its calls (the solve alone, without building the
    NLP, the solver and the compiled dynamics) [s]."""

    def __init__(self, solver: Any) -> None:
        self.solver, self.cpu = solver, 0.0

    def __call__(self, **kwargs: Any) -> Any:
        started = _cpu()
        try:
            return self.solver(**kwargs)
        finally:
            self.cpu += _cpu() - started

    def stats(self) -> dict[str, Any]:
        return dict(self.solver.stats())


def _one_solve(
    robot: Any, task: Any, objective: str, human: Any, warm: Any, n: int
) -> dict[str, Any]:
    """One cold solve (caches cleared) with whatever options ``optimal`` holds now."""
    from app.planning import optimal
    from app.planning.evaluation import evaluate_trajectory
    from app.planning.methods import objective_value

    built: list[Any] = []
    original = optimal._solver

    def capture(problem: Any, nlp: dict[str, Any]) -> Any:
        solver = _Timed(original(problem, nlp))
        built.append(solver)
        return solver

    optimal._solver = capture  # type: ignore[assignment]
    optimal._SOLVERS.clear()
    optimal._COMPILED.clear()
    load0 = os.getloadavg()[0]
    wall, cpu = time.perf_counter(), _cpu()
    row: dict[str, Any] = {}
    try:
        res = optimal.solve_optimal(
            robot, task.start, task.goal, 1.0, objective=objective, human=human,
            warm_start=warm, warm_start_name="paper", explain=False, n_intervals=n,
        )  # fmt: skip
    except optimal.SolverError as exc:
        res = None
        row["error"] = str(exc)[:200]
    row["cpu"] = _cpu() - cpu
    row["wall"] = time.perf_counter() - wall
    row["load"] = [load0, os.getloadavg()[0]]
    optimal._solver = original  # type: ignore[assignment]
    stats = built[-1].stats() if built else {}
    row["status"] = str(stats.get("return_status", "unknown"))
    row["iterations"] = int(stats.get("iter_count", -1))
    row["solve_cpu"] = built[-1].cpu if built else None
    # Where the solve's time went: CasADi's evaluation of each function IPOPT asks for [s]; the
    # rest of ``solve_cpu`` is IPOPT itself (the KKT factorisations and back-solves and, with
    # limited memory, the quasi-Newton update and its extra back-solves).
    row["t_proc"] = {
        k[len("t_proc_") :]: float(v) for k, v in stats.items() if k.startswith("t_proc_")
    }
    if res is not None:
        ev = evaluate_trajectory(robot, res.trajectory, task)
        row["solver_objective"] = res.solver.objective
        row["objective"] = objective_value(robot, ev, objective)
        row["violations"] = len(ev.violations)
        row["end_grading"] = res.solver.end_grading
    return row


def _child(variant: str, robot_name: str, objective: str, method: str, n: int, runs: int) -> None:
    """Every run of one (variant, case, method, N) in this process; prints one JSON line."""
    import numpy as np

    from app.planning import optimal
    from app.planning.methods import human_spec
    from app.planning.planner import PlanTask, plan
    from app.planning.robots import load_robot

    optimal._IPOPT_OPTIONS = {**optimal._IPOPT_OPTIONS, **variant_options(variant)}
    robot = load_robot(robot_name, payload=PAYLOADS[robot_name])
    task = PlanTask.default(robot)
    base = plan(robot, objective=objective, methods=("quintic", "paper"))
    warm = base.methods["paper"].trajectory
    if method == "bound":
        human = optimal.HumanSpec("none", robot.elbow_joint)
    else:
        human, _ = human_spec("peak", robot, task, base.template, np.radians(62.0))
    rows = []
    for _ in range(runs):
        rows.append(_one_solve(robot, task, objective, human, warm, n))
        if rows[0]["cpu"] >= ONE_RUN_ABOVE:
            break
    key = {"variant": variant, "robot": robot_name, "objective": objective, "method": method}
    print(json.dumps({**key, "n": n, "runs": rows}), flush=True)


def _converged_child(variant: str, robot_name: str, objective: str) -> None:
    """One converged plan (``bench_optimal``'s converged child, ``after`` = today's defaults)
    with the variant's IPOPT options in every solve; prints one JSON line."""
    from app.planning import optimal
    from benchmarks.bench_optimal import _converged_child as converged

    optimal._IPOPT_OPTIONS = {**optimal._IPOPT_OPTIONS, **variant_options(variant)}
    converged(robot_name, PAYLOADS[robot_name], objective, "after")


def _spawn(job: tuple[str, str, str, str, int], runs: int, timeout: float) -> dict[str, Any]:
    variant, robot_name, objective, method, n = job
    key = {"variant": variant, "robot": robot_name, "objective": objective, "method": method}
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child",
           f"{variant}:{robot_name}:{objective}:{method}:{n}:{runs}"]  # fmt: skip
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )  # fmt: skip
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the child's compiler too
        proc.communicate()
        out = {**key, "n": n, "runs": [], "error": f"timed out after {timeout:g} s"}
    else:
        if proc.returncode != 0:
            out = {**key, "n": n, "runs": [], "error": stderr.strip()[-400:]}
        else:
            out = json.loads(stdout.strip().splitlines()[-1])
    print(json.dumps(out), flush=True)
    return out


def _summary(out: dict[str, Any]) -> dict[str, Any]:
    runs = out["runs"]
    if not runs:
        error = (out.get("error") or "?").strip().splitlines()[-1]
        return {"text": f"failed: {error[-120:]}"}
    ok = [r for r in runs if "objective" in r]
    loads = [x for r in runs for x in r["load"]]
    return {
        "cpu": statistics.median(r["cpu"] for r in runs),
        "wall": statistics.median(r["wall"] for r in runs),
        "iterations": statistics.median(r["iterations"] for r in runs),
        "status": ",".join(sorted({r["status"] for r in runs})),
        "objective": statistics.median(r["objective"] for r in ok) if ok else None,
        "violations": max((r["violations"] for r in ok), default=0),
        "load": f"{min(loads):.1f}-{max(loads):.1f}",
        "runs": len(runs),
    }


def _cell(s: dict[str, Any], ref: dict[str, Any] | None) -> str:
    """One variant's cell: CPU [s] (iterations), CPU against ``exact``, objective against it."""
    if "text" in s:
        return s["text"]
    if not s["status"].startswith("Solve_Succeeded"):
        return f"**{s['status']}** ({s['iterations']:g} it., {s['cpu']:.1f} s)"
    text = f"{s['cpu']:.2f} s ({s['iterations']:g})"
    if ref is None or "text" in ref or ref["objective"] is None:
        return text
    rel = (s["objective"] - ref["objective"]) / abs(ref["objective"])
    same = "=" if abs(rel) <= SAME_OPTIMUM else f"**{100 * rel:+.3f} %**"
    return f"{text} {s['cpu'] / ref['cpu']:.2f}x {same}"


def table(results: list[dict[str, Any]]) -> str:
    """Markdown: one row per (case, method, N), one column per variant (medians); ``=``: the
    re-evaluated objective within :data:`SAME_OPTIMUM` of ``exact``'s, else the difference."""
    summary = {
        (r["robot"], r["objective"], r["method"], r["n"], r["variant"]): _summary(r)
        for r in results
    }
    variants = list(dict.fromkeys(r["variant"] for r in results))
    lines = [
        "| robot, objective, method | N | exact value | "
        + " | ".join(f"`{v}`" for v in variants) + " | runs | load |",
        "|---|---|---|" + "---|" * len(variants) + "---|---|",
    ]  # fmt: skip
    for robot, objective, method, n in sorted({k[:4] for k in summary}):
        cells = [summary.get((robot, objective, method, n, v)) for v in variants]
        ref = summary.get((robot, objective, method, n, "exact"))
        value = "-" if not ref or ref.get("objective") is None else f"{ref['objective']:.6g}"
        runs = "/".join(str(c.get("runs", 0)) for c in cells if c)
        loads = [x for c in cells if c and "load" in c for x in map(float, c["load"].split("-"))]
        load = f"{min(loads):.1f}-{max(loads):.1f}" if loads else ""
        text = " | ".join("" if c is None else _cell(c, ref) for c in cells)
        lines.append(
            f"| {robot} `{objective}` {method} | {n} | {value} | {text} | {runs} | {load} |"
        )
    return "\n".join(lines)


def _converged(args: argparse.Namespace) -> None:
    """``--converged``: each (case, variant, run) in its own process, one JSON line each, then
    the medians of the CPU per method."""
    rows: list[dict[str, Any]] = []
    for case in args.cases.split(","):
        for variant in args.variants.split(","):
            for _ in range(args.runs):
                cmd = [sys.executable, str(Path(__file__).resolve()), "--converged-child",
                       f"{variant}:{case}"]  # fmt: skip
                proc = subprocess.run(
                    cmd, capture_output=True, text=True, timeout=args.timeout,
                    env={**os.environ, "PYTHONPATH": str(ROOT)},
                )  # fmt: skip
                if proc.returncode != 0:
                    row = {"case": case, "variant": variant, "error": proc.stderr[-400:]}
                else:
                    row = {"case": case, **json.loads(proc.stdout.strip().splitlines()[-1])}
                    row["variant"] = variant
                rows.append(row)
                print(json.dumps(row, default=float), flush=True)
    if args.out:
        Path(args.out).write_text(json.dumps(rows, indent=1, default=float), encoding="utf-8")
    for case in args.cases.split(","):
        for variant in args.variants.split(","):
            done = [r for r in rows if r["case"] == case and r["variant"] == variant]
            ok = [r for r in done if "cpu" in r]
            if not ok:
                print(f"{case} {variant}: failed")
                continue
            cpu = {m: statistics.median(r["cpu"].get(m, 0.0) for r in ok) for m in ok[0]["cpu"]}
            values = {m: ok[0][m]["value"] for m in ("human_optimal", "bound")}
            print(f"{case} {variant}: CPU {cpu}, values {values}, runs {len(ok)}/{len(done)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--cases", default=",".join(CASES), help="robot:objective, comma-separated")
    parser.add_argument("--intervals", default="40,160,320", help="N, comma-separated")
    parser.add_argument("--methods", default="human_optimal,bound")
    parser.add_argument("--runs", type=int, default=3, help="cold runs per child (< 30 s each)")
    parser.add_argument("--jobs", type=int, default=1, help="children at once")
    parser.add_argument("--timeout", type=float, default=900.0, help="per child [s]")
    parser.add_argument("--out", default=None, help="also write every result as JSON here")
    parser.add_argument(
        "--converged", action="store_true",
        help="plan(..., converge=True) per variant and case instead (--runs processes each)",
    )  # fmt: skip
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--converged-child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.converged_child:
        _converged_child(*args.converged_child.split(":"))
        return
    if args.child:
        variant, robot_name, objective, method, n, runs = args.child.split(":")
        _child(variant, robot_name, objective, method, int(n), int(runs))
        return
    for v in args.variants.split(","):
        try:  # a bad name fails here, before any child starts
            variant_options(v)
        except ValueError as exc:
            parser.error(str(exc))
    if args.converged:
        _converged(args)
        return
    jobs = [
        (v, *case.split(":"), m, int(n))
        for case in args.cases.split(",")
        for n in args.intervals.split(",")
        for m in args.methods.split(",")
        for v in args.variants.split(",")
    ]
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(lambda j: _spawn(j, args.runs, args.timeout), jobs))
    if args.out:
        Path(args.out).write_text(json.dumps(results, indent=1), encoding="utf-8")
    print(table(results))


if __name__ == "__main__":
    main()
