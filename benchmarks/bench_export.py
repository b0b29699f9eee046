"""Export of a 1 s plan at 1 kHz in every format (target: each under 0.2 s).

Run:  .venv/bin/python benchmarks/bench_export.py [--repeats 7] [--json]

A plan of ``curtain_wall_6dof`` (6 joints, 1 s) is made once; then, in one warm process, each
format is exported from the plan's motion at 1000 Hz (URScript at 500 Hz, the fastest rate a
Universal Robots controller servos at) and timed end to end:
resampling the method's knots, inverse dynamics at every sample, the robot check and the
writer; median of ``--repeats``. ``export from JSON`` times ``export_result`` on the saved
``--json`` result (JSON parse of the motion block, robot rebuilt from its spec, CSV written).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

TARGET_S = 0.2


def timed(fn: Any, repeats: int) -> tuple[float, Any]:
    """Median wall time [s] of ``fn()`` and its last result."""
    times, out = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()

    from app.planning import load_robot, plan
    from app.planning.export import FORMATS, export_bytes, export_result, plan_motion

    robot = load_robot("curtain_wall_6dof")
    result = plan(robot, duration=1.0, particles=20, iterations=20, seed=0)
    motion = plan_motion(result, robot)
    rows: dict[str, dict[str, Any]] = {}
    for name in FORMATS:
        rate = 500.0 if name == "script" else 1000.0
        # This 6-joint arm is not a UR: its URScript is written only when forced.
        seconds, data = timed(
            lambda n=name, r=rate: export_bytes(
                motion, n, rate=r, robot=robot, force=n == "script"
            ),
            args.repeats,
        )
        rows[name] = {"rate_hz": rate, "seconds": seconds, "bytes": len(data)}
    saved = json.loads(json.dumps({"motion": motion.to_dict()}))
    seconds, data = timed(lambda: export_result(saved, "csv", rate=1000.0), args.repeats)
    rows["csv from saved JSON"] = {"rate_hz": 1000.0, "seconds": seconds, "bytes": len(data)}
    out = {
        "load_average_1min": os.getloadavg()[0],
        "repeats": args.repeats,
        "target_s": TARGET_S,
        "formats": rows,
        "all_under_target": all(r["seconds"] < TARGET_S for r in rows.values()),
    }
    if args.json:
        print(json.dumps(out))
    else:
        print(f"load average {out['load_average_1min']:.2f}; median of {args.repeats}")
        for name, row in rows.items():
            print(
                f"{name:<20} {row['rate_hz']:>6g} Hz  {1000 * row['seconds']:7.1f} ms  "
                f"{row['bytes']:>9} bytes"
            )
        print(f"all under {TARGET_S} s: {out['all_under_target']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
