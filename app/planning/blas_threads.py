"""One BLAS thread for IPOPT's linear solver.

MUMPS, IPOPT's linear solver in the casadi wheel, calls the OpenBLAS bundled with casadi, which
starts a thread per core. On the optimal control's KKT systems (sparse, a few thousand rows per
block) the extra threads only spin: the human arm's converged peak-power plan took 24.9 s of CPU
for 15.7 s of wall time, and 15.2 s of CPU in the same wall time with one thread
(benchmarks/RESULTS.md, "One BLAS thread"). Spinning threads take the CPU from everything else
on the machine: the other plans of a sweep or a service, the other tests of a suite.

:func:`single_threaded_casadi_blas` sets that OpenBLAS to one thread unless the user chose a
count (``OPENBLAS_NUM_THREADS`` or ``OMP_NUM_THREADS`` in the environment). numpy's own BLAS is
a different library and is left alone.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import os

logger = logging.getLogger("bioplan.planning")

#: casadi's bundled OpenBLAS (the name MUMPS links against).
_CASADI_OPENBLAS = "libcasadi-tp-openblas.so.0"
#: Environment variables with which a user sets OpenBLAS's thread count themselves.
_USER_SETTINGS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")


@functools.cache
def single_threaded_casadi_blas() -> bool:
    """Set casadi's OpenBLAS to one thread (once per process); True if it was set.

    Loading the library by its path first makes it the very instance MUMPS binds to later (the
    dynamic loader shares a library by its name). Nothing happens where the library is absent
    (another platform or casadi build) or the user set a thread count.
    """
    if any(os.environ.get(name) for name in _USER_SETTINGS):
        return False
    import casadi

    path = os.path.join(os.path.dirname(casadi.__file__), _CASADI_OPENBLAS)
    try:
        ctypes.CDLL(path).openblas_set_num_threads(1)
    except (OSError, AttributeError) as exc:
        logger.debug("casadi's OpenBLAS thread count left as is (%s)", exc)
        return False
    return True
