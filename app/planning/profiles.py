"""Point-to-point joint trajectories on a time grid."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Trajectory:
    """A joint-space trajectory sampled on a uniform time grid.

    Attributes:
        t: (T,) sample times [s], starting at 0.
        q: (T, n) joint positions [rad].
        qd: (T, n) joint velocities [rad/s].
        qdd: (T, n) joint accelerations [rad/s^2].
        jerk: (T, n) joint jerks [rad/s^3].
        name: profile name (e.g. ``"quintic"``, ``"bio_optimized"``).
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    qdd: NDArray[np.float64]
    jerk: NDArray[np.float64]
    name: str = ""

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def n_joints(self) -> int:
        return int(self.q.shape[1])
