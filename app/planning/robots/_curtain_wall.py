"""The curtain-wall installation robot (``curtain_wall_6dof``).

A pedestal-mounted 6-axis arm: J1 base yaw (z) on a 0.9 m column, J2 shoulder pitch 1.3 m above
the floor and 0.15 m in front of the J1 axis, J3 elbow pitch, J4-J6 roll-pitch-roll wrist, and a
vacuum gripper holding a glass/aluminium panel. Upper arm 0.495 m and forearm 0.45 m as in the
paper. At q = 0 the arm hangs straight down like a relaxed human arm; J2, J3 and J5 turn about
-y, so positive angles swing the hand forward and up exactly as human shoulder and elbow
flexion do (the default task J2 0 -> 20 deg, J3 0 -> 150 deg is a curl).

Link masses and inertias are assumptions (aluminium castings + motors, modelled as solid
cylinders for the inertia); motors and gearboxes are assumed typical of AC servo motors with
harmonic-drive (strain-wave) gearboxes. Every number is listed with its source in
``curtain_wall_parameters()``.
"""

from __future__ import annotations

import math

from app.planning.energy import MotorModel
from app.planning.robots._chain import ChainLink, ChainSpec, Visual
from app.planning.robots._table import parameter_row as _row

__all__ = ["curtain_wall_chain", "curtain_wall_motors", "curtain_wall_parameters"]

PAPER = "paper (Liu et al., SIAT): upper arm 0.495 m, forearm 0.45 m, 4 kg payload"
ASSUMED_LINK = (
    "assumed: aluminium link + motor, inertia of a solid cylinder "
    "(I_axial = m r^2/2, I_transverse = m (3 r^2 + L^2)/12)"
)
ASSUMED_LIMIT = "assumed, typical of 10-20 kg payload industrial arms"
ASSUMED_MOTOR = "assumed, typical of {cls} with a harmonic-drive (strain-wave) gearbox"
ASSUMED_REGEN = "assumed: servo drive with a regenerative DC bus recovering half of braking power"

_BLUE = (0.2, 0.4, 0.75, 1.0)
_GREY = (0.6, 0.6, 0.62, 1.0)
_DARK = (0.25, 0.25, 0.28, 1.0)

# name, joint, origin in parent [m], axis, mass [kg], com [m], cylinder (radius, length) [m] for
# the inertia, lower/upper [deg], velocity [rad/s], effort [Nm], motor class
_LINKS: tuple[
    tuple[
        str,
        str,
        tuple[float, float, float],
        tuple[float, float, float],
        float,
        tuple[float, float, float],
        tuple[float, float],
        tuple[float, float],
        float,
        float,
    ],
    ...,
] = (
    (
        "turret",
        "j1_base_yaw",
        (0.0, 0.0, 0.9),
        (0.0, 0.0, 1.0),
        15.0,
        (0.05, 0.0, 0.2),
        (0.1, 0.4),
        (-170.0, 170.0),
        2.5,
        200.0,
    ),
    (
        "upper_arm",
        "j2_shoulder_pitch",
        (0.15, 0.0, 0.4),
        (0.0, -1.0, 0.0),
        12.0,
        (0.0, 0.0, -0.22),
        (0.06, 0.495),
        (-90.0, 180.0),
        2.5,
        350.0,
    ),
    (
        "forearm",
        "j3_elbow_pitch",
        (0.0, 0.0, -0.495),
        (0.0, -1.0, 0.0),
        9.0,
        (0.0, 0.0, -0.18),
        (0.05, 0.45),
        (-10.0, 160.0),
        6.0,
        200.0,
    ),
    (
        "wrist_1",
        "j4_wrist_roll",
        (0.0, 0.0, -0.45),
        (0.0, 0.0, 1.0),
        2.5,
        (0.0, 0.0, -0.05),
        (0.045, 0.1),
        (-175.0, 175.0),
        7.0,
        40.0,
    ),
    (
        "wrist_2",
        "j5_wrist_pitch",
        (0.0, 0.0, -0.1),
        (0.0, -1.0, 0.0),
        2.0,
        (0.0, 0.0, -0.04),
        (0.04, 0.08),
        (-120.0, 120.0),
        7.0,
        40.0,
    ),
    (
        "flange",
        "j6_wrist_roll",
        (0.0, 0.0, -0.08),
        (0.0, 0.0, 1.0),
        1.5,
        (0.0, 0.0, -0.03),
        (0.06, 0.06),
        (-175.0, 175.0),
        7.0,
        25.0,
    ),
)

