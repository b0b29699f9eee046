"""Clearance from the mounting plane and the sidecar's obstacles as optimal-control constraints
(issue 27).

The safety check (:mod:`app.planning.safety`) finds a trajectory that dips a link below the
mounting plane or into an obstacle; this module lets the optimal-control transcription keep
them clear:

* every moving collision shape of the robot (as the safety check loads it: URDF
  ``<collision>``, meshes as convex hulls) is covered by spheres fixed in its joint's frame: its
  axis-aligned bounding box in its own frame is cut along its longest side into near-cubes, each
  inside its circumscribed sphere (the union of the boxes holds the shape, so the spheres do);
* the spheres' centres follow the symbolic forward kinematics
  (:meth:`app.planning.symbolic.SymbolicChain.joint_placements`), and at every evaluation point
  of the transcription (nodes and quarter points) ``z(centre) - radius >= plane + margin``;
* for every sidecar obstacle (:class:`app.planning.robots._obstacles.Obstacle`) and every
  sphere that can reach it, the sphere stays outside it by ``radius + margin``. A plane (a
  half-space) is one smooth row: the centre's signed distance along the normal. Outside a box
  or a cylinder is a disjunction, so each sphere, obstacle *and evaluation point* keeps one row
  chosen at the solve's initial guess (the warm start):

  - where the guess has the sphere clear, the exact distance from the centre to the obstacle
    (the norm of the ``max(|x_i| - h_i, 0)`` terms in the obstacle's frame; a cylinder's
    radial and axial excess), once differentiable, exact outside; inside it is 0 with no useful
    gradient, hence
  - where the guess cuts the obstacle, a *face*: a box's six face planes; a cylinder's curved
    side (``sqrt(x² + y²) >= R + radius + margin`` in its frame) or one of its caps. The run of
    such points keeps the face it entered by, then the face it leaves by (switching where the
    second becomes the better); when those are opposite (it passes through), it goes round by
    a third face, one for every sphere passing through the obstacle that way: the face they
    are least inside over their runs (:func:`_choose_faces`, :func:`_detours`). Being beyond one
    face plane is sufficient, not necessary (near an edge the exact distance is larger).

  The choice is an NLP parameter (a one-hot weight per row), so the solver built for one choice
  serves the next; a re-solve warm-started from the last solution chooses again.

Only pairs that can come near get rows: a sphere's centre stays within the sum of the joint
offsets below its chain's first joint (plus its own offset) of that joint's fixed origin; a
pair whose obstacle is further than that reach plus the radius and the margin cannot touch.

Between the evaluation points the constraints are not guaranteed; the caller re-checks the
solution with the safety check and refines the mesh (:func:`app.planning.methods.run_optimal`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app.planning.symbolic import symbolic_chain

if TYPE_CHECKING:
    from app.planning.robots import Obstacle, Robot
    from app.planning.safety import SafetyScene

__all__ = ["CLEARANCE_MARGIN", "ClearanceConstraint", "ObstacleRows", "clearance_constraint"]

FloatArray = NDArray[np.float64]

#: Clearance kept between the covering spheres and the plane or an obstacle [m].
CLEARANCE_MARGIN = 0.005
#: Most spheres per collision shape.
_MAX_SPHERES = 8
#: Scale of the clearance rows in the NLP [m].
_ROW_SCALE = 0.1
#: Smoothing of the norms at zero [m] (``sqrt(x² + y² + ε²) - ε`` is at most the true norm:
#: the rows stay conservative).
_AXIS_EPS = 1e-6
#: Rows per obstacle kind: its faces, then (box, cylinder) the exact distance from outside.
_FACES = {"plane": 1, "box": 7, "cylinder": 4}
#: Each face's opposite (a sphere cannot go from beyond one to beyond the other between points).
_OPPOSITE = {
    "plane": {},
    "box": {0: 1, 1: 0, 2: 3, 3: 2, 4: 5, 5: 4},
    "cylinder": {1: 2, 2: 1},
}


@dataclass(frozen=True)
class ObstacleRows:
    """One obstacle in the frame its faces are written in, and the spheres that can reach it.

    Attributes:
        name: the obstacle's name (as the safety check reports it).
        kind: ``plane``, ``box`` or ``cylinder``.
        rotation: (3, 3) the obstacle's frame in the base frame (a plane's local z is its
            normal, pointing to the free side).
        origin: (3,) the frame's origin in the base frame [m] (a plane's point).
        half: (3,) a box's half extents; a cylinder's (radius, radius, half length); zeros for a
            plane [m].
        spheres: indices of the constraint's spheres kept out of it.
    """

    name: str
    kind: str
    rotation: FloatArray
    origin: FloatArray
    half: FloatArray
    spheres: tuple[int, ...]

    @property
    def n_faces(self) -> int:
        return _FACES[self.kind]

    def key(self) -> tuple[Any, ...]:
        return (self.name, self.kind, self.rotation.tobytes(), self.origin.tobytes(),
                self.half.tobytes(), self.spheres)  # fmt: skip

    def faces(self, centre: Any) -> list[Any]:
        """How far the point ``centre`` (3, 1) [m] (CasADi) lies beyond each face [m]
        (negative: on the obstacle's side of it; box: +x, -x, +y, -y, +z, -z of its frame;
        cylinder: curved side, top cap, bottom cap), then (box, cylinder) its distance to the
        obstacle [m] (0 inside; once differentiable: the square root of a sum of squared
        ``max(·, 0)`` terms, smoothed by ε)."""
        import casadi as ca

        p = ca.DM(self.rotation).T @ (centre - ca.DM(self.origin))
        hx, hy, hz = (float(v) for v in self.half)
        if self.kind == "plane":
            return [p[2]]

        def norm(*values: Any) -> Any:
            return ca.sqrt(sum(v**2 for v in values) + _AXIS_EPS**2) - _AXIS_EPS

        if self.kind == "box":
            faces = [p[0] - hx, -p[0] - hx, p[1] - hy, -p[1] - hy, p[2] - hz, -p[2] - hz]
            out = [ca.fmax(ca.fabs(p[i]) - h, 0.0) for i, h in enumerate((hx, hy, hz))]
            return [*faces, norm(*out)]
        radial = norm(p[0], p[1])
        axial = ca.fmax(ca.fabs(p[2]) - hz, 0.0)
        return [radial - hx, p[2] - hz, -p[2] - hz, norm(ca.fmax(radial - hx, 0.0), axial)]

    def distance(self, point: FloatArray) -> float:
        """Distance from ``point`` (3,) [m] to the obstacle [m] (signed for a plane; 0 inside a
        box or a cylinder)."""
        p = self.rotation.T @ (np.asarray(point, dtype=float) - self.origin)
        if self.kind == "plane":
            return float(p[2])
        if self.kind == "box":
            return float(np.linalg.norm(np.maximum(np.abs(p) - self.half, 0.0)))
        radial = max(float(np.hypot(p[0], p[1])) - float(self.half[0]), 0.0)
        return float(np.hypot(radial, max(abs(float(p[2])) - float(self.half[2]), 0.0)))


@dataclass(frozen=True)
class ClearanceConstraint:
    """Spheres covering the robot's moving collision shapes, kept above a plane and out of the
    obstacles.

    Attributes:
        joints: (S,) the chain index (``robot.joint_names``) of each sphere's joint.
        centres: (S, 3) sphere centres in their joint's frame [m].
        radii: (S,) sphere radii [m].
        links: (S,) the link each sphere covers.
        plane: the mounting plane's height in the base frame [m], or None (not kept).
        margin: clearance kept from the plane and the obstacles [m].
        obstacles: the obstacles some sphere can reach, with those spheres.
    """

    joints: tuple[int, ...]
    centres: FloatArray
    radii: FloatArray
    links: tuple[str, ...]
    plane: float | None
    margin: float = CLEARANCE_MARGIN
    obstacles: tuple[ObstacleRows, ...] = ()

    @property
    def n_spheres(self) -> int:
        return len(self.joints)

    @property
    def n_pairs(self) -> int:
        """Sphere-obstacle pairs with rows."""
        return sum(len(o.spheres) for o in self.obstacles)

    def describe(self) -> str:
        """What is kept clear: ``mount plane, obstacle 'table'``."""
        what = [] if self.plane is None else ["mount plane"]
        return ", ".join(what + [f"obstacle '{o.name}'" for o in self.obstacles])

    def key(self) -> tuple[Any, ...]:
        """What changes the NLP's structure (the numbers are constants of its graph; the faces
        chosen are parameters)."""
        return (self.joints, self.centres.tobytes(), self.radii.tobytes(), self.plane,
                self.margin, tuple(o.key() for o in self.obstacles))  # fmt: skip

    def n_parameters(self, n_points: int) -> int:
        """Size of the face-choice parameter for ``n_points`` evaluation points."""
        return n_points * sum(len(o.spheres) * o.n_faces for o in self.obstacles)

    def _centres(self, robot: Robot, q: Any) -> list[Any]:
        """(3, 1) base-frame centre of every sphere at ``q`` (CasADi)."""
        import casadi as ca

        poses = symbolic_chain(robot).joint_placements(q)
        out = []
        for j, centre in zip(self.joints, self.centres, strict=True):
            rot, pos = poses[j]
            out.append(rot @ ca.DM(centre) + pos)
        return out

    def lowest(self, robot: Robot, q: Any) -> Any:
        """(S,) height of each sphere's lowest point above the plane minus the margin [m] at
        the (n,) configuration ``q`` (numbers or CasADi expressions); empty without a plane."""
        import casadi as ca

        if self.plane is None:
            return ca.DM(0, 1)
        rows = [c[2] - float(r) for c, r in zip(self._centres(robot, q), self.radii, strict=True)]
        return ca.vertcat(*rows) - (self.plane + self.margin)

    def beyond(self, robot: Robot, q: Any, obstacle: ObstacleRows) -> Any:
        """(P R,) how far each of ``obstacle``'s spheres is beyond each of its rows (faces,
        then the exact distance) less its radius and the margin [m], sphere-major, at the
        configuration ``q`` (CasADi)."""
        import casadi as ca

        centres = self._centres(robot, q)
        rows: list[Any] = []
        for s in obstacle.spheres:
            clear = float(self.radii[s]) + self.margin
            rows.extend(f - clear for f in obstacle.faces(centres[s]))
        return ca.vertcat(*rows)

    def violations(self, robot: Robot, q: FloatArray) -> list[str]:
        """The links whose spheres cut the plane (+ margin) at the (n,) configuration ``q``."""
        values = np.asarray(self.lowest(robot, np.asarray(q, float)), dtype=float).ravel()
        return sorted({self.links[i] for i in np.flatnonzero(values < 0.0)})

    def blocked(self, robot: Robot, q: FloatArray) -> list[tuple[str, list[str]]]:
        """What the (n,) configuration ``q`` does not keep clear by the margin: (``the mount
        plane`` or ``obstacle 'NAME'``, its links), for each one with a link too close (an
        obstacle's link is one whose sphere is beyond none of its faces)."""
        out = []
        links = self.violations(robot, q)
        if links:
            out.append(("the mount plane", links))
        q = np.asarray(q, dtype=float)
        for obstacle in self.obstacles:
            values = np.asarray(self.beyond(robot, q, obstacle), dtype=float).ravel()
            best = values.reshape(len(obstacle.spheres), obstacle.n_faces)[:, -1]
            inside = {self.links[obstacle.spheres[i]] for i in np.flatnonzero(best < 0.0)}
            if inside:
                out.append((f"obstacle '{obstacle.name}'", sorted(inside)))
        return out

    def constrain(
        self, robot: Robot, grid: Any, cons: Any, par: Any = None, guess: Any = None
    ) -> None:
        """The clearance rows at every evaluation point of the transcription's grid.

        Args:
            robot: the robot.
            grid: the transcription's grid (``point_q``: (n, K) symbolic positions).
            cons: the constraint rows.
            par: the NLP parameters, with a ``faces`` block of :meth:`n_parameters` (K) (only
                used with obstacles).
            guess: (n, K) positions at the evaluation points in the initial guess [rad]: the
                faces are chosen there (only used with obstacles).
        """
        import casadi as ca

        q = ca.SX.sym("q", robot.n_joints)
        points = int(grid.point_q.shape[1])
        if self.plane is not None:
            fn = ca.Function("clearance", [q], [self.lowest(robot, q)])
            values = fn.map(points)(grid.point_q)
            cons.add(values / _ROW_SCALE, 0.0, np.inf)
        if not self.obstacles:
            return
        if par is None or guess is None:
            raise ValueError("obstacle clearance needs the NLP parameters and the initial guess")
        block = par.index["faces"]
        offset = block.start
        # Point blocks are one per fraction of the interval (N columns each): time order.
        n = int(grid.h.shape[1])
        fractions = points // n
        column = np.arange(points)
        order = np.argsort(column % n + (column // n) / max(fractions - 1, 1), kind="stable")
        choices = []
        for obstacle in self.obstacles:
            pairs, faces = len(obstacle.spheres), obstacle.n_faces
            fn = ca.Function("beyond", [q], [self.beyond(robot, q, obstacle)]).map(points)
            size = pairs * faces * points
            # The face each sphere keeps at each point, chosen at the guess (one-hot).
            start = np.asarray(fn(np.asarray(guess, dtype=float)), dtype=float)  # (P F, K)
            beyond = start.reshape(pairs, faces, points)[:, :, order]
            best = np.empty((pairs, points), dtype=int)
            opposite = _OPPOSITE[obstacle.kind]
            detours = _detours(list(beyond), opposite) if faces > 1 else {}
            for p in range(pairs):
                best[p, order] = _choose_faces(beyond[p], opposite, detours)
            onehot = np.zeros((pairs, faces, points))
            np.put_along_axis(onehot, best[:, None, :], 1.0, axis=1)
            # CasADi's reshape is column-major: the parameter runs point by point, then sphere.
            choices.append(onehot.transpose(2, 0, 1).reshape(-1))
            weights = ca.reshape(par.sym[offset : offset + size], pairs * faces, points)
            # One row per sphere and point, the weights inside the mapped function: its
            # derivatives then have P outputs per point, not P R.
            w = ca.SX.sym("w", pairs * faces)
            each = ca.reshape(w * self.beyond(robot, q, obstacle), faces, pairs)
            chosen = ca.Function("chosen", [q, w], [ca.sum1(each).T]).map(points)
            cons.add(chosen(grid.point_q, weights) / _ROW_SCALE, 0.0, np.inf)
            offset += size
        if offset != block.stop:
            raise ValueError("the face-choice parameter has the wrong size")
        par.values[block] = np.concatenate(choices)


def _runs(beyond: FloatArray) -> list[tuple[int, int, int, int]]:
    """The runs of points where one sphere cuts a box or a cylinder in the guess, in time
    order: (first, end (exclusive), face A before, face B after) (see :func:`_choose_faces`).

    Args:
        beyond: (R, K) how far beyond each row (faces, then the exact distance), less radius
            and margin, at each point [m].
    """
    faces, points = beyond[:-1], beyond.shape[1]
    inside = beyond[-1] < 0.0
    out = []
    k = 0
    while k < points:
        if not inside[k]:
            k += 1
            continue
        end = k
        while end < points and inside[end]:
            end += 1
        a = int(faces[:, k - 1 if k > 0 else end % points].argmax())
        b = int(faces[:, end].argmax()) if end < points else a
        out.append((k, end, a, b))
        k = end
    return out


def _detours(beyond: list[FloatArray], opposite: dict[int, int]) -> dict[tuple[int, int], int]:
    """The face every sphere of one obstacle goes round by when it passes through between two
    opposite faces: per pair of opposite faces, the other face that the spheres passing
    through are least inside of over their runs (one face for all, so that spheres of one link
    are not sent round opposite sides).

    Args:
        beyond: per sphere, (R, K) as for :func:`_runs`.
        opposite: face -> its opposite face.
    """
    worst: dict[tuple[int, int], FloatArray] = {}
    for values in beyond:
        for k, end, a, b in _runs(values):
            if opposite.get(a) == b:
                key = (min(a, b), max(a, b))
                least = values[:-1, k:end].min(axis=1)
                worst[key] = np.minimum(worst[key], least) if key in worst else least
    out = {}
    for key, least in worst.items():
        others = [f for f in range(least.size) if f not in key]
        out[key] = max(others, key=lambda f: float(least[f]))
    return out


def _choose_faces(
    beyond: FloatArray, opposite: dict[int, int], detours: dict[tuple[int, int], int]
) -> NDArray[np.int_]:
    """The row one sphere keeps at each evaluation point, in time order.

    A plane has one row. For a box or a cylinder, the last row is the exact distance: kept
    wherever the guess has the sphere clear (by its radius and the margin). A run of points
    where the guess cuts the obstacle lies between a face A before (the face the sphere is
    furthest beyond there) and B after (the ends are clear: checked before solving); there the
    exact distance has no useful gradient, so the run keeps a face: A, then B where B becomes
    the better of the two; when A and B are opposite faces (it passes through) it goes round by
    a third face C (:func:`_detours`): A, then C (one point at least), then B, each switch
    where the next face becomes the better. Consecutive points thus never ask for opposite
    sides.

    Args:
        beyond: (R, K) how far beyond each row's face or distance, less radius and margin, at
            each point [m].
        opposite: face -> its opposite face.
        detours: (lower, higher) opposite faces -> the face to go round by.

    Returns:
        (K,) the row index at each point.
    """
    rows, points = beyond.shape
    if rows == 1:
        return np.zeros(points, dtype=int)
    faces = beyond[:-1]
    best = np.full(points, rows - 1, dtype=int)
    for k, end, a, b in _runs(beyond):
        run = faces[:, k:end]
        if opposite.get(a) == b:
            c = detours[(min(a, b), max(a, b))]
            s1 = _switch(run[a], run[c], 0)
            s2 = max(_switch(run[c], run[b], s1), s1 + 1)  # C for one point at least
            best[k : k + s1], best[k + s1 : k + s2], best[k + s2 : end] = a, c, b
        else:
            s1 = _switch(run[a], run[b], 0, fallback=end - k)
            best[k : k + s1], best[k + s1 : end] = a, b
    return best


def _switch(now: FloatArray, then: FloatArray, first: int, fallback: int | None = None) -> int:
    """The first index from ``first`` where ``then`` is at least ``now``; else ``fallback``
    (None: where ``then`` comes nearest)."""
    ahead = np.flatnonzero(then[first:] >= now[first:])
    if ahead.size:
        return first + int(ahead[0])
    if fallback is not None:
        return fallback
    return first + int(np.argmax(then[first:] - now[first:]))


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


def _frame(obstacle: Obstacle) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(rotation (3, 3), origin (3,), half sizes (3,)) of an obstacle's face frame [m]."""
    import pinocchio as pin

    origin = np.asarray(obstacle.position, dtype=float)
    if obstacle.kind == "plane":
        z = np.asarray(obstacle.normal, dtype=float)
        z = z / np.linalg.norm(z)
        seed = np.eye(3)[int(np.argmin(np.abs(z)))]  # any direction not along the normal
        x = np.cross(seed, z)
        x /= np.linalg.norm(x)
        return np.column_stack([x, np.cross(z, x), z]), origin, np.zeros(3)
    rotation = np.asarray(pin.rpy.rpyToMatrix(*obstacle.rpy), dtype=float)
    if obstacle.kind == "box":
        return rotation, origin, np.asarray(obstacle.size, dtype=float) / 2
    r, half = float(obstacle.radius), float(obstacle.length) / 2
    return rotation, origin, np.array([r, r, half])


def _reach(
    robot: Robot, joints: list[int], centres: list[FloatArray]
) -> list[tuple[FloatArray, float]]:
    """For each sphere, a fixed point (its chain's first joint's origin) [m] and the farthest
    its centre can be from it in any configuration [m] (joint offsets below, plus its own)."""
    bodies = symbolic_chain(robot).bodies
    out = []
    for j, centre in zip(joints, centres, strict=True):
        reach = float(np.linalg.norm(centre))
        k = j
        while bodies[k].parent >= 0:
            reach += float(np.linalg.norm(bodies[k].translation))
            k = bodies[k].parent
        out.append((np.asarray(bodies[k].translation, dtype=float), reach))
    return out


def clearance_constraint(
    robot: Robot, scene: SafetyScene, margin: float = CLEARANCE_MARGIN
) -> ClearanceConstraint | None:
    """The spheres of the robot's moving collision shapes above the scene's mounting plane and
    out of its obstacles (those the spheres can reach).

    Returns:
        None when the scene has neither a plane nor an obstacle some sphere can reach, or the
        robot has no collision geometry that moves.
    """
    import pinocchio as pin

    from app.planning.safety import _collision_model, _NotCheckable

    if scene.mount_plane_height is None and not scene.obstacles:
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
        if cm.link[g] == "":
            continue  # the scene's own plane and obstacles
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
    reach = _reach(robot, joints, centres)
    obstacles = []
    for obstacle in scene.obstacles:
        rotation, origin, half = _frame(obstacle)
        rows = ObstacleRows(obstacle.name, obstacle.kind, rotation, origin, half, ())
        near = tuple(
            s
            for s, (anchor, far) in enumerate(reach)
            if rows.distance(anchor) <= far + radii[s] + margin
        )
        if near:
            obstacles.append(
                ObstacleRows(obstacle.name, obstacle.kind, rotation, origin, half, near)
            )
    plane = scene.mount_plane_height
    if plane is None and not obstacles:
        return None
    return ClearanceConstraint(
        joints=tuple(joints),
        centres=np.array(centres, dtype=float),
        radii=np.array(radii, dtype=float),
        links=tuple(links),
        plane=None if plane is None else float(plane),
        margin=margin,
        obstacles=tuple(obstacles),
    )
