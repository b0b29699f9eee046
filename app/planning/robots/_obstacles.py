"""The sidecar's workspace: obstacles (boxes, cylinders, planes) and the mounting plane.

Read by ``read_sidecar``; used by :mod:`app.planning.safety`. Values are in the robot's base
frame: positions and sizes in metres, orientations in degrees (roll, pitch, yaw about the fixed
x, y, z axes, as in URDF). Every error names the file and the field (``obstacles[1].size``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from app.planning.robots._sidecar import _Fields

__all__ = ["OBSTACLE_KINDS", "MountPlane", "Obstacle", "read_workspace"]

#: Obstacle kinds and the fields each one takes (besides ``name`` and ``kind``).
OBSTACLE_KINDS: dict[str, tuple[str, ...]] = {
    "box": ("position", "rpy_deg", "size"),
    "cylinder": ("position", "rpy_deg", "radius", "length"),
    "plane": ("position", "normal"),
}
_MOUNT = ("height", "enabled")


@dataclass(frozen=True)
class Obstacle:
    """A fixed obstacle in the robot's base frame.

    Attributes:
        name: the name findings report.
        kind: ``box``, ``cylinder`` (axis along its local z) or ``plane`` (a half-space).
        position: (3,) box or cylinder centre, or a point on the plane [m].
        rpy: (3,) roll, pitch, yaw of a box or cylinder [rad] (URDF convention).
        size: (3,) full box extents [m] (box only).
        radius, length: cylinder radius and length [m] (cylinder only).
        normal: (3,) unit normal of a plane, pointing to the free side (the robot's side).
    """

    name: str
    kind: str
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    length: float = 0.0
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class MountPlane:
    """The plane the robot stands on: every moving link must stay above it.

    Attributes:
        height: its height in the base frame [m] (None: the robot's default, 0 m for arms).
        enabled: False turns the check off (a robot hung from a ceiling, a wall mount).
    """

    height: float | None = None
    enabled: bool = True


def _positive(fields: _Fields, where: str, value: Any) -> float:
    return fields.number(where, value, lower=0.0, strict=True)


def _obstacle(fields: _Fields, index: int, data: Any, seen: set[str]) -> Obstacle:
    where = f"obstacles[{index}]"
    values = fields.mapping(where, data)
    name = fields.text(f"{where}.name", values.get("name"))
    if name is None:
        raise fields.fail(f"{where}.name", None, "a name for the obstacle")
    if name in seen:
        raise fields.fail(f"{where}.name", name, "a name no other obstacle has")
    seen.add(name)
    kind = values.get("kind")
    if kind not in OBSTACLE_KINDS:
        raise fields.fail(f"{where}.kind", kind, f"one of {', '.join(OBSTACLE_KINDS)}")
    fields.unknown(where, values, ("name", "kind", *OBSTACLE_KINDS[kind]))
    position = fields.vector(f"{where}.position", values.get("position"))
    if position is None:
        raise fields.fail(f"{where}.position", None, "a list of three numbers [m]")
    if kind == "plane":
        normal = fields.vector(f"{where}.normal", values.get("normal")) or (0.0, 0.0, 1.0)
        norm = math.sqrt(sum(v * v for v in normal))
        if norm == 0.0:
            raise fields.fail(f"{where}.normal", list(normal), "a non-zero direction")
        unit = (normal[0] / norm, normal[1] / norm, normal[2] / norm)
        return Obstacle(name=name, kind=kind, position=position, normal=unit)
    rpy_deg = fields.vector(f"{where}.rpy_deg", values.get("rpy_deg")) or (0.0, 0.0, 0.0)
    rpy = (math.radians(rpy_deg[0]), math.radians(rpy_deg[1]), math.radians(rpy_deg[2]))
    if kind == "box":
        size = fields.vector(f"{where}.size", values.get("size"))
        if size is None or min(size) <= 0.0:
            got = None if size is None else list(size)
            raise fields.fail(f"{where}.size", got, "three extents > 0 m")
        return Obstacle(name=name, kind=kind, position=position, rpy=rpy, size=size)
    for key in ("radius", "length"):
        if key not in values:
            raise fields.fail(f"{where}.{key}", None, "a number > 0 [m]")
    return Obstacle(
        name=name,
        kind=kind,
        position=position,
        rpy=rpy,
        radius=_positive(fields, f"{where}.radius", values["radius"]),
        length=_positive(fields, f"{where}.length", values["length"]),
    )


def read_workspace(
    fields: _Fields, top: dict[str, Any]
) -> tuple[tuple[Obstacle, ...], MountPlane, str | None]:
    """The sidecar's ``obstacles``, ``mount_plane`` and ``srdf`` fields.

    Returns:
        (obstacles, mount plane, SRDF path as written or None).
    """
    raw = top.get("obstacles")
    if raw is not None and not isinstance(raw, list):
        raise fields.fail("obstacles", raw, "a list of obstacles (name, kind, ...)")
    seen: set[str] = set()
    obstacles = tuple(_obstacle(fields, i, item, seen) for i, item in enumerate(raw or []))
    mount = fields.mapping("mount_plane", top.get("mount_plane"))
    fields.unknown("mount_plane", mount, _MOUNT)
    height = mount.get("height")
    enabled = mount.get("enabled", True)
    if not isinstance(enabled, bool):
        raise fields.fail("mount_plane.enabled", enabled, "true or false")
    plane = MountPlane(
        height=None if height is None else fields.number("mount_plane.height", height),
        enabled=enabled,
    )
    return obstacles, plane, fields.text("srdf", top.get("srdf"))
