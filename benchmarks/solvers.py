"""Solver variants for the optimal-control methods (issue 25, item 6 "Fast").

Run: ``.venv/bin/python benchmarks/solvers.py [--variants ipopt,...] [--robots ...]
[--timeout 900]``; prints one JSON object (every variant, case and method: status, cold and
warm seconds, objective and its difference to IPOPT's) and a text table.

Each variant runs in a child process (a variant that hangs or crashes CasADi cannot take the
others with it). In the child, ``app.planning.optimal._solver`` is replaced by the variant's
builder; everything else (transcription, scaling, warm start, status check) is the project's own
``solve_optimal``. Cases: ``human_optimal`` (peak constraint) and ``bound`` on
``curtain_wall_6dof`` (default task, 1 s, 4 kg) and ``human_arm_2dof`` (default task, 1 s, 12 kg),
warm-started from the paper's PSO plan, default 40 intervals. *cold*: the solver cache cleared
(the problem built, and compiled for the code-generation variant), as ``bioplan plan`` pays it;
*warm*: the same structure solved again. The paper's PSO time (default budget) is measured in the
same child, for the issue's target "6-DOF human_optimal + bound within 3x the PSO time".

Variants:
- ``ipopt``: the project's default (IPOPT, MX graph calling the SX dynamics, not expanded).
- ``ipopt_expand``: the same expanded to SX before the solve (``expand=True``).
- ``ipopt_jit``: expanded, C code generated and compiled by the system compiler (``jit``).
- ``sqp_qrqp``: CasADi's ``sqpmethod`` with its sparse active-set QP solver ``qrqp``.
- ``sqp_hpipm``: ``sqpmethod`` with ``hpipm`` (no stage structure given: one dense stage).
- ``fatrop``: CasADi's ``fatrop`` with automatic structure detection (it needs stage-wise order).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

ROOT = Path(__file__).resolve().parents[1]
VARIANTS = ("ipopt", "ipopt_expand", "ipopt_jit", "sqp_qrqp", "sqp_hpipm", "fatrop")
CASES = (
    ("curtain_wall_6dof", 4.0, "peak_power"),
    ("curtain_wall_6dof", 4.0, "tau_sq"),
    ("human_arm_2dof", 12.0, "peak_power"),
    ("human_arm_2dof", 12.0, "peak_torque"),
)
#: A variant "gives the same optimum" within this fraction of IPOPT's objective [-].
SAME_OPTIMUM = 1e-3


class _Normalised:
    """A CasADi solver whose ``stats()["return_status"]`` reads ``Solve_Succeeded`` when the
    solver says ``success`` (sqpmethod and fatrop name their statuses differently)."""

    def __init__(self, solver: Any) -> None:
        self.solver = solver

    def __call__(self, **kwargs: Any) -> Any:
        return self.solver(**kwargs)

    def stats(self) -> dict[str, Any]:
        stats = dict(self.solver.stats())
        stats["raw_status"] = stats.get("return_status")
        if stats.get("success"):
            stats["return_status"] = "Solve_Succeeded"
        return stats


#: The numeric arguments of the NLP being built (fatrop needs to know its equality rows).
_LAST_ARGS: dict[str, Any] = {}


def _capture_args() -> None:
    """Wrap ``optimal._nlp`` so the builder sees the bounds of the constraints it builds for."""
    from app.planning import optimal

    original = optimal._nlp

    def nlp(problem: Any, warm: Any) -> Any:
        out = original(problem, warm)
        _LAST_ARGS["args"] = out[1]
        return out

    optimal._nlp = nlp  # type: ignore[assignment]


def _builder(variant: str) -> Any:
    """A replacement for ``optimal._solver``: the variant's solver, cached per structure."""
    import casadi as ca

    from app.planning import optimal

    cache: dict[Any, Any] = {}
    quiet_sqp = {
        "print_time": False,
        "print_header": False,
        "print_iteration": False,
        "print_status": False,
        "max_iter": 300,
        "error_on_fail": False,
    }

    def build(problem: Any, nlp: dict[str, Any]) -> Any:
        key = optimal._structure_key(problem)
        if key in cache:
            return cache[key]
        base = dict(optimal._IPOPT_OPTIONS)
        if variant == "ipopt":
            solver = ca.nlpsol("optimal", "ipopt", nlp, base)
        elif variant == "ipopt_expand":
            solver = ca.nlpsol("optimal", "ipopt", nlp, {**base, "expand": True})
        elif variant == "ipopt_jit":
            opts = {
                **base,
                "expand": True,
                "jit": True,
                "compiler": "shell",
                "jit_options": {"flags": ["-O1"], "verbose": False},
            }
            solver = ca.nlpsol("optimal", "ipopt", nlp, opts)
        elif variant in ("sqp_qrqp", "sqp_hpipm"):
            qp = "qrqp" if variant == "sqp_qrqp" else "hpipm"
            qp_opts: dict[str, Any] = {"error_on_fail": False}
            if qp == "qrqp":
                qp_opts["print_iter"] = False
                qp_opts["print_header"] = False
            solver = _Normalised(
                ca.nlpsol(
                    "optimal",
                    "sqpmethod",
                    nlp,
                    {**quiet_sqp, "expand": True, "qpsol": qp, "qpsol_options": qp_opts},
                )
            )
        elif variant == "fatrop":
            args = _LAST_ARGS["args"]
            equality = [bool(lo == hi) for lo, hi in zip(args["lbg"], args["ubg"], strict=True)]
            solver = _Normalised(
                ca.nlpsol(
                    "optimal",
                    "fatrop",
                    nlp,
                    {
                        "expand": True,
                        "structure_detection": "auto",
                        "equality": equality,
                        "print_time": False,
                        "fatrop.print_level": 0,
                    },
                )
            )
        else:
            raise ValueError(f"unknown variant {variant!r}: expected one of {VARIANTS}")
        cache[key] = solver
        return solver

    build.cache = cache  # type: ignore[attr-defined]
    return build