# Payload: a curtain-wall panel held by the vacuum gripper, its plane normal to the flange axis.
PAYLOAD_MASS = 4.0
PAYLOAD_SIZE = (0.5, 0.4, 0.02)
PAYLOAD_COM = (0.0, 0.0, -0.07)  # flange face 0.06 m below J6 + half the panel's thickness

# gear ratio, k_t [Nm/A], R [ohm], rotor inertia [kg m^2], viscous [Nm s/rad], Coulomb [Nm]
_MOTORS: tuple[tuple[float, float, float, float, float, float, str], ...] = (
    (160.0, 0.50, 0.90, 1.2e-4, 1.5, 4.0, "750 W AC servo motors"),
    (160.0, 0.50, 0.90, 1.2e-4, 1.5, 4.0, "750 W AC servo motors"),
    (100.0, 0.40, 1.50, 0.8e-4, 0.8, 2.5, "400 W AC servo motors"),
    (100.0, 0.20, 3.50, 0.2e-4, 0.2, 0.8, "100-200 W AC servo motors"),
    (100.0, 0.20, 3.50, 0.2e-4, 0.2, 0.8, "100-200 W AC servo motors"),
    (100.0, 0.20, 3.50, 0.2e-4, 0.2, 0.8, "100-200 W AC servo motors"),
)
REGEN_EFFICIENCY = 0.5

# Joint controller limits per joint J1..J6: acceleration [rad/s^2], jerk [rad/s^3].
_CONTROLLER_LIMITS: tuple[tuple[float, float], ...] = (
    (10.0, 100.0),
    (12.0, 120.0),
    (25.0, 250.0),
    (30.0, 300.0),
    (30.0, 300.0),
    (30.0, 300.0),
)
ASSUMED_CONTROLLER = (
    "assumed, of the order of the axis acceleration and jerk limits of 10-20 kg payload "
    "industrial arm controllers; J3 reaches the default 150 deg curl in 0.76 s at these limits"
)


def _cylinder_inertia(mass: float, radius: float, length: float) -> tuple[float, float, float]:
    transverse = mass * (3.0 * radius**2 + length**2) / 12.0
    return (round(transverse, 9), round(transverse, 9), round(mass * radius**2 / 2.0, 9))


def curtain_wall_motors() -> tuple[MotorModel, ...]:
    """One motor + gearbox per joint, J1..J6 (joint-side friction)."""
    return tuple(
        MotorModel(
            gear_ratio=gear,
            torque_constant=k_t,
            winding_resistance=resistance,
            rotor_inertia=rotor,
            viscous_friction=viscous,
            coulomb_friction=coulomb,
            regen_efficiency=REGEN_EFFICIENCY,
        )
        for gear, k_t, resistance, rotor, viscous, coulomb, _ in _MOTORS
    )


def curtain_wall_chain(*, comment: str = "") -> ChainSpec:
    """The URDF/MJCF description (no payload, armature or friction: applied in code)."""
    links = []
    for index, (link, joint, origin, axis, mass, com, cyl, lim, velocity, effort) in enumerate(
        _LINKS
    ):
        radius, length = cyl
        ixx, iyy, izz = _cylinder_inertia(mass, radius, length)
        colour = _BLUE if index in (1, 2) else _GREY
        if link == "turret":
            visuals: tuple[Visual, ...] = (
                Visual((0.0, 0.0, 0.0), (0.0, 0.0, 0.4), 0.1, colour),
                Visual((0.0, 0.0, 0.4), (0.15, 0.0, 0.4), 0.08, colour),
            )
        else:
            next_origin = _LINKS[index + 1][2] if index + 1 < len(_LINKS) else (0.0, 0.0, -0.06)
            visuals = (Visual((0.0, 0.0, 0.0), next_origin, radius, colour),)
        links.append(
            ChainLink(
                joint=joint,
                link=link,
                origin=origin,
                axis=axis,
                lower=round(math.radians(lim[0]), 6),
                upper=round(math.radians(lim[1]), 6),
                velocity=velocity,
                effort=effort,
                mass=mass,
                com=com,
                inertia=(ixx, iyy, izz, 0.0, 0.0, 0.0),
                visuals=visuals,
            )
        )
    pedestal = (
        # 0.08 m column: the hanging arm (its axis 0.15 m from J1's) clears it by 10 mm; a
        # thicker one would put the default start pose in contact (app.planning.safety).
        Visual((0.0, 0.0, 0.0), (0.0, 0.0, 0.9), 0.08, _DARK),
        Visual((0.0, 0.0, 0.02), (0.0, 0.0, 0.02), 0.0, _DARK, box=(0.6, 0.6, 0.04)),
    )
    return ChainSpec(
        name="curtain_wall_6dof",
        base="pedestal",
        links=tuple(links),
        base_visuals=pedestal,
        comment=comment,
    )


