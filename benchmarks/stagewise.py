"""The stage-wise transcription for fatrop against the project's IPOPT (issue 25, item 6).

Run: ``.venv/bin/python benchmarks/stagewise.py [--objectives tau_sq,peak_power]
[--intervals 40,80,160,320] [--solvers project,fatrop,ipopt_stagewise,ipopt_blocked,
fatrop_c,ipopt_stagewise_c] [--runs 3]
[--timeout 1800] [--out FILE]``; prints one JSON object and a text table.

Problem: the ``bound`` (no human constraint) of ``curtain_wall_6dof`` on its default task
(1 s, 4 kg, rest to rest, no reversal), warm-started from the paper's PSO plan (default budget,
seed 0), on N constant-jerk intervals. Solvers:

- ``project``: ``optimal.solve_optimal`` (IPOPT, MX graph, the per-point dynamics compiled to C
  from 1400 evaluation points), its solver and compiled-dynamics caches cleared before each
  cold run;
- ``fatrop``: :mod:`benchmarks.stagewise_problem` solved by CasADi's ``fatrop`` (manual structure);
  ``peak_power`` with the slack epigraph and the epigraph variable started at 4x the guess's
  peak (the one setting that solved the 40-interval case, see benchmarks/RESULTS.md);
- ``ipopt_stagewise``: the same stage-wise NLP solved by the project's IPOPT options;
- ``ipopt_blocked``: that NLP re-ordered as ``optimal`` orders its own (every node's states,
  then the controls; every gap row, then the path rows): the ordering alone, for MUMPS;
- ``fatrop_c``, ``ipopt_stagewise_c``: as ``fatrop`` and ``ipopt_stagewise`` with the
  per-point dynamics compiled to C (``optimal``'s ``_compiled``, cleared before each cold run;
  the stage function an MX graph calling it).

Each (objective, N, solver) runs in its own child process (a solver that hangs cannot take the
others with it): ``--runs`` cold runs (build + first solve) and, after each, the solve alone
again on the built solver; the paper's PSO is timed in the same child (``plan`` with
``quintic`` and ``paper``, once per run). Reported: medians of wall and CPU seconds (CPU of
the process and its waited-for children: the C compiler), iterations, the solver's objective
and its difference to the project's at the same N, and the objective re-evaluated with
Pinocchio on the 1000-sample report grid.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

ROOT = Path(__file__).resolve().parents[1]
ROBOT, PAYLOAD, DURATION = "curtain_wall_6dof", 4.0, 1.0
SOLVERS = (
    "project", "fatrop", "ipopt_stagewise", "ipopt_blocked", "fatrop_c", "ipopt_stagewise_c",
)  # fmt: skip
#: The stage-wise optimum "equals" the project's within this fraction [-].
SAME_OPTIMUM = 1e-3


def _cpu() -> float:
    """CPU seconds of this process and its waited-for children (the C compiler) [s]."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _timed(fn: Any) -> tuple[Any, float, float]:
    wall, cpu = time.perf_counter(), _cpu()
    out = fn()
    return out, time.perf_counter() - wall, _cpu() - cpu


def _pso(robot: Any, objective: str) -> tuple[Any, float, float]:
    """The paper's PSO plan (the warm start) and its wall and CPU seconds."""
    from app.planning.planner import plan

    res, wall, cpu = _timed(lambda: plan(robot, objective=objective, methods=("quintic", "paper")))
    return res.methods["paper"].trajectory, wall, cpu


def _project_run(robot: Any, task: Any, objective: str, n: int, warm: Any) -> dict[str, Any]:
    from app.planning import optimal

    human = optimal.HumanSpec("none", robot.elbow_joint)

    def solve() -> Any:
        return optimal.solve_optimal(
            robot, task.start, task.goal, DURATION, objective=objective, human=human,
            warm_start=warm, warm_start_name="paper", n_intervals=n, explain=False,
        )  # fmt: skip

    optimal._SOLVERS.clear()
    optimal._COMPILED.clear()
    res, cold_wall, cold_cpu = _timed(solve)
    _, solve_wall, solve_cpu = _timed(solve)  # the structure is cached now: the solve alone
    return {
        "cold_wall": cold_wall, "cold_cpu": cold_cpu, "solve_wall": solve_wall,
        "solve_cpu": solve_cpu, "iterations": res.solver.iterations,
        "objective": res.solver.objective, "trajectory": res.trajectory,
    }  # fmt: skip


