"""Reading a user URDF enough to give one-line errors: joints, limits, mimic tags, meshes.

URDF files are parsed from bytes: ElementTree refuses a ``str`` that carries an XML encoding
declaration (``<?xml version="1.0" encoding="utf-8"?>``, as every UR file has).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from app.planning.robots._types import RobotError

__all__ = ["MOVABLE_TYPES", "UrdfJoint", "UrdfModel", "parse_urdf", "read_xml"]

#: Joint types a robot may have (prismatic and mimic joints only when locked).
MOVABLE_TYPES = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class UrdfJoint:
    """One movable URDF joint.

    Attributes:
        name: joint name.
        kind: ``revolute``, ``continuous`` or ``prismatic``.
        parent, child: link names.
        lower, upper: position limits [rad or m] (+-inf for continuous joints).
        velocity: speed limit [rad/s or m/s].
        effort: torque [Nm] or force [N] limit.
        mimic: (leader joint, multiplier, offset) for a ``<mimic>`` joint, else None.
        limited: False for a joint without ``<limit>`` (a caster, a wheel): its limits are
            unknown (position ±inf, speed and effort inf) and it must be locked or given
            limits by a sidecar.
    """

    name: str
    kind: str
    parent: str
    child: str
    lower: float
    upper: float
    velocity: float
    effort: float
    mimic: tuple[str, float, float] | None = None
    limited: bool = True

    @property
    def unit(self) -> str:
        """Display unit of a value of this joint: ``deg`` (rotary) or ``m`` (prismatic)."""
        return "m" if self.kind == "prismatic" else "deg"


@dataclass(frozen=True)
class UrdfModel:
    """What the loader needs from a URDF file.

    Attributes:
        name: the robot's name (``<robot name>``, else the file's stem).
        joints: movable joints in file order.
        links: link names.
        meshes: every ``<mesh filename>`` of visuals and collisions, in file order.
        parents: child link -> (joint name, parent link), for every joint (fixed ones too).
        root: the root link.
    """

    name: str
    joints: tuple[UrdfJoint, ...]
    links: tuple[str, ...]
    meshes: tuple[str, ...]
    parents: dict[str, tuple[str, str]] = field(default_factory=dict)
    root: str = ""

    def ancestors(self, link: str) -> list[str]:
        """The joints from the root down to ``link`` (root first; fixed joints included)."""
        out: list[str] = []
        while link in self.parents:
            joint, link = self.parents[link]
            out.append(joint)
        return out[::-1]

    def joint(self, name: str) -> UrdfJoint:
        for joint in self.joints:
            if joint.name == name:
                return joint
        raise KeyError(name)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(joint.name for joint in self.joints)


def read_xml(path: Path, what: str) -> ET.Element:
    """The root element of an XML file, parsed from its bytes; one-line errors."""
    file = path.name
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise RobotError(f"{file}: no such file ({path}): expected a {what} file") from None
    except OSError as exc:
        raise RobotError(
            f"{file}: cannot be read ({exc.strerror}): expected a {what} file"
        ) from None
    try:
        return ET.fromstring(data)
    except ET.ParseError as exc:
        line, column = exc.position
        raise RobotError(
            f"{file}: not well-formed XML at line {line}, column {column + 1}: "
            f"expected a {what} document"
        ) from None


def _number(file: str, joint: str, limit: ET.Element, key: str) -> float:
    text = limit.get(key)
    if text is None:
        raise RobotError(
            f"{file}: joint '{joint}' <limit> lacks '{key}': "
            "expected lower, upper, velocity and effort (velocity and effort for continuous)"
        )
    try:
        value = float(text)
    except ValueError:
        raise RobotError(
            f"{file}: joint '{joint}' <limit {key}=\"{text}\">: expected a number"
        ) from None
    if not math.isfinite(value):
        raise RobotError(
            f"{file}: joint '{joint}' <limit {key}=\"{text}\">: expected a finite number"
        )
    return value


def _mimic(file: str, name: str, element: ET.Element) -> tuple[str, float, float] | None:
    tag = element.find("mimic")
    if tag is None:
        return None
    leader = tag.get("joint")
    if not leader:
        raise RobotError(f"{file}: joint '{name}' <mimic> has no joint: expected <mimic joint=...>")
    try:
        multiplier = float(tag.get("multiplier", "1"))
        offset = float(tag.get("offset", "0"))
    except ValueError:
        raise RobotError(
            f"{file}: joint '{name}' <mimic> multiplier/offset: expected numbers"
        ) from None
    return leader, multiplier, offset


def _limits(file: str, name: str, kind: str, element: ET.Element) -> tuple[float, ...]:
    limit = element.find("limit")
    if limit is None:  # a caster or a wheel: lockable; refused later if left free
        return -math.inf, math.inf, math.inf, math.inf
    if kind == "continuous":
        lower, upper = -math.inf, math.inf
    else:
        lower = _number(file, name, limit, "lower")
        upper = _number(file, name, limit, "upper")
        if not lower < upper:
            raise RobotError(
                f"{file}: joint '{name}' limits lower={lower} upper={upper}: expected lower < upper"
            )
    velocity = _number(file, name, limit, "velocity")
    effort = _number(file, name, limit, "effort")
    for key, value in (("velocity", velocity), ("effort", effort)):
        if value <= 0.0:
            raise RobotError(
                f"{file}: joint '{name}' <limit {key}=\"{value:g}\">: expected a value > 0"
            )
    return lower, upper, velocity, effort


def _joint(file: str, element: ET.Element, links: list[str]) -> tuple[str, str, UrdfJoint | None]:
    """(parent, child, the movable joint or None for a fixed one)."""
    name = element.get("name")
    if not name:
        raise RobotError(f"{file}: a <joint> has no name: expected <joint name=... type=...>")
    kind = element.get("type")
    parent = element.find("parent")
    child = element.find("child")
    parent_link = parent.get("link") if parent is not None else None
    child_link = child.get("link") if child is not None else None
    if parent_link is None or child_link is None:
        raise RobotError(
            f"{file}: joint '{name}' lacks <parent link> or <child link>: expected both"
        )
    for role, link_name in (("parent", parent_link), ("child", child_link)):
        if link_name not in links:
            raise RobotError(
                f"{file}: joint '{name}' {role} link '{link_name}' is not defined: "
                "expected a <link> of that name"
            )
    if kind == "fixed":
        return parent_link, child_link, None
    if kind not in MOVABLE_TYPES:
        raise RobotError(
            f"{file}: joint '{name}' has type '{kind}': expected revolute, continuous, "
            "prismatic or fixed"
        )
    lower, upper, velocity, effort = _limits(file, name, kind, element)
    joint = UrdfJoint(
        name,
        kind,
        parent_link,
        child_link,
        lower,
        upper,
        velocity,
        effort,
        _mimic(file, name, element),
        limited=element.find("limit") is not None,
    )
    return parent_link, child_link, joint


def parse_urdf(path: Path) -> UrdfModel:
    """Validate a URDF enough to give one-line errors.

    Raises:
        RobotError: unreadable or malformed file, a joint without limits, a floating or planar
            joint, not a tree, or no movable joint.
    """
    file = path.name
    root = read_xml(path, "URDF")
    if root.tag != "robot":
        raise RobotError(f"{file}: root element is <{root.tag}>: expected <robot>")
    links = [link.get("name") or "" for link in root.findall("link")]
    if not all(links):
        raise RobotError(f"{file}: a <link> has no name: expected <link name=...>")
    if len(set(links)) != len(links):
        raise RobotError(f"{file}: duplicate link names: expected unique link names")
    movable: list[UrdfJoint] = []
    children: set[str] = set()
    parents: dict[str, tuple[str, str]] = {}
    for element in root.findall("joint"):
        parent, child, joint = _joint(file, element, links)
        if child in children:
            raise RobotError(f"{file}: link '{child}' is the child of two joints: expected a tree")
        children.add(child)
        parents[child] = (element.get("name") or "", parent)
        if joint is not None:
            movable.append(joint)
    roots = [name for name in links if name not in children]
    if len(roots) != 1:
        raise RobotError(f"{file}: {len(roots)} root links {roots}: expected exactly one")
    if not movable:
        raise RobotError(
            f"{file}: no moving joint (every joint is fixed): expected at least two revolute "
            "or continuous joints"
        )
    names = {joint.name for joint in movable}
    for joint in movable:
        if joint.mimic is not None and joint.mimic[0] not in names:
            raise RobotError(
                f"{file}: joint '{joint.name}' mimics '{joint.mimic[0]}', which is not a "
                "movable joint: expected a movable joint name"
            )
    meshes = tuple(
        mesh.get("filename") or ""
        for link in root.findall("link")
        for tag in ("visual", "collision")
        for element in link.findall(tag)
        for mesh in element.iter("mesh")
    )
    return UrdfModel(
        name=root.get("name") or path.stem,
        joints=tuple(movable),
        links=tuple(links),
        meshes=meshes,
        parents=parents,
        root=roots[0],
    )