def _link_rows() -> list[dict[str, object]]:
    """Per link: lengths, joint origin, mass, centre of mass, inertia and the joint's limits."""
    rows: list[dict[str, object]] = []
    for link, joint, origin, _axis, mass, com, cyl, lim, velocity, effort in _LINKS:
        ixx, iyy, izz = _cylinder_inertia(mass, *cyl)
        length_source = PAPER if link in ("upper_arm", "forearm") else "assumed"
        if link in ("upper_arm", "forearm"):
            rows.append(_row(f"{link}.length", cyl[1], "m", length_source))
        origin_source = length_source if link in ("forearm", "wrist_1") else "assumed"
        velocity_note = (
            "; J3 allows the default 150 deg curl in 1.0 s (quintic peak 4.9 rad/s)"
            if joint == "j3_elbow_pitch"
            else ""
        )
        rows += [
            _row(f"{joint}.origin", list(origin), "m", origin_source),
            _row(f"{link}.mass", mass, "kg", ASSUMED_LINK),
            _row(f"{link}.com", list(com), "m", ASSUMED_LINK),
            _row(f"{link}.inertia_xx", ixx, "kg m^2", ASSUMED_LINK),
            _row(f"{link}.inertia_yy", iyy, "kg m^2", ASSUMED_LINK),
            _row(f"{link}.inertia_zz", izz, "kg m^2", ASSUMED_LINK),
            _row(f"{joint}.lower", round(math.radians(lim[0]), 6), "rad", ASSUMED_LIMIT),
            _row(f"{joint}.upper", round(math.radians(lim[1]), 6), "rad", ASSUMED_LIMIT),
            _row(f"{joint}.velocity", velocity, "rad/s", ASSUMED_LIMIT + velocity_note),
            _row(
                f"{joint}.effort",
                effort,
                "Nm",
                "assumed: margin over the default curl with 4 kg in 1.0 s, short of it in 0.3 s",
            ),
        ]
    return rows


def _motor_rows() -> list[dict[str, object]]:
    """Per joint: the motor, gearbox and friction of :func:`curtain_wall_motors`."""
    rows: list[dict[str, object]] = []
    for (gear, k_t, resistance, rotor, viscous, coulomb, cls), (_, joint, *_rest) in zip(
        _MOTORS, _LINKS, strict=True
    ):
        source = ASSUMED_MOTOR.format(cls=cls)
        motor = f"{joint}.motor"
        rows += [
            _row(f"{motor}.gear_ratio", gear, "1", source),
            _row(f"{motor}.torque_constant", k_t, "Nm/A", source),
            _row(f"{motor}.winding_resistance", resistance, "ohm", source),
            _row(f"{motor}.rotor_inertia", rotor, "kg m^2", source + " (rotor + wave generator)"),
            _row(f"{motor}.viscous_friction", viscous, "Nm s/rad", source + " (joint side)"),
            _row(f"{motor}.coulomb_friction", coulomb, "Nm", source + " (joint side)"),
            _row(f"{motor}.regen_efficiency", REGEN_EFFICIENCY, "1", ASSUMED_REGEN),
        ]
    return rows


def curtain_wall_parameters() -> tuple[dict[str, object], ...]:
    """The parameter table: one ``{name, value, unit, source}`` row per number of the robot
    (pedestal, links, joint limits, motors, controller limits, payload)."""
    rows = [
        _row(
            "pedestal.height",
            0.9,
            "m",
            "assumed: column putting the shoulder 1.3 m above the floor",
        ),
        _row(
            "turret.shoulder_offset",
            [0.15, 0.0, 0.4],
            "m",
            "assumed: J2 axis 0.15 m in front of the J1 axis, 0.4 m above the column",
        ),
        *_link_rows(),
        *_motor_rows(),
    ]
    for (_, joint, *_rest), (acceleration, jerk) in zip(_LINKS, _CONTROLLER_LIMITS, strict=True):
        rows += [
            _row(f"{joint}.acceleration", acceleration, "rad/s^2", ASSUMED_CONTROLLER),
            _row(f"{joint}.jerk", jerk, "rad/s^3", ASSUMED_CONTROLLER),
        ]
    rows += [
        _row("payload.mass", PAYLOAD_MASS, "kg", PAPER + " (default; configurable)"),
        _row(
            "payload.size", list(PAYLOAD_SIZE), "m", "assumed: thin curtain-wall panel, uniform box"
        ),
        _row(
            "payload.com",
            list(PAYLOAD_COM),
            "m",
            "assumed: panel held against the vacuum gripper, flange frame",
        ),
    ]
    return tuple(rows)
