"""Run every benchmark in turn (``make bench``); each prints its own results and command.

Benchmarks share the machine with nothing else only if you let them: run this on an idle
machine, and copy the medians into ``benchmarks/RESULTS.md`` with the load average printed.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
SCRIPTS = (
    ["bench_dynamics.py"],
    ["bench_pso.py"],
    ["bench_planner.py"],
    ["bench_optimal.py"],
    ["bench_read.py"],
    ["bench_emg.py"],
    ["bench_analysis.py"],
    ["bench_cohort.py"],
    ["bench_pose.py"],
    ["bench_simulation.py"],
    ["bench_api.py"],
    ["bench_frontend.py"],
)


def main() -> int:
    failed = []
    for script in SCRIPTS:
        cmd = [sys.executable, str(HERE / script[0]), *script[1:], *sys.argv[1:]]
        print(f"\n$ {' '.join(cmd)}  (load average {os.getloadavg()[0]:.2f})", flush=True)
        if subprocess.run(cmd, cwd=HERE.parent).returncode != 0:
            failed.append(script[0])
    if failed:
        print(f"\nfailed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