def _run_variant(variant: str, robots: list[str]) -> dict[str, Any]:
    """Every case and method with one variant (in this process)."""
    import numpy as np

    from app.planning import optimal
    from app.planning.evaluation import evaluate_trajectory
    from app.planning.methods import human_spec, objective_value
    from app.planning.planner import PlanTask, plan
    from app.planning.robots import load_robot

    build = _builder(variant)
    optimal._solver = build  # type: ignore[assignment]
    _capture_args()
    rows: list[dict[str, Any]] = []
    for robot_name, payload, objective in [c for c in CASES if c[0] in robots]:
        robot = load_robot(robot_name, payload=payload)
        task = PlanTask.default(robot)
        started = time.perf_counter()
        base = plan(robot, objective=objective, methods=("quintic", "paper"))
        pso_seconds = time.perf_counter() - started
        warm = base.methods["paper"].trajectory
        spec, _ = human_spec("peak", robot, task, base.template, np.radians(62.0))
        bound = optimal.HumanSpec("none", robot.elbow_joint)
        for name, human in (("human_optimal", spec), ("bound", bound)):
            row: dict[str, Any] = {
                "robot": robot_name, "payload": payload, "objective": objective, "method": name,
                "pso_seconds": pso_seconds,
            }  # fmt: skip
            times: list[float] = []
            try:
                for _ in range(2):  # cold (cache cleared), then warm
                    if not times:
                        build.cache.clear()
                    t0 = time.perf_counter()
                    res = optimal.solve_optimal(
                        robot, task.start, task.goal, 1.0, objective=objective, human=human,
                        warm_start=warm, warm_start_name="paper", explain=False,
                    )  # fmt: skip
                    times.append(time.perf_counter() - t0)
                ev = evaluate_trajectory(robot, res.trajectory, task)
                row.update(
                    status="ok", cold_seconds=times[0], warm_seconds=times[1],
                    iterations=res.solver.iterations,
                    objective_value=objective_value(robot, ev, objective),
                    violations=list(ev.violations),
                )  # fmt: skip
            except Exception as exc:  # a variant's failure is a result here
                row.update(status="failed", error=f"{type(exc).__name__}: {exc}"[:300])
            rows.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
    return {"variant": variant, "rows": rows}


def _child(variant: str, timeout: float, robots: str) -> dict[str, Any]:
    """One variant in a child process, in a temporary folder (the code-generation variant writes
    its C sources and objects to the working directory); on timeout its whole process group
    (the compiler too) is killed."""
    import signal
    import tempfile

    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", variant, "--robots", robots]
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="bioplan-solvers-") as tmp:
        proc = subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp,
            env={**os.environ, "PYTHONPATH": str(ROOT)}, start_new_session=True,
        )  # fmt: skip
        try:
            stdout, stderr = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            return {"variant": variant, "error": f"timed out after {timeout:g} s", "rows": []}
    if proc.returncode != 0:
        return {"variant": variant, "error": stderr[-600:], "rows": []}
    out: dict[str, Any] = json.loads(stdout.strip().splitlines()[-1])
    out["wall_seconds"] = time.perf_counter() - started
    return out


def _table(results: list[dict[str, Any]]) -> str:
    ref: dict[tuple[str, str, str], float] = {}
    for res in results:
        if res["variant"] == "ipopt":
            for r in res["rows"]:
                if r["status"] == "ok":
                    ref[(r["robot"], r["objective"], r["method"])] = r["objective_value"]
    lines = [
        "variant | robot | objective | method | cold s | warm s | iters | objective | vs ipopt"
    ]
    for res in results:
        if res.get("error"):
            lines.append(f"{res['variant']} | failed: {res['error'].strip().splitlines()[-1]}")
        for r in res["rows"]:
            head = f"{res['variant']} | {r['robot']} | {r['objective']} | {r['method']}"
            if r["status"] != "ok":
                lines.append(f"{head} | failed: {r['error']}")
                continue
            key = (r["robot"], r["objective"], r["method"])
            diff = ""
            if key in ref:
                rel = (r["objective_value"] - ref[key]) / abs(ref[key])
                r["vs_ipopt"] = rel
                diff = f"{100 * rel:+.3f} %" + ("" if abs(rel) <= SAME_OPTIMUM else " (differs)")
            lines.append(
                f"{head} | {r['cold_seconds']:.2f} | {r['warm_seconds']:.2f} | {r['iterations']} | "
                f"{r['objective_value']:.6g} | {diff}"
            )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--timeout", type=float, default=900.0, help="per variant [s]")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--out", default=None, help="also write the JSON here")
    parser.add_argument(
        "--robots", default="curtain_wall_6dof,human_arm_2dof", help="comma-separated robots"
    )
    args = parser.parse_args()
    if args.child:
        print(json.dumps(_run_variant(args.child, args.robots.split(","))))
        return
    results = [_child(v, args.timeout, args.robots) for v in args.variants.split(",")]
    text = _table(results)
    payload = json.dumps({"same_optimum": SAME_OPTIMUM, "results": results}, indent=1)
    if args.out:
        Path(args.out).write_text(payload, encoding="utf-8")
    print(payload)
    print(text)


if __name__ == "__main__":
    main()
