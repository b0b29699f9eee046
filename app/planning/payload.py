"""A robot's payload and the error of robot models (kept apart from ``Robot``, so that the
dynamics, which takes a payload, does not depend on the robot package).

``Payload`` is a rigid body fixed to a robot's payload body; ``RobotError`` says what about a
robot model cannot be loaded or used. Both are re-exported by ``app.planning.robots``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.errors import BioPlanError

__all__ = ["Payload", "RobotError"]


class RobotError(BioPlanError):
    """A robot cannot be loaded or used; one-line message: what, which file, what was expected."""


def _frozen(values: ArrayLike, shape: tuple[int, ...], what: str) -> NDArray[np.float64]:
    array = np.array(values, dtype=np.float64)
    if array.shape != shape:
        raise RobotError(f"{what} has shape {array.shape}: expected {shape}")
    if not np.all(np.isfinite(array)):
        raise RobotError(f"{what} contains NaN or inf: expected finite values")
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class Payload:
    """A rigid payload fixed to the payload body (a dumbbell in the hand, a panel at the flange).

    Attributes:
        mass: payload mass [kg] (>= 0).
        com: (3,) centre of mass in the payload body's frame [m].
        inertia: (3, 3) inertia about the centre of mass, payload body's axes [kg m^2]
            (zeros for a point mass).
        size: (3,) box extents for display [m] (zeros for a point mass).
    """

    mass: float
    com: NDArray[np.float64]
    inertia: NDArray[np.float64]
    size: NDArray[np.float64]

    def __post_init__(self) -> None:
        mass = float(self.mass)
        if not np.isfinite(mass) or mass < 0.0:
            raise RobotError(f"payload mass is {self.mass}: expected a finite mass >= 0 kg")
        object.__setattr__(self, "mass", mass)
        object.__setattr__(self, "com", _frozen(self.com, (3,), "payload com"))
        inertia = _frozen(self.inertia, (3, 3), "payload inertia")
        if not np.allclose(
            inertia, inertia.T, rtol=0.0, atol=1e-12 * (1.0 + np.abs(inertia).max())
        ):
            raise RobotError("payload inertia is not symmetric: expected a symmetric 3x3 tensor")
        if np.linalg.eigvalsh(inertia).min() < -1e-12 * (1.0 + np.abs(inertia).max()):
            raise RobotError("payload inertia is not positive semi-definite: expected I >= 0")
        object.__setattr__(self, "inertia", inertia)
        size = _frozen(self.size, (3,), "payload size")
        if np.any(size < 0.0):
            raise RobotError(f"payload size is {size.tolist()}: expected extents >= 0 m")
        object.__setattr__(self, "size", size)

    @classmethod
    def point(cls, mass: float, com: ArrayLike = (0.0, 0.0, 0.0)) -> Payload:
        """A point mass at ``com`` (body frame) [kg, m]."""
        return cls(
            mass=mass, com=np.asarray(com, float), inertia=np.zeros((3, 3)), size=np.zeros(3)
        )

    @classmethod
    def box(cls, mass: float, size: ArrayLike, com: ArrayLike = (0.0, 0.0, 0.0)) -> Payload:
        """A uniform box of extents ``size`` (x, y, z) [m] along the body's axes, centred at com."""
        a, b, c = np.asarray(size, dtype=np.float64)
        inertia = float(mass) / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
        return cls(mass=mass, com=np.asarray(com, float), inertia=inertia, size=np.array([a, b, c]))

    def with_mass(self, mass: float) -> Payload:
        """The same payload shape with another mass; the inertia scales with the mass."""
        if not np.isfinite(mass) or mass < 0.0:
            raise RobotError(f"payload mass is {mass}: expected a finite mass >= 0 kg")
        if np.all(self.size > 0.0):
            return Payload.box(mass, self.size, self.com)
        inertia = self.inertia * (float(mass) / self.mass) if self.mass > 0.0 else np.zeros((3, 3))
        return Payload(mass=mass, com=self.com, inertia=inertia, size=self.size)
