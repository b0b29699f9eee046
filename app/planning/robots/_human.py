"""The human arm (``human_arm_2dof``): segment parameters from de Leva (1996), scaled to a subject.

Sagittal plane, x forward, y to the subject's left, z up, shoulder at the origin. Link 1 is the
upper arm (shoulder joint centre to elbow joint centre); link 2 lumps forearm and hand
(elbow to the grip). q1 = shoulder flexion, 0 = arm hanging, positive forward/up; q2 = elbow
flexion, 0 = straight. Both joints rotate about -y so that positive angles lift the hand forward:
elbow = l1 (sin q1, 0, -cos q1).

De Leva's radii of gyration are about the segment's sagittal (antero-posterior, x), transverse
(medio-lateral, y) and longitudinal (z) axes; flexion in the sagittal plane turns about y and
therefore uses the *transverse* radius.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from app.planning.robots._chain import ChainLink, ChainSpec, Visual
from app.planning.robots._table import parameter_row as _row
from app.planning.robots._types import RobotError

__all__ = [
    "DEFAULT_SUBJECT",
    "DE_LEVA_SOURCE",
    "HumanArmSegments",
    "human_arm_chain",
    "human_arm_parameters",
    "human_arm_segments",
    "segment_masses",
]

DE_LEVA_SOURCE = (
    "de Leva P (1996) Adjustments to Zatsiorsky-Seluyanov's segment inertia parameters, "
    "J Biomech 29(9):1223-1230"
)
# Table 4 lists, per sex, the mean segment lengths and the samples' stature with the relative
# masses, centre-of-mass positions and radii of gyration. Every value below was cross-checked
# against an independent public tabulation of that table (all 38 agree).
_TABLE4 = DE_LEVA_SOURCE + ", Table 4"

DEFAULT_SUBJECT = {"body_mass": 75.0, "body_height": 1.75, "sex": "male"}

# Reference stature of the samples whose mean segment lengths de Leva lists [m].
_STATURE = {"male": 1.741, "female": 1.735}

# Per segment: relative mass, mean length [m], CM from the proximal end (fraction of length),
# radii of gyration about sagittal / transverse / longitudinal axes (fractions of length).
# Upper arm SJC-EJC, forearm EJC-WJC, hand WJC-MET3.
_ARM: dict[str, dict[str, tuple[float, float, float, float, float, float]]] = {
    "male": {
        "upper_arm": (0.0271, 0.2817, 0.5772, 0.285, 0.269, 0.158),
        "forearm": (0.0162, 0.2689, 0.4574, 0.276, 0.265, 0.121),
        "hand": (0.0061, 0.0862, 0.7900, 0.628, 0.513, 0.401),
    },
    "female": {
        "upper_arm": (0.0255, 0.2751, 0.5754, 0.278, 0.260, 0.148),
        "forearm": (0.0138, 0.2643, 0.4559, 0.261, 0.257, 0.094),
        "hand": (0.0056, 0.0780, 0.7474, 0.531, 0.454, 0.335),
    },
}

# Relative masses of all segments of de Leva's Table 4 (head, whole trunk, and one side of the
# limbs); used to check that the table adds up to the body mass.
_ALL_MASSES: dict[str, dict[str, float]] = {
    "male": {
        "head": 0.0694,
        "trunk": 0.4346,
        "upper_arm": 0.0271,
        "forearm": 0.0162,
        "hand": 0.0061,
        "thigh": 0.1416,
        "shank": 0.0433,
        "foot": 0.0137,
    },
    "female": {
        "head": 0.0668,
        "trunk": 0.4257,
        "upper_arm": 0.0255,
        "forearm": 0.0138,
        "hand": 0.0056,
        "thigh": 0.1478,
        "shank": 0.0481,
        "foot": 0.0129,
    },
}
_BILATERAL = ("upper_arm", "forearm", "hand", "thigh", "shank", "foot")

# Joint limits: assumed typical adult ranges of motion and torque capacity (order of the peak
# isometric flexion torques of adult men), not subject-specific.
_LIMITS = {
    "shoulder_flexion": (math.radians(-60.0), math.radians(180.0), 10.0, 100.0),
    "elbow_flexion": (0.0, math.radians(160.0), 15.0, 80.0),
}
# Acceleration [rad/s^2] and jerk [rad/s^3] limits: assumed, of the order of the peak elbow
# and shoulder accelerations of fast voluntary arm movements (the default 150 deg curl in 1 s
# needs 15 rad/s^2 as a quintic).
_CONTROLLER_LIMITS = {"shoulder_flexion": (30.0, 300.0), "elbow_flexion": (40.0, 400.0)}
_CONTROLLER_SOURCE = (
    "assumed: of the order of peak accelerations of fast voluntary arm movements; used by the "
    "jerk-limited baseline only"
)
_LIMIT_SOURCE = (
    "assumed: typical adult range of motion; torque of the order of peak isometric flexion "
    "torque of adult men"
)


def _sig(x: float) -> float:
    # Six significant digits: far below the tables' own uncertainty, and short exact numbers
    # in the generated files (the closed-form model reads the very same values).
    return float(f"{x:.6g}")


def _check_subject(body_mass: float, body_height: float, sex: str) -> None:
    if sex not in _ARM:
        raise RobotError(f"sex is '{sex}': expected 'male' or 'female'")
    if not (math.isfinite(body_mass) and 20.0 <= body_mass <= 250.0):
        raise RobotError(f"body_mass is {body_mass}: expected 20-250 kg")
    if not (math.isfinite(body_height) and 1.0 <= body_height <= 2.5):
        raise RobotError(f"body_height is {body_height}: expected 1.0-2.5 m")


def segment_masses(body_mass: float, *, sex: str = "male") -> dict[str, float]:
    """All body-segment masses of de Leva's table for one subject, both sides of the limbs.

    Args:
        body_mass: total body mass [kg].
        sex: "male" or "female".

    Returns:
        Segment name (``left_forearm``, ``head``, ...) -> mass [kg]; the values sum to
        ``body_mass`` up to the table's rounding (0.01 %).
    """
    _check_subject(body_mass, 1.75, sex)
    masses: dict[str, float] = {}
    for name, fraction in _ALL_MASSES[sex].items():
        if name in _BILATERAL:
            masses[f"left_{name}"] = fraction * body_mass
            masses[f"right_{name}"] = fraction * body_mass
        else:
            masses[name] = fraction * body_mass
    return masses


@dataclass(frozen=True)
class HumanArmSegments:
    """Planar 2-link arm parameters of one subject (all rounded to 6 significant digits).

    Attributes:
        l1: shoulder-to-elbow length [m].
        lc1: shoulder to upper-arm centre of mass [m].
        m1: upper-arm mass [kg].
        i1: (3,) upper-arm inertia about its centre of mass, (x, y, z) axes [kg m^2].
        l2: elbow to grip (forearm length + hand CM distance; the grip is taken at the hand's
            centre of mass) [m].
        lc2: elbow to the forearm+hand centre of mass [m].
        m2: forearm + hand mass [kg].
        i2: (3,) forearm+hand inertia about its centre of mass [kg m^2].
        forearm_length: elbow to wrist [m] (for display).
    """

    l1: float
    lc1: float
    m1: float
    i1: tuple[float, float, float]
    l2: float
    lc2: float
    m2: float
    i2: tuple[float, float, float]
    forearm_length: float


def _segment(sex: str, name: str, body_mass: float, scale: float) -> tuple[float, ...]:
    """(mass, length, cm distance, Ixx, Iyy, Izz) of one segment, unrounded."""
    fraction, length, cm, r_sag, r_trans, r_long = _ARM[sex][name]
    mass = fraction * body_mass
    length *= scale
    return (
        mass,
        length,
        cm * length,
        mass * (r_sag * length) ** 2,
        mass * (r_trans * length) ** 2,
        mass * (r_long * length) ** 2,
    )


def human_arm_segments(
    body_mass: float = 75.0, body_height: float = 1.75, *, sex: str = "male"
) -> HumanArmSegments:
    """De Leva's upper arm and forearm + hand scaled to a subject.

    Masses scale with body mass, lengths with body height over the table's reference stature,
    inertias as m (r L)^2. Forearm and hand are combined by the parallel-axis theorem (both
    centres of mass lie on the segment's long axis).

    Args:
        body_mass: total body mass [kg].
        body_height: stature [m].
        sex: "male" or "female".
    """
    _check_subject(body_mass, body_height, sex)
    scale = body_height / _STATURE[sex]
    m1, l1, c1, ix1, iy1, iz1 = _segment(sex, "upper_arm", body_mass, scale)
    mf, lf, cf, ixf, iyf, izf = _segment(sex, "forearm", body_mass, scale)
    mh, _lh, ch, ixh, iyh, izh = _segment(sex, "hand", body_mass, scale)
    ch += lf  # hand CM measured from the elbow
    m2 = mf + mh
    c2 = (mf * cf + mh * ch) / m2
    shift = mf * (cf - c2) ** 2 + mh * (ch - c2) ** 2
    return HumanArmSegments(
        l1=_sig(l1),
        lc1=_sig(c1),
        m1=_sig(m1),
        i1=(_sig(ix1), _sig(iy1), _sig(iz1)),
        l2=_sig(ch),
        lc2=_sig(c2),
        m2=_sig(m2),
        i2=(_sig(ixf + ixh + shift), _sig(iyf + iyh + shift), _sig(izf + izh)),
        forearm_length=_sig(lf),
    )


def human_arm_chain(seg: HumanArmSegments, *, comment: str = "") -> ChainSpec:
    """The URDF/MJCF description of a subject's arm (no payload: it is applied in code)."""
    skin = (0.93, 0.76, 0.65, 1.0)
    shirt = (0.35, 0.45, 0.65, 1.0)
    links = []
    for joint, link, origin, length, mass, com, inertia, radius in (
        ("shoulder_flexion", "upper_arm", 0.0, seg.l1, seg.m1, seg.lc1, seg.i1, 0.045),
        ("elbow_flexion", "forearm_hand", -seg.l1, seg.l2, seg.m2, seg.lc2, seg.i2, 0.035),
    ):
        lower, upper, velocity, effort = _LIMITS[joint]
        if link == "upper_arm":
            visuals: tuple[Visual, ...] = (
                Visual((0.0, 0.0, 0.0), (0.0, 0.0, -length), radius, shirt),
            )
        else:
            visuals = (
                Visual((0.0, 0.0, 0.0), (0.0, 0.0, -seg.forearm_length), radius, skin),
                Visual((0.0, 0.0, -seg.forearm_length), (0.0, 0.0, -length), 0.025, skin),
            )
        links.append(
            ChainLink(
                joint=joint,
                link=link,
                origin=(0.0, 0.0, origin),
                axis=(0.0, -1.0, 0.0),
                lower=round(lower, 6),
                upper=round(upper, 6),
                velocity=velocity,
                effort=effort,
                mass=mass,
                com=(0.0, 0.0, -com),
                inertia=(inertia[0], inertia[1], inertia[2], 0.0, 0.0, 0.0),
                visuals=visuals,
            )
        )
    # The trunk beside the arm's plane (y = 0), 15 mm from the upper arm: it is the arm's
    # collision partner in the safety check, which a closer box would touch at rest.
    trunk = Visual((0.0, 0.21, -0.26), (0.0, 0.21, -0.26), 0.0, shirt, box=(0.2, 0.3, 0.55))
    return ChainSpec(
        name="human_arm_2dof",
        base="trunk",
        links=tuple(links),
        base_visuals=(trunk,),
        comment=comment,
    )


def _de_leva_rows(sex: str) -> list[dict[str, object]]:
    """de Leva's (1996) Table 4 values of the arm's segments for ``sex``."""
    rows = [_row("de_leva.reference_stature", _STATURE[sex], "m", _TABLE4)]
    for segment, values in _ARM[sex].items():
        fraction, length, cm, r_sag, r_trans, r_long = values
        for key, value, unit in (
            ("mass_fraction", fraction, "1"),
            ("length", length, "m"),
            ("cm_fraction_from_proximal", cm, "1"),
            ("radius_sagittal", r_sag, "1"),
            ("radius_transverse", r_trans, "1"),
            ("radius_longitudinal", r_long, "1"),
        ):
            rows.append(_row(f"de_leva.{sex}.{segment}.{key}", value, unit, _TABLE4))
    return rows


def _segment_rows(seg: HumanArmSegments) -> list[dict[str, object]]:
    """The subject's two links: mass [kg], length and CM distance [m], inertia [kg m^2]."""
    scaled = "de Leva (1996) scaled: mass x body mass, length x body height / reference stature"
    lumped = scaled + "; forearm and hand combined by the parallel-axis theorem"
    rows: list[dict[str, object]] = []
    for link, mass, length, com, inertia, source in (
        ("upper_arm", seg.m1, seg.l1, seg.lc1, seg.i1, scaled),
        ("forearm_hand", seg.m2, seg.l2, seg.lc2, seg.i2, lumped),
    ):
        grip = "" if link == "upper_arm" else "; elbow to grip, grip at the hand's CM (assumed)"
        rows += [
            _row(f"{link}.mass", mass, "kg", source),
            _row(f"{link}.length", length, "m", source + grip),
            _row(f"{link}.com_distance", com, "m", source),
            _row(f"{link}.inertia_xx", inertia[0], "kg m^2", source),
            _row(f"{link}.inertia_yy", inertia[1], "kg m^2", source),
            _row(f"{link}.inertia_zz", inertia[2], "kg m^2", source),
        ]
    return rows


def _limit_rows() -> list[dict[str, object]]:
    """Per joint: range [rad], peak velocity [rad/s] and torque [Nm], controller limits."""
    rows: list[dict[str, object]] = []
    for joint, (lower, upper, velocity, effort) in _LIMITS.items():
        acceleration, jerk = _CONTROLLER_LIMITS[joint][0], _CONTROLLER_LIMITS[joint][1]
        rows += [
            _row(f"{joint}.lower", round(lower, 6), "rad", _LIMIT_SOURCE),
            _row(f"{joint}.upper", round(upper, 6), "rad", _LIMIT_SOURCE),
            _row(f"{joint}.velocity", velocity, "rad/s", _LIMIT_SOURCE),
            _row(f"{joint}.effort", effort, "Nm", _LIMIT_SOURCE),
            _row(f"{joint}.acceleration", acceleration, "rad/s^2", _CONTROLLER_SOURCE),
            _row(f"{joint}.jerk", jerk, "rad/s^3", _CONTROLLER_SOURCE),
        ]
    return rows


def human_arm_parameters(
    seg: HumanArmSegments, *, body_mass: float, body_height: float, sex: str
) -> tuple[dict[str, object], ...]:
    """The parameter table of a subject's arm: one ``{name, value, unit, source}`` row per
    number (the subject, de Leva's table, the scaled links, joint limits, payload, motors)."""
    return (
        _row("subject.body_mass", body_mass, "kg", "input"),
        _row("subject.body_height", body_height, "m", "input"),
        _row("subject.sex", sex, "", "input"),
        *_de_leva_rows(sex),
        *_segment_rows(seg),
        *_limit_rows(),
        _row("payload.mass", 12.0, "kg", "paper: 12 kg dumbbell (default; configurable)"),
        _row(
            "payload.position",
            "grip (0, 0, -forearm_hand.length)",
            "m",
            "point mass at the grip (assumed)",
        ),
        _row(
            "motors",
            "ideal actuator",
            "",
            "muscles are not motors: gear 1, no resistance, friction, rotor inertia or "
            "regeneration, so electrical energy equals mechanical work",
        ),
    )