class _Blocked:
    """IPOPT on the stage-wise NLP re-ordered as ``optimal`` orders its own: the states of
    every node first (component by component), then the controls; every gap row first, then
    the path rows. The same NLP; only the order IPOPT (and MUMPS) sees differs."""

    def __init__(self, problem: Any) -> None:
        import casadi as ca
        import numpy as np

        from app.planning import optimal

        lay, n = problem.layout, problem.problem.n_intervals
        width, rows = lay.nx + lay.nu, lay.nx + problem.ng
        idx = np.arange(problem.args["x0"].size)
        states = np.vstack([idx[: n * width].reshape(n, width)[:, : lay.nx], idx[n * width :]])
        controls = idx[: n * width].reshape(n, width)[:, lay.nx :]
        self.perm = np.concatenate([states.ravel(order="F"), controls.ravel(order="F")])
        g_idx = np.arange(n * rows).reshape(n, rows)
        self.gperm = np.concatenate(
            [g_idx[:, : lay.nx].ravel(order="F"), g_idx[:, lay.nx :].ravel(order="F")]
        )
        inverse = np.empty_like(self.perm)
        inverse[self.perm] = np.arange(self.perm.size)
        nlp = problem.nlp
        v = ca.MX.sym("v", idx.size)
        fg = ca.Function("fg", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]])
        f, g = fg(v[[int(i) for i in inverse]], nlp["p"])
        g = g[[int(i) for i in self.gperm]]
        self.solver = ca.nlpsol(
            "blocked", "ipopt", {"x": v, "p": nlp["p"], "f": f, "g": g},
            dict(optimal._IPOPT_OPTIONS),
        )  # fmt: skip
        a = problem.args
        self.args = {
            "x0": a["x0"][self.perm], "lbx": a["lbx"][self.perm], "ubx": a["ubx"][self.perm],
            "lbg": a["lbg"][self.gperm], "ubg": a["ubg"][self.gperm], "p": a["p"],
        }  # fmt: skip
        self.problem = problem

    def solve(self) -> Any:
        import numpy as np

        from benchmarks.stagewise_problem import StagewiseResult

        sol = self.solver(**self.args)
        stats = self.solver.stats()
        if stats.get("return_status") != "Solve_Succeeded":
            raise RuntimeError(f"IPOPT (blocked order): {stats.get('return_status')}")
        ws = np.empty(self.perm.size)
        ws[self.perm] = np.asarray(sol["x"], dtype=np.float64).ravel()
        p = self.problem
        return StagewiseResult(
            knots=p._knots(ws), objective=float(p.cost_fn(ws, p.problem.duration)),
            status="Solve_Succeeded", iterations=int(stats["iter_count"]),
            build_seconds=0.0, solve_seconds=0.0, sizes={},
        )  # fmt: skip


def _stagewise_run(
    robot: Any, task: Any, objective: str, n: int, warm: Any, solver: str
) -> dict[str, Any]:
    from app.planning import optimal
    from app.planning.profiles import time_grid
    from benchmarks.stagewise_problem import StagewiseProblem

    compiled = solver.endswith("_c")
    base = solver.removesuffix("_c")
    opts: dict[str, Any] = {"compile_dynamics": compiled}
    if base == "fatrop" and objective == "peak_power":
        opts.update(epigraph="slacks", z_start=4.0)
    name = "fatrop" if base == "fatrop" else "ipopt"
    optimal._COMPILED.clear()  # cold: the C dynamics compiled again

    def build() -> Any:
        problem = StagewiseProblem(
            robot, task.start, task.goal, DURATION, objective=objective, n_intervals=n,
            warm_start=warm, solver=name, **opts,
        )  # fmt: skip
        return _Blocked(problem) if base == "ipopt_blocked" else problem

    problem, build_wall, build_cpu = _timed(build)
    res, first_wall, first_cpu = _timed(problem.solve)
    _, solve_wall, solve_cpu = _timed(problem.solve)
    return {
        "cold_wall": build_wall + first_wall, "cold_cpu": build_cpu + first_cpu,
        "build_wall": build_wall, "solve_wall": solve_wall, "solve_cpu": solve_cpu,
        "iterations": res.iterations, "objective": res.objective,
        "trajectory": res.knots.sample(time_grid(DURATION, 1000), name=solver),
    }  # fmt: skip


