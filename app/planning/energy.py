"""Energy metrics of a joint trajectory, their physical floors, and the motor model."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class MotorModel:
    """A joint's motor and gearbox, seen from the joint side.

    Attributes:
        gear_ratio: motor turns per joint turn (N, dimensionless, >= 1).
        torque_constant: motor torque constant k_t [Nm/A].
        winding_resistance: motor winding resistance R [ohm].
        rotor_inertia: rotor (+ gearbox input) inertia at the motor shaft [kg m^2]; the joint
            sees N^2 times this as armature.
        viscous_friction: viscous friction at the joint [Nm s/rad].
        coulomb_friction: Coulomb friction at the joint [Nm].
        regen_efficiency: fraction of negative (generated) electrical power recovered, in [0, 1].
    """

    gear_ratio: float
    torque_constant: float
    winding_resistance: float
    rotor_inertia: float
    viscous_friction: float
    coulomb_friction: float
    regen_efficiency: float = 0.0

    @property
    def armature(self) -> float:
        """Reflected rotor inertia at the joint, N^2 J_m [kg m^2]."""
        return self.gear_ratio**2 * self.rotor_inertia
