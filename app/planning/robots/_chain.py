"""A serial chain of revolute joints, written out as a URDF and as an MJCF from one description.

Both built-in robots are described once (``ChainSpec``) and both files are generated from that
description, so the two engines see the same rigid bodies by construction. Every shape is also
the link's URDF ``<collision>`` geometry (the safety check, ``app.planning.safety``); in the
MJCF the shapes stay contact-free (``contype="0" conaffinity="0"``), so simulation is unchanged.
Rotor inertia, friction, damping and the payload are deliberately *not* written into either
file: they are applied in code to both engines alike (see ``Robot.dynamics`` and
``Robot.mujoco_model``).

All link frames are parallel to the world frame at q = 0, which keeps inertias readable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ChainLink", "ChainSpec", "Visual", "mjcf_text", "urdf_text"]


@dataclass(frozen=True)
class Visual:
    """A cylinder (or box) in a link's frame, shown and checked for collisions (URDF
    ``<visual>`` and ``<collision>``); never contributes mass nor MuJoCo contacts.

    Attributes:
        start, end: (3,) end points of the cylinder axis in the link frame [m] (box: the centre
            is their midpoint and ``end - start`` must be zero; ``size`` gives the extents).
        radius: cylinder radius [m] (ignored for boxes).
        rgba: colour.
        box: (3,) full box extents [m], or None for a cylinder.
    """

    start: tuple[float, float, float]
    end: tuple[float, float, float]
    radius: float
    rgba: tuple[float, float, float, float] = (0.7, 0.7, 0.72, 1.0)
    box: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class ChainLink:
    """One revolute joint and the link it moves.

    Attributes:
        joint: joint name (URDF joint == MJCF joint).
        link: child link name (URDF link == MJCF body).
        origin: (3,) joint position in the parent link frame [m] (no rotation: all frames
            stay parallel).
        axis: (3,) unit joint axis in the link frame.
        lower, upper: position limits [rad].
        velocity: speed limit [rad/s].
        effort: torque limit [Nm].
        mass: link mass [kg].
        com: (3,) centre of mass in the link frame [m].
        inertia: (ixx, iyy, izz, ixy, ixz, iyz) about the centre of mass, link axes [kg m^2].
        visuals: display geometry.
    """

    joint: str
    link: str
    origin: tuple[float, float, float]
    axis: tuple[float, float, float]
    lower: float
    upper: float
    velocity: float
    effort: float
    mass: float
    com: tuple[float, float, float]
    inertia: tuple[float, float, float, float, float, float]
    visuals: tuple[Visual, ...] = ()


@dataclass(frozen=True)
class ChainSpec:
    """A fixed-base serial chain.

    Attributes:
        name: robot name.
        base: name of the fixed root link (URDF) / static body (MJCF).
        base_visuals: display geometry of the base (e.g. a pedestal).
        links: the moving links, root first.
        comment: one line written at the top of both files.
    """

    name: str
    base: str
    links: tuple[ChainLink, ...]
    base_visuals: tuple[Visual, ...] = ()
    comment: str = ""


def _num(x: float) -> str:
    # repr() round-trips a float exactly, so the files hold exactly the parameters' values
    # (the closed-form model and the parsed models then agree to rounding error only).
    value = float(x)
    if value == 0.0:
        return "0"
    text = repr(value)
    return text[:-2] if text.endswith(".0") else text


def _vec(values: tuple[float, ...] | list[float]) -> str:
    return " ".join(_num(v) for v in values)


def _cylinder_pose(visual: Visual) -> tuple[tuple[float, ...], tuple[float, ...], float]:
    """Centre, URDF rpy and length of a cylinder running from ``start`` to ``end``."""
    p0 = np.asarray(visual.start, dtype=float)
    p1 = np.asarray(visual.end, dtype=float)
    d = p1 - p0
    length = float(np.linalg.norm(d))
    centre = tuple(round(float(v), 9) for v in (p0 + p1) / 2)
    if length == 0.0:
        return centre, (0.0, 0.0, 0.0), 0.0
    u = d / length
    length = round(length, 9)
    if abs(abs(float(u[2])) - 1.0) < 1e-12:
        return centre, (0.0, 0.0, 0.0), length  # along +-z: the cylinder is symmetric
    # Rotation taking the cylinder's local z onto u, as URDF roll-pitch-yaw (R = Rz Ry Rx).
    # Ry(pitch) then Rz(yaw) maps z to (cos y sin p, sin y sin p, cos p).
    pitch = math.acos(max(-1.0, min(1.0, float(u[2]))))
    yaw = math.atan2(float(u[1]), float(u[0])) if math.hypot(u[0], u[1]) > 1e-12 else 0.0
    return centre, (0.0, round(pitch, 12), round(yaw, 12)), length


def _urdf_shape(visual: Visual, indent: str) -> tuple[list[str], list[str]]:
    """The ``<visual>`` and the ``<collision>`` element of one shape (the same geometry)."""
    if visual.box is not None:
        centre = tuple((a + b) / 2 for a, b in zip(visual.start, visual.end, strict=True))
        rpy: tuple[float, ...] = (0.0, 0.0, 0.0)
        geometry = f'<box size="{_vec(visual.box)}"/>'
    else:
        centre, rpy, length = _cylinder_pose(visual)
        geometry = f'<cylinder radius="{_num(visual.radius)}" length="{_num(length)}"/>'
    origin = f'{indent}  <origin xyz="{_vec(centre)}" rpy="{_vec(rpy)}"/>'
    shown = [
        f"{indent}<visual>",
        origin,
        f"{indent}  <geometry>{geometry}</geometry>",
        f'{indent}  <material name="rgba_{_vec(visual.rgba).replace(" ", "_")}">'
        f'<color rgba="{_vec(visual.rgba)}"/></material>',
        f"{indent}</visual>",
    ]
    checked = [
        f"{indent}<collision>",
        origin,
        f"{indent}  <geometry>{geometry}</geometry>",
        f"{indent}</collision>",
    ]
    return shown, checked


def _urdf_shapes(visuals: tuple[Visual, ...], indent: str) -> list[str]:
    """Every shape's ``<visual>``, then every shape's ``<collision>``."""
    pairs = [_urdf_shape(visual, indent) for visual in visuals]
    return [line for shown, _ in pairs for line in shown] + [
        line for _, checked in pairs for line in checked
    ]


def urdf_text(spec: ChainSpec) -> str:
    """The chain as URDF text (joints in chain order; no payload, armature or friction)."""
    lines = ['<?xml version="1.0"?>']
    if spec.comment:
        lines.append(f"<!-- {spec.comment} -->")
    lines.append(f'<robot name="{spec.name}">')
    lines.append(f'  <link name="{spec.base}">')
    lines.extend(_urdf_shapes(spec.base_visuals, "    "))
    lines.append("  </link>")
    parent = spec.base
    for link in spec.links:
        ixx, iyy, izz, ixy, ixz, iyz = link.inertia
        lines += [
            f'  <joint name="{link.joint}" type="revolute">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{link.link}"/>',
            f'    <origin xyz="{_vec(link.origin)}" rpy="0 0 0"/>',
            f'    <axis xyz="{_vec(link.axis)}"/>',
            f'    <limit lower="{_num(link.lower)}" upper="{_num(link.upper)}" '
            f'velocity="{_num(link.velocity)}" effort="{_num(link.effort)}"/>',
            "  </joint>",
            f'  <link name="{link.link}">',
            "    <inertial>",
            f'      <origin xyz="{_vec(link.com)}" rpy="0 0 0"/>',
            f'      <mass value="{_num(link.mass)}"/>',
            f'      <inertia ixx="{_num(ixx)}" ixy="{_num(ixy)}" ixz="{_num(ixz)}" '
            f'iyy="{_num(iyy)}" iyz="{_num(iyz)}" izz="{_num(izz)}"/>',
            "    </inertial>",
        ]
        lines.extend(_urdf_shapes(link.visuals, "    "))
        lines.append("  </link>")
        parent = link.link
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def _mjcf_geom(visual: Visual, indent: str) -> str:
    rgba = _vec(visual.rgba)
    if visual.box is not None:
        centre = tuple((a + b) / 2 for a, b in zip(visual.start, visual.end, strict=True))
        half = tuple(v / 2 for v in visual.box)
        return (
            f'{indent}<geom type="box" pos="{_vec(centre)}" size="{_vec(half)}" '
            f'rgba="{rgba}" contype="0" conaffinity="0"/>'
        )
    return (
        f'{indent}<geom type="cylinder" fromto="{_vec(visual.start + visual.end)}" '
        f'size="{_num(visual.radius)}" rgba="{rgba}" contype="0" conaffinity="0"/>'
    )


def mjcf_text(spec: ChainSpec) -> str:
    """The chain as MJCF text, the same rigid bodies as ``urdf_text``.

    Explicit ``<inertial>`` on every moving body (``inertiafromgeom="false"``), contacts off,
    radians, 1 ms time step, and one unit-gear torque motor per joint whose force is clamped
    to the effort limit through ``actuatorfrcrange``.
    """
    lines = []
    if spec.comment:
        lines.append(f"<!-- {spec.comment} -->")
    lines += [
        f'<mujoco model="{spec.name}">',
        '  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>',
        '  <option timestep="0.001"/>',
        "  <worldbody>",
        f'    <body name="{spec.base}">',
    ]
    for visual in spec.base_visuals:
        lines.append(_mjcf_geom(visual, "      "))
    indent = "      "
    for link in spec.links:
        ixx, iyy, izz, ixy, ixz, iyz = link.inertia
        lines += [
            f'{indent}<body name="{link.link}" pos="{_vec(link.origin)}">',
            f'{indent}  <joint name="{link.joint}" type="hinge" axis="{_vec(link.axis)}" '
            f'range="{_num(link.lower)} {_num(link.upper)}" '
            f'actuatorfrcrange="{_num(-link.effort)} {_num(link.effort)}"/>',
            f'{indent}  <inertial pos="{_vec(link.com)}" mass="{_num(link.mass)}" '
            f'fullinertia="{_vec((ixx, iyy, izz, ixy, ixz, iyz))}"/>',
        ]
        for visual in link.visuals:
            lines.append(_mjcf_geom(visual, indent + "  "))
        indent += "  "
    for _ in spec.links:
        indent = indent[:-2]
        lines.append(f"{indent}</body>")
    lines += ["    </body>", "  </worldbody>", "  <actuator>"]
    for link in spec.links:
        lines.append(f'    <motor name="{link.joint}" joint="{link.joint}" gear="1"/>')
    lines += ["  </actuator>", "</mujoco>"]
    return "\n".join(lines) + "\n"