def _child_main(objective: str, n: int, solver: str, runs: int) -> dict[str, Any]:
    """One (objective, N, solver) in this process: ``runs`` cold runs, the PSO beside each."""
    import numpy as np

    from app.planning.evaluation import evaluate_trajectory
    from app.planning.methods import objective_value
    from app.planning.planner import PlanTask
    from app.planning.robots import load_robot

    robot = load_robot(ROBOT, payload=PAYLOAD)
    task = PlanTask.default(robot)
    out: dict[str, Any] = {"objective": objective, "n_intervals": n, "solver": solver}
    rows: list[dict[str, Any]] = []
    pso: list[tuple[float, float]] = []
    for _ in range(runs):
        warm, pso_wall, pso_cpu = _pso(robot, objective)
        pso.append((pso_wall, pso_cpu))
        try:
            if solver == "project":
                row = _project_run(robot, task, objective, n, warm)
            else:
                row = _stagewise_run(robot, task, objective, n, warm, solver)
        except Exception as exc:  # a solver's failure is a result here
            out["error"] = f"{type(exc).__name__}: {exc}"[:400]
            break
        ev = evaluate_trajectory(robot, row.pop("trajectory"), task)
        row["fine_grid_objective"] = objective_value(robot, ev, objective)
        row["violations"] = list(ev.violations)
        rows.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)
    out["runs"] = rows
    out["pso_wall"] = float(np.median([p[0] for p in pso]))
    out["pso_cpu"] = float(np.median([p[1] for p in pso]))
    for key in ("cold_wall", "cold_cpu", "solve_wall", "solve_cpu", "iterations"):
        if rows:
            out[key] = float(statistics.median(r[key] for r in rows))
    if rows:
        out["objective_value"] = rows[0]["objective"]
        out["fine_grid_objective"] = rows[0]["fine_grid_objective"]
        out["load"] = os.getloadavg()[0]
    return out


def _child(objective: str, n: int, solver: str, runs: int, timeout: float) -> dict[str, Any]:
    import signal

    cmd = [
        sys.executable, str(Path(__file__).resolve()), "--child",
        f"{objective}:{n}:{solver}", "--runs", str(runs),
    ]  # fmt: skip
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)}, start_new_session=True,
    )  # fmt: skip
    base = {"objective": objective, "n_intervals": n, "solver": solver}
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return {**base, "error": f"timed out after {timeout:g} s", "runs": []}
    if proc.returncode != 0:
        return {**base, "error": stderr[-600:], "runs": []}
    result: dict[str, Any] = json.loads(stdout.strip().splitlines()[-1])
    return result


def _table(results: list[dict[str, Any]]) -> str:
    ref = {
        (r["objective"], r["n_intervals"]): r["objective_value"]
        for r in results
        if r["solver"] == "project" and "objective_value" in r
    }
    lines = [
        "objective | N | solver | cold wall / CPU s | solve wall / CPU s | iters | objective "
        "| vs project | fine grid | PSO CPU s | cold CPU / PSO CPU"
    ]
    for r in results:
        head = f"{r['objective']} | {r['n_intervals']} | {r['solver']}"
        if "objective_value" not in r:
            lines.append(f"{head} | failed: {r.get('error', '?').strip().splitlines()[-1]}")
            continue
        key = (r["objective"], r["n_intervals"])
        diff = ""
        if key in ref:
            rel = (r["objective_value"] - ref[key]) / abs(ref[key])
            r["vs_project"] = rel
            diff = f"{100 * rel:+.4f} %" + ("" if abs(rel) <= SAME_OPTIMUM else " (differs)")
        lines.append(
            f"{head} | {r['cold_wall']:.2f} / {r['cold_cpu']:.2f} | {r['solve_wall']:.2f} / "
            f"{r['solve_cpu']:.2f} | {r['iterations']:.0f} | {r['objective_value']:.6g} | {diff} "
            f"| {r['fine_grid_objective']:.6g} | {r['pso_cpu']:.2f} | "
            f"{r['cold_cpu'] / r['pso_cpu']:.1f}x"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objectives", default="tau_sq,peak_power")
    parser.add_argument("--intervals", default="40,80,160,320")
    parser.add_argument("--solvers", default=",".join(SOLVERS))
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--timeout", type=float, default=1800.0, help="per child [s]")
    parser.add_argument("--out", default=None, help="also write the JSON here")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        objective, n, solver = args.child.split(":")
        print(json.dumps(_child_main(objective, int(n), solver, args.runs)))
        return
    results = []
    for objective in args.objectives.split(","):
        for n in (int(v) for v in args.intervals.split(",")):
            for solver in args.solvers.split(","):
                if solver not in SOLVERS:
                    parser.error(f"--solvers: unknown {solver!r}, expected one of {SOLVERS}")
                results.append(_child(objective, n, solver, args.runs, args.timeout))
                print(json.dumps(results[-1]), file=sys.stderr, flush=True)
    text = _table(results)
    payload = json.dumps({"same_optimum": SAME_OPTIMUM, "results": results}, indent=1)
    if args.out:
        Path(args.out).write_text(payload, encoding="utf-8")
    print(payload)
    print(text)


if __name__ == "__main__":
    main()
