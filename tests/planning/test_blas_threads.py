"""IPOPT's linear solver runs casadi's OpenBLAS on one thread (:mod:`app.planning.blas_threads`),
unless the user set a thread count. Each case in a fresh interpreter: the setting is per process
and must be made before MUMPS first runs."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

_SOLVE_THEN_COUNT = """
import ctypes, os, casadi
from app.planning.evaluation import PlanTask
from app.planning.optimal import HumanSpec, solve_optimal
from app.planning.robots import load_robot
arm = load_robot("human_arm_2dof")
task = PlanTask.default(arm)
solve_optimal(arm, task.start, task.goal, 1.0, objective="tau_sq",
              human=HumanSpec("none", arm.elbow_joint), n_intervals=16)
lib = ctypes.CDLL(os.path.join(os.path.dirname(casadi.__file__), "libcasadi-tp-openblas.so.0"))
print(lib.openblas_get_num_threads())
"""


def _threads_after_a_solve(**env: str) -> int:
    clean = {
        k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")
    }
    out = subprocess.run(
        [sys.executable, "-c", _SOLVE_THEN_COUNT], env={**clean, **env},
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return int(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: OpenBLAS starts one thread anyway")
def test_one_blas_thread_unless_the_user_chose() -> None:
    assert _threads_after_a_solve() == 1
    assert _threads_after_a_solve(OPENBLAS_NUM_THREADS="2") == 2
    assert _threads_after_a_solve(OMP_NUM_THREADS="2") == 2
