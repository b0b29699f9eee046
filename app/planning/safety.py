"""Collision and workspace checks of planned trajectories with the robot's own collision geometry.

Every method's trajectory is checked for

* ``self`` collision between links of the robot (pairs on the same rigid body and adjacent
  links, parent and child, excluded; an SRDF's disabled pairs removed when one is given),
* ``plane``: a moving link below the mounting plane (a height in the base frame, 0 m unless
  the sidecar or the robot says otherwise; geometry fixed to the base is mounted on it),
* ``obstacle``: a moving link inside a sidecar obstacle (box, cylinder or plane).

The geometry is the URDF's ``<collision>`` elements, loaded by Pinocchio into coal shapes;
meshes are replaced by their convex hulls (a hull contains its mesh, so a distance to it is a
lower bound: no contact is missed, a concave link may be reported too close). Distances are
signed (negative = penetration, its depth).

Nothing passes between samples (``SWEEP``): between two samples every point of a link moves at
most ``sum_j R_j |Δq_j|`` (``R_j``: a configuration-independent bound on the distance from
joint ``j``'s axis to any point of the link's geometry, from the joint offsets along the chain
and the geometry's bounding sphere), so a pair whose distances at the two ends are ``d0``,
``d1`` and whose relative motion is bounded by ``D`` keeps at least ``(d0 + d1 - D) / 2`` in
between. An interval where that bound is not positive is bisected (cubic Hermite interpolation
of the samples' positions and speeds) until it is, or a contact is found, or the motion left is
below ``margin`` (then reported as a contact within the margin). Joint motion within one
sample interval is taken as monotone (its path length is ``|Δq|``).

The same bound lets the check skip samples (conservative advancement): from an evaluated
sample, every later sample whose accumulated motion bound stays below every pair's |distance|
keeps each pair's state (clear or in contact), so only the last of them is evaluated. Depths
and the minimum clearance are those of the evaluated samples; first contact times are exact to
the sample (a pair's state can only change across a sample interval that was evaluated).
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from app.planning.robots import Obstacle, Robot, RobotError

__all__ = [
    "DEFAULT_MARGIN",
    "NOT_CHECKED_NO_GEOMETRY",
    "NOT_CHECKED_NO_PAIRS",
    "SWEEP",
    "Finding",
    "SafetyReport",
    "SafetyScene",
    "check_safety",
    "default_scene",
    "not_checked",
    "safety_summary",
]

logger = logging.getLogger("bioplan.planning")

FloatArray = NDArray[np.float64]

#: Motion [m] below which an interval is not split further (the resolution of the check).
DEFAULT_MARGIN = 1e-4
#: Most samples one advancement step looks ahead.
_WINDOW = 256
#: Deepest bisection of one sample interval (2^-30 of it).
_MAX_SPLITS = 30
#: The reason given for a robot without collision geometry on its moving links.
NOT_CHECKED_NO_GEOMETRY = "not checked: the robot has no collision geometry"
#: The reason given when no two links can touch and neither a plane nor an obstacle is set.
NOT_CHECKED_NO_PAIRS = (
    "not checked: nothing can touch (no two non-adjacent links with collision geometry, no "
    "mounting plane, no obstacle)"
)
#: How the check covers the time between samples (reported with every result).
SWEEP = (
    "conservative advancement: every interval between samples is bounded by the links' "
    "largest motion and bisected until the bound clears or a contact is found; contacts "
    "within the margin count"
)
#: Shoulder height as a fraction of body height (Drillis and Contini, as tabulated by Winter,
#: Biomechanics and Motor Control of Human Movement): the human arm's floor lies this far
#: below its shoulder, its base frame.
SHOULDER_HEIGHT_RATIO = 0.818


class _Samples(Protocol):
    """A sampled trajectory: (T,) times [s], (T, n) positions [rad] and speeds [rad/s]."""

    @property
    def t(self) -> FloatArray: ...

    @property
    def q(self) -> FloatArray: ...

    @property
    def qd(self) -> FloatArray: ...


@dataclass(frozen=True)
class SafetyScene:
    """What the robot must not touch.

    Attributes:
        mount_plane_height: the mounting plane's height in the base frame [m], or None (no
            plane check).
        obstacles: fixed obstacles in the base frame.
        srdf: an SRDF whose ``disable_collisions`` pairs are not checked, or None.
    """

    mount_plane_height: float | None = 0.0
    obstacles: tuple[Obstacle, ...] = ()
    srdf: Path | None = None


@dataclass(frozen=True)
class Finding:
    """One pair in contact during one method's trajectory.

    Attributes:
        method: the method's name.
        time: the first time the pair is in contact [s].
        kind: ``self``, ``plane`` or ``obstacle``.
        links: the robot's links involved (two for ``self``, one otherwise).
        obstacle: ``mount plane`` or the obstacle's name (None for ``self``).
        depth: the deepest penetration at the evaluated samples [m] (>= 0; for a contact
            found only between samples, the depth where it was found).
        deepest_time: when it is deepest [s].
        between_samples: True when the contact lies between two samples (found by bisection).
    """

    method: str
    time: float
    kind: str
    links: tuple[str, ...]
    obstacle: str | None
    depth: float
    deepest_time: float
    between_samples: bool = False

    def describe(self) -> str:
        """One line: ``quintic: wrist_1_link below the mount plane from 0.312 s, 428.8 mm deep
        at 1.126 s``."""
        return _describe(self.to_dict())

    def to_dict(self) -> dict[str, Any]:
        # The fields in their order; ``links`` as a JSON list.
        return {**asdict(self), "links": list(self.links)}


@dataclass(frozen=True)
class SafetyReport:
    """The check of every method's trajectory.

    Attributes:
        checked: False when the robot could not be checked (``reason`` says why).
        ok: True when nothing touches, False with findings, None when not checked.
        reason: why not checked, or None.
        min_clearance: the smallest signed distance of any checked pair over every method [m]
            (negative: the deepest penetration), None when not checked.
        margin: the resolution of the between-samples check [m]: a pair closer than this
            between two samples counts as a contact.
        findings: every pair in contact, per method, in time order.
        mount_plane_height: the plane checked [m], or None.
        obstacles: the obstacles' names.
        pairs: how many pairs were checked (self, plane, obstacle).
    """

    checked: bool
    ok: bool | None
    reason: str | None = None
    min_clearance: float | None = None
    margin: float = DEFAULT_MARGIN
    findings: tuple[Finding, ...] = ()
    mount_plane_height: float | None = None
    obstacles: tuple[str, ...] = ()
    pairs: Mapping[str, int] = field(default_factory=dict)

    def summary(self) -> str:
        """One line: ``ok (min clearance 12.3 mm)``, the first finding, or why not checked."""
        return safety_summary(self.to_dict())

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "ok": self.ok,
            "checked": self.checked,
            "min_clearance": self.min_clearance,
            "margin": self.margin,
            "findings": [f.to_dict() for f in self.findings],
            "sweep": SWEEP,
            "mount_plane_height": self.mount_plane_height,
            "obstacles": list(self.obstacles),
            "pairs": dict(self.pairs),
        }
        if self.reason is not None:
            out["reason"] = self.reason
        return out


def _describe(finding: Mapping[str, Any]) -> str:
    links = list(finding.get("links") or ["?"])
    if finding.get("kind") == "self":
        what = f"{links[0]} touches {links[-1]}"
    elif finding.get("kind") == "plane":
        what = f"{links[0]} below the {finding.get('obstacle')}"
    else:
        what = f"{links[0]} inside obstacle '{finding.get('obstacle')}'"
    return (
        f"{finding.get('method')}: {what} from {float(finding.get('time', math.nan)):.3f} s, "
        f"{1000 * float(finding.get('depth', math.nan)):.1f} mm deep at "
        f"{float(finding.get('deepest_time', math.nan)):.3f} s"
    )


def safety_summary(safety: Mapping[str, Any] | None) -> str:
    """One line for a report's dict (``SafetyReport.to_dict()``, a stored plan's ``safety``):
    ``ok (min clearance 12.3 mm)``, ``UNSAFE: <first finding> (+N more)`` or why not checked."""
    if not safety or safety.get("checked") is not True:
        reason = None if not safety else safety.get("reason")
        return str(reason or "not checked")
    findings = list(safety.get("findings") or [])
    if safety.get("ok") is True or not findings:
        clearance = safety.get("min_clearance")
        shown = "n/a" if clearance is None else f"{1000 * float(clearance):.1f} mm"
        return f"ok (min clearance {shown})"
    tail = f" (+{len(findings) - 1} more)" if len(findings) > 1 else ""
    return f"UNSAFE: {_describe(findings[0])}{tail}"


def not_checked(reason: str) -> SafetyReport:
    """A report for a robot or plan that was not checked (``ok`` None, never True)."""
    return SafetyReport(checked=False, ok=None, reason=reason)


def _default_plane(robot: Robot) -> float:
    """The robot's own mounting plane [m]: 0 for arms; the floor for the human arm, whose base
    frame is the shoulder."""
    if robot.spec.get("source") == "human_arm_2dof":
        return -SHOULDER_HEIGHT_RATIO * float(robot.spec.get("body_height", 1.75))
    return 0.0


def default_scene(robot: Robot) -> SafetyScene:
    """The scene of a robot: its sidecar's obstacles, mounting plane and SRDF (``robot.spec``),
    else the robot's default plane and no obstacles.

    Raises:
        RobotError: the sidecar named in the spec cannot be read.
    """
    height: float | None = _default_plane(robot)
    sidecar = robot.spec.get("sidecar")
    if not sidecar:
        return SafetyScene(mount_plane_height=height)
    from app.planning.robots import read_sidecar

    car = read_sidecar(Path(sidecar))
    plane = car.mount_plane
    if plane is not None and plane.height is not None:
        height = plane.height
    if plane is not None and not plane.enabled:
        height = None
    return SafetyScene(mount_plane_height=height, obstacles=tuple(car.obstacles), srdf=car.srdf)


def check_safety(
    robot: Robot,
    trajectories: Mapping[str, _Samples],
    *,
    scene: SafetyScene | None = None,
    margin: float = DEFAULT_MARGIN,
) -> SafetyReport:
    """Check every trajectory for self-collision, the mounting plane and the obstacles.

    Args:
        robot: the robot (its URDF's ``<collision>`` geometry is used; locked joints held).
        trajectories: method name -> trajectory with ``t`` (T,) [s], ``q`` and ``qd`` (T, n)
            in ``robot.joint_names`` order [rad, rad/s].
        scene: plane, obstacles and SRDF; default ``default_scene(robot)``.
        margin: resolution of the between-samples check [m] (> 0).

    Returns:
        The report; ``checked`` False (``ok`` None) when the robot has no collision geometry
        on its moving links or its collision meshes cannot be loaded.
    """
    if not margin > 0.0:
        raise RobotError(f"safety margin is {margin}: expected a distance > 0 m")
    try:
        scene = default_scene(robot) if scene is None else scene
        model = _collision_model(robot, scene)
    except _NotCheckable as exc:
        return not_checked(str(exc))
    except RobotError as exc:  # the robot's sidecar is gone or changed since it was loaded
        return not_checked(f"not checked: {exc}")
    logger.debug("safety: %d pairs, %d trajectories", len(model.pairs), len(trajectories))
    findings: list[Finding] = []
    clearance = math.inf
    for name, trajectory in trajectories.items():
        model.fresh_data()  # each result independent of what the model checked before
        found, low = model.check(name, trajectory, margin)
        findings.extend(found)
        clearance = min(clearance, low)
    return SafetyReport(
        checked=True,
        ok=not findings,
        min_clearance=None if math.isinf(clearance) else float(clearance),
        margin=margin,
        findings=tuple(findings),
        mount_plane_height=scene.mount_plane_height,
        obstacles=tuple(o.name for o in scene.obstacles),
        pairs=model.pair_counts(),
    )


class _NotCheckable(Exception):
    """The robot cannot be checked (the message is the report's reason)."""


def _collision_model(robot: Robot, scene: SafetyScene) -> _CollisionModel:
    """The robot's collision model for a scene, cached on the robot (meshes load once)."""
    key = ("safety", scene)
    if key not in robot._cache:
        robot._cache[key] = _CollisionModel(robot, scene)
    model: _CollisionModel = robot._cache[key]
    return model


#: Largest collision mesh file read [bytes] (a robot's link meshes are kilobytes to megabytes).
MAX_MESH_BYTES = 64 * 1024 * 1024


def _mesh_search(robot: Robot) -> list[str]:
    """Folders Pinocchio may search for ``package://`` meshes, after every collision mesh the
    URDF names was found the way the viewer finds them (``resolve_mesh``).

    ``package://NAME/...`` resolves in the robot's ``package_dirs`` and in the URDF's ancestor
    named ``NAME`` (example-robot-data's layout), never in an arbitrary folder. A robot with
    ``package_dirs`` (a package, an upload) must keep its meshes inside them or its URDF's
    folder; any mesh must be a regular file of at most ``MAX_MESH_BYTES``.

    Raises:
        _NotCheckable: a mesh is missing, outside those folders, not a file or too large.
    """
    from app.planning.robots import read_xml, resolve_mesh

    urdf = Path(robot.urdf_path).resolve()
    roots = [*robot.package_dirs, urdf.parent] if robot.package_dirs else None
    names: set[str] = set()
    for mesh in read_xml(urdf, "URDF").iterfind("./link/collision/geometry/mesh"):
        reference = mesh.get("filename", "")
        if reference.startswith("package://"):
            names.add(reference[len("package://") :].partition("/")[0])
        found = resolve_mesh(
            reference, base_dir=urdf.parent, package_dirs=robot.package_dirs, allowed_roots=roots
        )
        if found is None or found.stat().st_size > MAX_MESH_BYTES:
            why = "not found" if found is None else f"larger than {MAX_MESH_BYTES} bytes"
            raise _NotCheckable(
                f"not checked: the collision geometry of {urdf.name} cannot be loaded "
                f"(mesh {Path(reference).name} {why})"
            )
    dirs = [str(p) for p in robot.package_dirs]
    dirs += [str(a.parent) for a in urdf.parents if a.name in names]
    return dirs


def _convex(geometry: Any) -> Any:
    """A mesh's convex hull (contains the mesh), other shapes unchanged."""
    import coal  # type: ignore[import-untyped]

    if not isinstance(geometry, coal.BVHModelBase):
        return geometry
    points = [np.asarray(v, dtype=float) for v in np.asarray(geometry.vertices())]
    return coal.Convex.convexHull(points, False, "")


def _bounding_radius(geometry: Any, placement: Any) -> float:
    """Largest distance [m] from the joint frame's origin to any point of the geometry."""
    if hasattr(geometry, "points"):  # a convex hull: its vertices are exact
        points = np.asarray(geometry.points())
        world = points @ np.asarray(placement.rotation).T + np.asarray(placement.translation)
        return float(np.linalg.norm(world, axis=1).max())
    geometry.computeLocalAABB()
    centre = np.asarray(placement.act(np.asarray(geometry.aabb_center, dtype=float)))
    return float(np.linalg.norm(centre) + geometry.aabb_radius)


def _is_prismatic(shortname: str) -> bool:
    """Pinocchio's prismatic joint models (``JointModelPX``, ..., ``...PrismaticUnaligned``)."""
    return shortname in ("JointModelPX", "JointModelPY", "JointModelPZ") or "Prismatic" in shortname


def _obstacle_geometry(obstacle: Obstacle) -> tuple[Any, Any]:
    """The coal shape and placement of an obstacle."""
    import coal
    import pinocchio as pin

    if obstacle.kind == "plane":
        normal = np.asarray(obstacle.normal, dtype=float)
        offset = float(normal @ np.asarray(obstacle.position, dtype=float))
        return coal.Halfspace(normal, offset), pin.SE3.Identity()
    rotation = pin.rpy.rpyToMatrix(*obstacle.rpy)
    placement = pin.SE3(rotation, np.asarray(obstacle.position, dtype=float))
    if obstacle.kind == "box":
        return coal.Box(*obstacle.size), placement
    return coal.Cylinder(obstacle.radius, obstacle.length), placement


@dataclass
class _Pair:
    index: int
    kind: str
    links: tuple[str, ...]
    obstacle: str | None


class _CollisionModel:
    """Pinocchio model + coal geometry of a robot in a scene, with the pairs to check."""

    def __init__(self, robot: Robot, scene: SafetyScene) -> None:
        import pinocchio as pin

        self.model = pin.buildModelFromUrdf(str(robot.urdf_path))
        try:
            geom = pin.buildGeomFromUrdf(
                self.model,
                str(robot.urdf_path),
                pin.GeometryType.COLLISION,
                package_dirs=_mesh_search(robot),
            )
        except (ValueError, RuntimeError) as exc:
            # Only the mesh's file name is quoted: the message may reach an API client, and
            # the server's folders are not theirs to read.
            missing = re.search(r"Mesh (\S+) could not be found", str(exc))
            what = f"mesh {Path(missing.group(1)).name} not found" if missing else "unreadable"
            raise _NotCheckable(
                f"not checked: the collision geometry of {Path(robot.urdf_path).name} cannot be "
                f"loaded ({what})"
            ) from None
        for obj in geom.geometryObjects:
            obj.geometry = _convex(obj.geometry)
        robot_geoms = [i for i, o in enumerate(geom.geometryObjects) if o.parentJoint > 0]
        if not robot_geoms:
            raise _NotCheckable(NOT_CHECKED_NO_GEOMETRY)
        self.geom = geom
        self.link = [self.model.frames[o.parentFrame].name for o in geom.geometryObjects]
        self._configuration_map(robot)
        self.pairs: list[_Pair] = []
        self._self_pairs(scene)
        self._world_pairs(scene, robot_geoms)
        if not self.pairs:
            raise _NotCheckable(NOT_CHECKED_NO_PAIRS)
        self.coefficients = self._motion_bounds(robot)
        self.fresh_data()

    def fresh_data(self) -> None:
        """New Pinocchio and collision data: the distance solver keeps guesses from its last
        calls, so a reused one gives the same trajectory a clearance different in the 11th
        digit depending on what was checked before (a plan served by the API differed from the
        same plan made in the library)."""
        self.data = self.model.createData()
        self.gdata = self.geom.createData()

    def _configuration_map(self, robot: Robot) -> None:
        """Where each of ``robot.all_joint_names`` sits in Pinocchio's configuration."""
        import pinocchio as pin

        self.neutral = pin.neutral(self.model)
        self.slots: list[tuple[int, int]] = []
        for name in robot.all_joint_names:
            if not self.model.existJointName(name):
                raise _NotCheckable(
                    f"not checked: joint '{name}' is not in {Path(robot.urdf_path).name}"
                )
            joint = self.model.joints[self.model.getJointId(name)]
            self.slots.append((joint.idx_q, joint.nq))
        self.joint_ids = [self.model.getJointId(n) for n in robot.joint_names]
        self.full = robot.full_configuration

    def _ancestors(self, joint: int) -> list[int]:
        out = []
        while joint > 0:
            out.append(joint)
            joint = int(self.model.parents[joint])
        return out

    def _self_pairs(self, scene: SafetyScene) -> None:
        import pinocchio as pin

        objects = self.geom.geometryObjects
        for a in range(len(objects)):
            for b in range(a + 1, len(objects)):
                ja, jb = objects[a].parentJoint, objects[b].parentJoint
                parents = self.model.parents
                if ja == jb or parents[ja] == jb or parents[jb] == ja:
                    continue  # one rigid body, or adjacent links
                self.geom.addCollisionPair(pin.CollisionPair(a, b))
        if scene.srdf is not None:
            if not Path(scene.srdf).is_file():
                raise _NotCheckable(f"not checked: the SRDF {Path(scene.srdf).name} does not exist")
            try:
                pin.removeCollisionPairs(self.model, self.geom, str(scene.srdf))
            except (ValueError, RuntimeError) as exc:
                raise _NotCheckable(
                    f"not checked: the SRDF {Path(scene.srdf).name} cannot be read "
                    f"({type(exc).__name__})"
                ) from None
        for index, pair in enumerate(self.geom.collisionPairs):
            links = (self.link[pair.first], self.link[pair.second])
            self.pairs.append(_Pair(index, "self", links, None))

    def _world_pairs(self, scene: SafetyScene, robot_geoms: Sequence[int]) -> None:
        """The plane and the obstacles, each against every moving geometry."""
        import coal
        import pinocchio as pin

        world: list[tuple[str, str, Any, Any]] = []
        if scene.mount_plane_height is not None:
            plane = coal.Halfspace(np.array([0.0, 0.0, 1.0]), float(scene.mount_plane_height))
            world.append(("plane", "mount plane", plane, pin.SE3.Identity()))
        for obstacle in scene.obstacles:
            shape, placement = _obstacle_geometry(obstacle)
            world.append(("obstacle", obstacle.name, shape, placement))
        for kind, name, shape, placement in world:
            obj = pin.GeometryObject(f"bioplan_{kind}_{name}", 0, 0, placement, shape)
            new = self.geom.addGeometryObject(obj)
            self.link.append("")
            for g in robot_geoms:
                self.geom.addCollisionPair(pin.CollisionPair(g, new))
                index = len(self.geom.collisionPairs) - 1
                self.pairs.append(_Pair(index, kind, (self.link[g],), name))

    def _motion_bounds(self, robot: Robot) -> FloatArray:
        """(P, n) bound on a pair's relative motion per unit motion of each free joint [m/rad].

        A revolute joint turning by Δθ moves a point at most r Δθ, r its distance to the axis;
        r is bounded by the joint offsets down the chain plus the geometry's radius about its
        own joint. Joints above both bodies of a pair move them together and are left out.
        """
        objects = self.geom.geometryObjects
        column = {j: k for k, j in enumerate(self.joint_ids)}
        offsets = [float(np.linalg.norm(p.translation)) for p in self.model.jointPlacements]

        def reach(g: int) -> dict[int, float]:
            joint = objects[g].parentJoint
            if joint == 0:
                return {}  # fixed to the base or the world: never moves
            radius = _bounding_radius(objects[g].geometry, objects[g].placement)
            out: dict[int, float] = {}
            chain = self._ancestors(joint)  # from the body's joint up to the root
            below = 0.0
            for j in chain:
                prismatic = _is_prismatic(self.model.joints[j].shortname())
                out[j] = 1.0 if prismatic else below + radius
                below += offsets[j]
                if prismatic:  # the offset grows with the joint's travel
                    below += travel(j)
            return out

        def travel(j: int) -> float:
            idx = self.model.joints[j].idx_q
            ends = (self.model.lowerPositionLimit[idx], self.model.upperPositionLimit[idx])
            finite = [abs(float(v)) for v in ends if math.isfinite(float(v))]
            return max(finite) if len(finite) == 2 else 0.0

        reaches = [reach(g) for g in range(len(objects))]
        out = np.zeros((len(self.pairs), len(self.joint_ids)))
        for p, pair in enumerate(self.pairs):
            cp = self.geom.collisionPairs[pair.index]
            ra, rb = reaches[cp.first], reaches[cp.second]
            for j in set(ra) ^ set(rb):
                if j in column:
                    out[p, column[j]] = ra.get(j, 0.0) + rb.get(j, 0.0)
        return out

    def pair_counts(self) -> dict[str, int]:
        kinds = [p.kind for p in self.pairs]
        return {k: kinds.count(k) for k in ("self", "plane", "obstacle")}

    def _pin_q(self, q: FloatArray) -> FloatArray:
        """(T, n) free joints -> (T, nq) Pinocchio configurations (locked joints held)."""
        values = self.full(np.atleast_2d(q))
        out = np.tile(self.neutral, (len(values), 1))
        for k, (idx, nq) in enumerate(self.slots):
            if nq == 2:  # continuous joint: (cos, sin)
                out[:, idx], out[:, idx + 1] = np.cos(values[:, k]), np.sin(values[:, k])
            else:
                out[:, idx] = values[:, k]
        return out

    def _all_distances_pin(self, configurations: FloatArray) -> FloatArray:
        """(T, P) signed distance of every pair at (T, nq) Pinocchio configurations [m]."""
        import pinocchio as pin

        out = np.empty((len(configurations), len(self.pairs)))
        results = self.gdata.distanceResults
        count = len(self.pairs)
        for k, row in enumerate(configurations):
            pin.computeDistances(self.model, self.data, self.geom, self.gdata, row)
            out[k] = np.fromiter((r.min_distance for r in results), float, count)
        return out

    def _distance(self, q: FloatArray, pair: _Pair) -> float:
        import pinocchio as pin

        row = self._pin_q(q)[0]
        pin.updateGeometryPlacements(self.model, self.data, self.geom, self.gdata, row)
        return float(pin.computeDistance(self.geom, self.gdata, pair.index).min_distance)

    def _advance(self, q: FloatArray) -> tuple[list[int], FloatArray, FloatArray]:
        """Conservative advancement over the samples: the samples that must be evaluated.

        From an evaluated sample k, every sample m whose accumulated motion bound stays below
        every pair's |distance| at k is certain to keep each pair's state (clear or in
        contact), so only the last of them is evaluated.

        Returns:
            (evaluated sample indices, (E, P) their distances [m], (T-1, P) motion bounds of
            each sample interval [m]).
        """
        step = np.abs(np.diff(q, axis=0)) @ self.coefficients.T  # (T-1, P)
        moved = np.vstack([np.zeros((1, step.shape[1])), np.cumsum(step, axis=0)])
        configurations = self._pin_q(q)
        index = [0]
        rows = [self._all_distances_pin(configurations[:1])[0]]
        last = len(q) - 1
        while index[-1] < last:
            k = index[-1]
            window = moved[k + 1 : k + 1 + _WINDOW] - moved[k]
            certain = np.all(window < np.abs(rows[-1]), axis=1)
            skip = len(certain) if certain.all() else int(np.argmin(certain))
            m = min(k + max(skip, 1), last)
            index.append(m)
            rows.append(self._all_distances_pin(configurations[m : m + 1])[0])
        return index, np.array(rows), step

    def check(
        self, method: str, trajectory: _Samples, margin: float
    ) -> tuple[list[Finding], float]:
        """Findings of one trajectory, and its smallest signed distance at the evaluated
        samples [m] (a contact's depth is the deepest at those samples)."""
        t = np.asarray(trajectory.t, dtype=float)
        q = np.asarray(trajectory.q, dtype=float)
        qd = np.asarray(trajectory.qd, dtype=float)
        index, d, step = self._advance(q)
        lowest = float(d.min()) if d.size else math.inf
        contacts: dict[int, list[tuple[float, float, bool]]] = {}
        for e, p in zip(*np.nonzero(d <= 0.0), strict=True):
            contacts.setdefault(int(p), []).append((float(t[index[e]]), float(-d[e, p]), False))
        for e in range(len(index) - 1):
            k = index[e]
            if index[e + 1] != k + 1:
                continue  # a certain stretch: no state changes inside it
            bound = 0.5 * (d[e] + d[e + 1] - step[k])
            for p in np.nonzero((bound <= 0.0) & (d[e] > 0.0) & (d[e + 1] > 0.0))[0]:
                hit = self._bisect(t, q, qd, k, int(p), d[e, p], d[e + 1, p], margin)
                if hit is not None:
                    contacts.setdefault(int(p), []).append(hit)
                    lowest = min(lowest, -hit[1])
        findings = []
        for p, hits in contacts.items():
            pair = self.pairs[p]
            first = min(hits)
            deepest = max(hits, key=lambda h: h[1])
            findings.append(
                Finding(
                    method=method,
                    time=first[0],
                    kind=pair.kind,
                    links=pair.links,
                    obstacle=pair.obstacle,
                    depth=deepest[1],
                    deepest_time=deepest[0],
                    between_samples=all(h[2] for h in hits),
                )
            )
        findings.sort(key=lambda f: (f.time, f.kind, f.links))
        return findings, lowest

    def _bisect(
        self,
        t: FloatArray,
        q: FloatArray,
        qd: FloatArray,
        k: int,
        p: int,
        d0: float,
        d1: float,
        margin: float,
    ) -> tuple[float, float, bool] | None:
        """The first contact of pair ``p`` between samples k and k+1, or None if it clears.

        Sub-intervals are searched in time order, so the first one that holds a contact at its
        start, or that cannot be cleared although its motion is below ``margin``, holds the
        first contact.

        Returns:
            (time [s], depth there [m] >= 0, True) of the first contact.
        """
        pair = self.pairs[p]
        coef = self.coefficients[p]
        h = float(t[k + 1] - t[k])
        stack = [(0.0, 1.0, q[k], q[k + 1], d0, d1, 0)]
        while stack:
            s0, s1, qa, qb, da, db, depth = stack.pop()
            if da <= 0.0:
                return float(t[k] + s0 * h), -da, True
            motion = float(np.abs(qb - qa) @ coef)
            if 0.5 * (da + db - motion) > 0.0:
                continue
            sm = 0.5 * (s0 + s1)
            if motion <= margin or depth >= _MAX_SPLITS:
                return float(t[k] + sm * h), max(0.0, -0.5 * (da + db - motion)), True
            qm = _hermite(q[k], q[k + 1], qd[k] * h, qd[k + 1] * h, sm)
            dm = self._distance(qm, pair)
            # The earlier half is searched first (popped last pushed).
            stack.append((sm, s1, qm, qb, dm, db, depth + 1))
            stack.append((s0, sm, qa, qm, da, dm, depth + 1))
        return None


def _hermite(
    q0: FloatArray, q1: FloatArray, m0: FloatArray, m1: FloatArray, s: float
) -> FloatArray:
    """Cubic Hermite interpolation at s in [0, 1] (m0, m1: end slopes times the interval)."""
    s2, s3 = s * s, s * s * s
    return (
        (2 * s3 - 3 * s2 + 1) * q0
        + (s3 - 2 * s2 + s) * m0
        + (-2 * s3 + 3 * s2) * q1
        + (s3 - s2) * m1
    )
