"""Clearance from the mounting plane as optimal-control constraints (issue 27).

The safety check (:mod:`app.planning.safety`) finds a trajectory that dips a link below the
mounting plane; this module lets the optimal-control transcription keep the plane clear:

* every moving collision shape of the robot (as the safety check loads it: URDF
  ``<collision>``, meshes as convex hulls) is covered by spheres fixed in its joint's frame: its
  axis-aligned bounding box in its own frame is cut along its longest side into near-cubes, each
  inside its circumscribed sphere (the union of the boxes holds the shape, so the spheres do);
* the spheres' centres follow the symbolic forward kinematics
  (:meth:`app.planning.symbolic.SymbolicChain.joint_placements`), and at every evaluation point
  of the transcription (nodes and quarter points) ``z(centre) - radius >= plane + margin``.

Between the points the constraint is not guaranteed; the caller re-checks the solution with the
safety check and refines the mesh (:func:`app.planning.methods.run_optimal`). Obstacles are not
constrained here (only the plane).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app.planning.symbolic import symbolic_chain

if TYPE_CHECKING:
    from app.planning.robots import Robot
    from app.planning.safety import SafetyScene

__all__ = ["CLEARANCE_MARGIN", "ClearanceConstraint", "clearance_constraint"]

FloatArray = NDArray[np.float64]

#: Clearance kept between the covering spheres and the plane [m].
CLEARANCE_MARGIN = 0.005
#: Most spheres per collision shape.
_MAX_SPHERES = 8
#: Scale of the clearance rows in the NLP [m].
_ROW_SCALE = 0.1


@dataclass(frozen=True)
class ClearanceConstraint:
    """Spheres covering the robot's moving collision shapes, kept above a plane.

    Attributes:
        joints: (S,) the chain index (``robot.joint_names``) of each sphere's joint.
        centres: (S, 3) sphere centres in their joint's frame [m].
        radii: (S,) sphere radii [m].
        links: (S,) the link each sphere covers.
        plane: the mounting plane's height in the base frame [m].
        margin: clearance kept above the plane [m].
    """

    joints: tuple[int, ...]
    centres: FloatArray
    radii: FloatArray
    links: tuple[str, ...]
    plane: float
    margin: float = CLEARANCE_MARGIN

    @property
    def n_spheres(self) -> int:
        return len(self.joints)

    def key(self) -> tuple[Any, ...]:
        """What changes the NLP's structure (the numbers are constants of its graph)."""
        return (self.joints, self.centres.tobytes(), self.radii.tobytes(), self.plane, self.margin)

    def lowest(self, robot: Robot, q: Any) -> Any:
        """(S,) height of each sphere's lowest point above the plane minus the margin [m] at
        the (n,) configuration ``q`` (numbers or CasADi expressions)."""
        import casadi as ca

        poses = symbolic_chain(robot).joint_placements(q)
        rows = []
        for j, centre, radius in zip(self.joints, self.centres, self.radii, strict=True):
            rot, pos = poses[j]
            rows.append((rot[2, :] @ ca.DM(centre) + pos[2]) - float(radius))
        return ca.vertcat(*rows) - (self.plane + self.margin)

    def violations(self, robot: Robot, q: FloatArray) -> list[str]:
        """The links whose spheres cut the plane (+ margin) at the (n,) configuration ``q``."""
        values = np.asarray(self.lowest(robot, np.asarray(q, float)), dtype=float).ravel()
        return sorted({self.links[i] for i in np.flatnonzero(values < 0.0)})

    def constrain(self, robot: Robot, grid: Any, cons: Any) -> None:
        """The clearance rows at every evaluation point of the transcription's grid."""
        import casadi as ca

        q = ca.SX.sym("q", robot.n_joints)
        fn = ca.Function("clearance", [q], [self.lowest(robot, q)])
        values = fn.map(grid.point_q.shape[1])(grid.point_q)
        cons.add(values / _ROW_SCALE, 0.0, np.inf)


def _box_spheres(lo: FloatArray, hi: FloatArray) -> list[tuple[FloatArray, float]]:
    """Spheres covering the box [lo, hi]: near-cubes along its longest side [m]."""
    size = np.maximum(hi - lo, 0.0)
    axis = int(np.argmax(size))
    others = np.delete(size, axis)
    count = int(min(_MAX_SPHERES, max(1, math.ceil(size[axis] / max(others.max(), 1e-3)))))
    out = []
    for k in range(count):
        a, b = lo.copy(), hi.copy()
        a[axis] = lo[axis] + size[axis] * k / count
        b[axis] = lo[axis] + size[axis] * (k + 1) / count
        out.append(((a + b) / 2, float(np.linalg.norm(b - a) / 2)))
    return out


def _local_box(geometry: Any) -> tuple[FloatArray, FloatArray]:
    """The shape's axis-aligned bounding box in its own frame [m]."""
    if hasattr(geometry, "points"):  # a convex hull: its vertices are exact
        points = np.asarray(geometry.points(), dtype=float)
        return points.min(axis=0), points.max(axis=0)
    geometry.computeLocalAABB()
    box = geometry.aabb_local
    return np.asarray(box.min_, dtype=float), np.asarray(box.max_, dtype=float)


def clearance_constraint(
    robot: Robot, scene: SafetyScene, margin: float = CLEARANCE_MARGIN
) -> ClearanceConstraint | None:
    """The spheres of the robot's moving collision shapes above the scene's mounting plane.

    Returns:
        None when the scene has no plane or the robot has no collision geometry that moves.
    """
    import pinocchio as pin

    from app.planning.safety import _collision_model, _NotCheckable

    if scene.mount_plane_height is None:
        return None
    try:
        cm = _collision_model(robot, scene)
    except _NotCheckable:
        return None
    names = list(robot.joint_names)
    # Any configuration serves: a shape is fixed in its joint's frame.
    q = np.clip(np.zeros(len(names)), robot.q_min, robot.q_max)
    data = cm.model.createData()
    pin.forwardKinematics(cm.model, data, cm._pin_q(q)[0])
    gdata = cm.geom.createData()
    pin.updateGeometryPlacements(cm.model, data, cm.geom, gdata)
    joints: list[int] = []
    centres: list[FloatArray] = []
    radii: list[float] = []
    links: list[str] = []
    for g, obj in enumerate(cm.geom.geometryObjects):
        joint = int(obj.parentJoint)
        # The nearest free joint at or above the shape (locked joints are part of its body).
        while joint > 0 and cm.model.names[joint] not in names:
            joint = int(cm.model.parents[joint])
        if joint <= 0:
            continue  # fixed to the base: no motion keeps it clear
        relative = data.oMi[joint].inverse() * gdata.oMg[g]
        lo, hi = _local_box(obj.geometry)
        for centre, radius in _box_spheres(lo, hi):
            joints.append(names.index(cm.model.names[joint]))
            centres.append(np.asarray(relative.act(centre), dtype=float))
            radii.append(radius)
            links.append(cm.link[g])
    if not joints:
        return None
    return ClearanceConstraint(
        joints=tuple(joints),
        centres=np.array(centres, dtype=float),
        radii=np.array(radii, dtype=float),
        links=tuple(links),
        plane=float(scene.mount_plane_height),
        margin=margin,
    )
