"""Identified parameters in a sidecar: link inertias and joint friction (``bioplan identify``).

Two optional sidecar sections (``docs/robots.md``)::

    links:                       # replace these links' <inertial> in the URDF
      forearm: {mass: 2.4, com: [0, 0, -0.12], inertia: [0.01, 0, 0, 0.01, 0, 0.001]}
    friction:                    # joint-side friction and torque offset, per joint
      elbow: {viscous: 0.8, coulomb: 1.5, offset: -0.2}

``mass`` [kg] > 0, ``com`` [m] in the link frame, ``inertia`` [kg m^2] about the centre of mass
along the link's axes, in URDF order (ixx, ixy, ixz, iyy, iyz, izz), positive definite and
obeying the triangle inequality. ``viscous`` [Nm s/rad] >= 0 and ``coulomb`` [Nm] >= 0 replace
the motors' friction (the energy model's τ_f = b q̇ + c tanh(q̇/ε)); ``offset`` [Nm] is the
logged torque's constant bias, used when ``bioplan validate`` compares a log with the model.

A robot loaded with ``links`` uses a copy of its URDF with those inertials replaced (written
once, content-addressed, mesh paths made absolute): Pinocchio, MuJoCo and the viewer all see
the identified bodies.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from app.planning.robots._cache import write_cached
from app.planning.robots._types import RobotError

if TYPE_CHECKING:
    from app.planning.energy import MotorModel
    from app.planning.robots._sidecar import Sidecar

__all__ = [
    "JointFriction",
    "LinkInertial",
    "identified_urdf",
    "link_inertials",
    "read_identified",
    "with_friction",
]

_LINK = ("mass", "com", "inertia")
_FRICTION = ("viscous", "coulomb", "offset")


@dataclass(frozen=True)
class LinkInertial:
    """A link's rigid body: mass [kg], com (3,) [m] in the link frame, inertia (ixx, ixy, ixz,
    iyy, iyz, izz) about the centre of mass [kg m^2]."""

    mass: float
    com: tuple[float, float, float]
    inertia: tuple[float, float, float, float, float, float]

    def matrix(self) -> np.ndarray:
        xx, xy, xz, yy, yz, zz = self.inertia
        return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


@dataclass(frozen=True)
class JointFriction:
    """Joint-side friction: viscous [Nm s/rad], Coulomb [Nm], logged-torque offset [Nm]."""

    viscous: float = 0.0
    coulomb: float = 0.0
    offset: float = 0.0


def _inertia_ok(values: Sequence[float]) -> bool:
    xx, xy, xz, yy, yz, zz = values
    matrix = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    eig = np.linalg.eigvalsh(matrix)
    tol = 1e-9 * max(1.0, float(np.abs(eig).max()))
    return bool(eig.min() > 0.0 and 2.0 * eig.max() <= eig.sum() + tol)


def read_identified(
    fields: Any, top: Mapping[str, Any]
) -> tuple[dict[str, LinkInertial], dict[str, JointFriction]]:
    """The ``links`` and ``friction`` sections, checked (``fields`` is the sidecar's reader)."""
    links: dict[str, LinkInertial] = {}
    for name, data in fields.mapping("links", top.get("links")).items():
        where = f"links.{name}"
        values = fields.mapping(where, data)
        fields.unknown(where, values, _LINK)
        missing = [key for key in _LINK if key not in values]
        if missing:
            raise fields.fail(where, data, f"mass, com and inertia (lacks {missing[0]})")
        inertia = values["inertia"]
        if not isinstance(inertia, list) or len(inertia) != 6:
            raise fields.fail(f"{where}.inertia", inertia, "six numbers ixx ixy ixz iyy iyz izz")
        six = tuple(fields.number(f"{where}.inertia[{i}]", v) for i, v in enumerate(inertia))
        if not _inertia_ok(six):
            raise fields.fail(
                f"{where}.inertia", inertia, "a positive-definite inertia (triangle inequality)"
            )
        com = fields.vector(f"{where}.com", values["com"])
        links[name] = LinkInertial(
            mass=fields.number(f"{where}.mass", values["mass"], lower=0.0, strict=True),
            com=com,
            inertia=six,
        )
    friction: dict[str, JointFriction] = {}
    for name, data in fields.mapping("friction", top.get("friction")).items():
        where = f"friction.{name}"
        values = fields.mapping(where, data)
        fields.unknown(where, values, _FRICTION)
        friction[name] = JointFriction(
            viscous=fields.number(f"{where}.viscous", values.get("viscous", 0.0), lower=0.0),
            coulomb=fields.number(f"{where}.coulomb", values.get("coulomb", 0.0), lower=0.0),
            offset=fields.number(f"{where}.offset", values.get("offset", 0.0)),
        )
    return links, friction


def with_friction(
    motors: tuple[MotorModel, ...], free: Sequence[str], car: Sidecar | None
) -> tuple[MotorModel, ...]:
    """The motors with the sidecar's identified friction (unknown joints refused)."""
    friction: Mapping[str, JointFriction] = getattr(car, "friction", {}) if car else {}
    if not friction:
        return motors
    assert car is not None
    unknown = sorted(set(friction) - set(free))
    if unknown:
        raise RobotError(
            f"{car.path.name}: friction.{unknown[0]} is not a free joint: expected one of "
            f"{', '.join(free)}"
        )
    return tuple(
        dataclasses.replace(
            motor, viscous_friction=friction[name].viscous, coulomb_friction=friction[name].coulomb
        )
        if name in friction
        else motor
        for name, motor in zip(free, motors, strict=True)
    )


def link_inertials(urdf: Path) -> dict[str, LinkInertial | None]:
    """Every link's ``<inertial>`` of a URDF (None: no inertial, a massless link)."""
    from scipy.spatial.transform import Rotation

    from app.planning.robots._urdf import read_xml

    out: dict[str, LinkInertial | None] = {}
    for link in read_xml(urdf, "URDF").findall("link"):
        inertial = link.find("inertial")
        name = link.get("name", "")
        if inertial is None:
            out[name] = None
            continue
        origin = inertial.find("origin")
        xyz = [
            float(v)
            for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()
        ]
        rpy = [
            float(v)
            for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()
        ]
        mass_el, inertia_el = inertial.find("mass"), inertial.find("inertia")
        mass = float(mass_el.get("value", "0")) if mass_el is not None else 0.0
        keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        six = [float(inertia_el.get(k, "0")) if inertia_el is not None else 0.0 for k in keys]
        matrix = LinkInertial(mass, (0.0, 0.0, 0.0), tuple(six)).matrix()  # type: ignore[arg-type]
        rotation = Rotation.from_euler("xyz", rpy).as_matrix()
        turned = rotation @ matrix @ rotation.T
        out[name] = LinkInertial(
            mass=mass,
            com=(xyz[0], xyz[1], xyz[2]),
            inertia=tuple(float(turned[i, j]) for i, j in _UPPER),  # type: ignore[arg-type]
        )
    return out


_UPPER = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def identified_urdf(urdf: Path, car: Sidecar | None) -> Path:
    """``urdf``, or a copy with the sidecar's ``links`` inertials (cached, mesh paths absolute).

    Raises:
        RobotError: a ``links`` entry that names no link of the URDF.
    """
    links: Mapping[str, LinkInertial] = getattr(car, "links", {}) if car else {}
    if not links:
        return urdf
    assert car is not None
    from app.planning.robots._urdf import read_xml

    root = read_xml(urdf, "URDF")
    elements = {link.get("name"): link for link in root.findall("link")}
    unknown = sorted(set(links) - set(elements))
    if unknown:
        raise RobotError(
            f"{car.path.name}: links.{unknown[0]} is not a link of {urdf.name}: expected one of "
            f"{', '.join(str(k) for k in elements)}"
        )
    for name, body in links.items():
        link = elements[name]
        for old in link.findall("inertial"):
            link.remove(old)
        inertial = ET.Element("inertial")
        ET.SubElement(inertial, "origin", xyz=" ".join(f"{v:.12g}" for v in body.com), rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=f"{body.mass:.12g}")
        ET.SubElement(
            inertial,
            "inertia",
            {
                k: f"{v:.12g}"
                for k, v in zip(
                    ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"), body.inertia, strict=True
                )
            },
        )
        link.insert(0, inertial)
    folder = urdf.resolve().parent
    for mesh in root.iter("mesh"):
        filename = mesh.get("filename", "")
        if filename and "://" not in filename and not Path(filename).is_absolute():
            mesh.set("filename", str(folder / filename))
    text = ET.tostring(root, encoding="unicode")
    return write_cached(text, urdf.stem + ".identified", ".urdf")
