"""Trade-offs (issue 26): a 9-point Pareto front against one converged bound solve.

Run: ``.venv/bin/python benchmarks/front.py [--robot curtain_wall_6dof] [--objectives A,B]
[--points 9] [--json]``.

Side by side in one run, each cold (the IPOPT solver cache cleared first, so both pay for
building their problems): ``plan(..., methods=["quintic", "bound"], converge=True)`` on A (one
converged bound solve: its multistart, certificate and mesh refinement), then
``pareto_front(objectives=A,B, points=9)`` (both ends converged, seven epsilon-constraint points
each warm-started from its neighbour and refined from half its neighbour's mesh). Target: the
front within 10x the bound solve, in CPU time of this process (everything runs in it, on one
thread; on the shared 2-core machine the wall time also counts the other jobs' load, which
changes between the two measurements, so it is reported beside). The front's points are printed
with their convergence.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

TARGET_RATIO = 10.0


def _cold() -> None:
    from app.planning import optimal

    optimal._SOLVERS.clear()


def run(robot_name: str, payload: float, objectives: str, points: int) -> dict[str, Any]:
    from app.planning.front import pareto_front
    from app.planning.planner import plan
    from app.planning.robots import load_robot

    a, b = objectives.split(",")
    robot = load_robot(robot_name, payload=payload)
    _cold()
    started, cpu = time.perf_counter(), time.process_time()
    single = plan(robot, duration=1.0, objective=a, methods=["quintic", "bound"], converge=True)
    bound_s, bound_cpu = time.perf_counter() - started, time.process_time() - cpu
    conv = single.methods["bound"].solver["convergence"]  # type: ignore[index]
    _cold()
    started, cpu = time.perf_counter(), time.process_time()
    front = pareto_front(robot, objectives=objectives, duration=1.0, points=points)
    front_s, front_cpu = time.perf_counter() - started, time.process_time() - cpu
    d = front.to_dict()
    return {
        "robot": robot_name,
        "payload": payload,
        "objectives": [a, b],
        "points": len(d["points"]),
        "bound_seconds": bound_s,
        "bound_objective": single.objective_values["bound"],
        "bound_convergence": [s["n_intervals"] for s in conv["sequence"]],
        "front_seconds": front_s,
        "front_solves": d["solves"],
        "bound_cpu_seconds": bound_cpu,
        "front_cpu_seconds": front_cpu,
        "ratio": front_cpu / bound_cpu,
        "wall_ratio": front_s / bound_s,
        "target_ratio": TARGET_RATIO,
        "end_vs_bound_pct": 100 * (d["points"][0][a] / single.objective_values["bound"] - 1),
        "knee": d["knee"],
        "front": [
            {
                "id": p["id"],
                a: p[a],
                b: p[b],
                "final_intervals": p["convergence"]["final_intervals"],
                "relative_change": p["convergence"]["relative_change"],
                "peak_torques": p["peak_torques"],
            }
            for p in d["points"]
        ],
        "dropped": d["dropped"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robot", default="curtain_wall_6dof")
    parser.add_argument("--payload", type=float, default=4.0)
    parser.add_argument("--objectives", default="tau_sq,jerk")
    parser.add_argument("--points", type=int, default=9)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    out = run(args.robot, args.payload, args.objectives, args.points)
    if args.json:
        print(json.dumps(out, indent=2))
        return
    a, b = out["objectives"]
    print(
        f"{out['robot']} {out['payload']:g} kg, 1 s: front {a},{b} of {out['points']} points "
        f"{out['front_cpu_seconds']:.1f} s CPU ({out['front_solves']} solves) vs one converged "
        f"bound on {a} {out['bound_cpu_seconds']:.1f} s CPU (meshes {out['bound_convergence']}): "
        f"{out['ratio']:.1f}x (target <= {TARGET_RATIO:g}x; wall {out['wall_ratio']:.1f}x); the "
        f"{a} end is "
        f"{out['end_vs_bound_pct']:+.3f} % from the bound"
    )
    for p in out["front"]:
        change = p["relative_change"]
        print(
            f"  {p['id']}: {a} {p[a]:.6g}  {b} {p[b]:.6g}  mesh {p['final_intervals']}"
            f" (last change {100 * change:.3f} %)" + ("  knee" if p["id"] == out["knee"] else "")
        )


if __name__ == "__main__":
    main()
