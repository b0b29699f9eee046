"""The comparison scene: both robots from their URDF, the payload, end-effector traces, phases.

``PreparedComparison`` does all the arithmetic once per comparison (meshes in link frames, every
joint frame's pose at every sample, the payload's path); ``ComparisonScene`` creates the nodes
once on a viser target (one browser tab's ``ClientHandle``, or a server used for an export) and
``show(index)`` only assigns precomputed poses, which is all the playback loop does.

Two robots show any two of the comparison's trajectories (``set_methods``; by default the
standard quintic and the paper's method): the solid one in its URDF colours, the ghost in its
method's colour, beside it (default) or over it, shifted a little (``set_layout``). The recorded
human (``app.viewer.human``) stands in the same row; ``camera`` frames all of them
(``app.viewer.framing``).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from app.names import METHODS, PHASES
from app.viewer.comparison import LABELS, Comparison, trajectory_colour, trajectory_label
from app.viewer.framing import (
    Box,
    box_of,
    corners,
    frame_camera,
    human_box,
    human_placement,
    shifted,
    union,
)
from app.viewer.human import HumanFigure, PreparedHuman
from app.viewer.kinematics import UrdfChain, load_urdf, matrices_to_wxyz

FloatArray = NDArray[np.float64]
#: Runs ``fn(*args)`` where untrusted mesh files may be parsed: ``(fn, *args) -> result``.
MeshReader = Callable[..., Any]
Layout = Literal["ghost", "side_by_side"]
LAYOUTS: tuple[Layout, ...] = ("ghost", "side_by_side")

ROOT = "/bioplan"


def rgb(colour: str) -> tuple[int, int, int]:
    """``(r, g, b)`` of a CSS hex colour ``#rrggbb``."""
    value = colour.lstrip("#")
    return int(value[0:2], 16), int(value[2:4], 16), int(value[4:6], 16)


#: RGB colours of the two trajectories: the standard quintic's and the paper's method's
#: (``app.names.METHODS``, the palette the Compare page and the reports use).
COLORS = {"standard": rgb(METHODS["quintic"].colour), "optimized": rgb(METHODS["paper"].colour)}
PAYLOAD_COLOR = (120, 170, 200)
#: The A/B/C phase marks on the traces (``app.names.PHASES``).
PHASE_COLORS = {phase.name: rgb(phase.colour) for phase in PHASES}
#: The ghost robot over the solid one: clearly visible, still see-through.
GHOST_OPACITY = 0.6
#: Colour of a contact marker and of the mounting plane's outline (the safety check's).
CONTACT_COLOR = (220, 40, 40)
#: Radius of the sphere marking a link in contact [m].
CONTACT_RADIUS = 0.035
#: The mounting plane: colour, opacity and thickness [m] of the translucent slab drawn on it.
MOUNT_PLANE_COLOR = (200, 120, 60)
MOUNT_PLANE_OPACITY = 0.25
MOUNT_PLANE_THICKNESS = 0.004
#: The sidecar's obstacles: colour and opacity.
OBSTACLE_COLOR = (150, 150, 165)
OBSTACLE_OPACITY = 0.35
#: End-effector trace: a thin tube of at most this many rings of TRACE_SIDES vertices [m].
TRACE_SAMPLES = 120
TRACE_SIDES = 6
TRACE_RADIUS = 0.004


@dataclass(frozen=True)
class LinkMesh:
    """One visual mesh of a link, in the link's frame."""

    link: str
    vertices: NDArray[np.float32]
    faces: NDArray[np.uint32]
    color: tuple[int, int, int]


class PreparedComparison:
    """Everything the scene needs, computed once per comparison.

    Args:
        comparison: the comparison to show.
        urdf_path: the robot's URDF file, so that its meshes (relative or ``package://`` paths)
            are found; default: ``comparison.urdf`` text, which shows primitives only.
        package_dirs: folders holding ``package://`` packages (see ``Robot.package_dirs``).
        allowed_roots: when given, meshes outside these folders are not read (uploads).
        locks: locked joints drawn at their values (``Robot.locks``; default: at zero).
        mesh_reader: ``(fn, *args) -> fn(*args)`` run where untrusted files may be parsed
            (the service's limited child process); default: in this process.

    Attributes:
        link_paths: link -> names from the root link down to it.
        meshes: visual meshes in their link frames.
        missing_meshes: visual mesh references of the URDF that resolve to no file (their
            links are drawn without bodies; the viewer says so).
        joint_wxyz, joint_position: label -> joint -> (T, 4) / (T, 3) pose of the joint's child
            link in its parent link's frame.
        payload_path: label -> (T, 3) world position of the payload's centre [m].
        traces: label -> (vertices (V, 3), faces (F, 3)) of the tube along the payload path.
        reach: largest distance of the payload from the base over both trajectories [m].
    """

    def __init__(
        self,
        comparison: Comparison,
        *,
        urdf_path: Path | None = None,
        package_dirs: Sequence[Path] = (),
        allowed_roots: Sequence[Path] | None = None,
        locks: Mapping[str, float] | None = None,
        mesh_reader: MeshReader | None = None,
    ) -> None:
        self.comparison = comparison
        source: str | Path = urdf_path if urdf_path is not None else comparison.urdf
        urdf = load_urdf(source, package_dirs=package_dirs, allowed_roots=allowed_roots)
        self.chain = UrdfChain(urdf)
        self.link_paths = {link: self.chain.link_path(link) for link in self.chain.links}
        # Meshes are files of the robot's owner: parsed where ``mesh_reader`` says (the
        # service's memory- and time-limited child process), never in the server itself.
        read = mesh_reader or (lambda fn, *args: fn(*args))
        self.meshes = read(load_link_meshes, source, tuple(package_dirs), allowed_roots)
        self.missing_meshes = _unresolved_meshes(urdf, source, package_dirs, allowed_roots)
        names = tuple(comparison.joint_names)
        held = dict(locks or {})
        # Joints that actually turn in either trajectory (J1 of a planar curl does not).
        moving = {
            name
            for i, name in enumerate(names)
            if any(np.ptp(comparison.q[label][:, i]) > 1e-9 for label in LABELS)
        }
        #: links moved by some joint of the trajectory (the ghost draws only these).
        self.moving_links = {
            link
            for link in self.chain.links
            if any(j.name in moving for j in self.chain.joints if j.child in self.link_paths[link])
        }
        self.joint_wxyz: dict[str, dict[str, FloatArray]] = {}
        self.joint_position: dict[str, dict[str, FloatArray]] = {}
        self.payload_path: dict[str, FloatArray] = {}
        #: label -> (lo, hi) box of the robot over the whole trajectory, in its root frame [m].
        self.bounds: dict[str, Box] = {}
        #: every trajectory the comparison holds (methods, and standard/optimized).
        self.labels = tuple(comparison.q)
        extents = _link_corners(self.meshes)
        com = np.append(comparison.payload_com, 1.0)
        for label in self.labels:
            q = comparison.q[label]
            if held:  # locked joints as constant columns (a gripper held open, ...)
                q = np.column_stack([q, np.tile(list(held.values()), (q.shape[0], 1))])
            local = self.chain.joint_transforms(q, names + tuple(held))
            self.joint_wxyz[label] = {j: matrices_to_wxyz(m[:, :3, :3]) for j, m in local.items()}
            self.joint_position[label] = {j: m[:, :3, 3].copy() for j, m in local.items()}
            world = self.chain.link_poses(q, names + tuple(held))
            if comparison.payload_body not in world:
                raise ValueError(
                    f"payload body {comparison.payload_body!r} is not a link of the URDF"
                )
            self.payload_path[label] = (world[comparison.payload_body] @ com)[:, :3]
            self.bounds[label] = _robot_box(world, extents, self.payload_path[label], comparison)
        stacked = np.concatenate(list(self.payload_path.values()))
        self.reach = float(np.max(np.linalg.norm(stacked[:, :2], axis=1), initial=0.3))
        self.height = float(np.max(stacked[:, 2], initial=1.0))
        self.traces = {label: trace_tube(self.payload_path[label]) for label in self.labels}
        self.phases = {
            label: [comparison.phase_at(label, i) for i in range(len(comparison.t))]
            for label in self.labels
        }
        #: label -> (joint, property) pairs that change along the trajectory: all a playback
        #: frame sends (a revolute joint's frame turns but never moves its origin).
        self.animated = {label: self._animated(label) for label in self.labels}
        self.human = self._prepare_human()
        #: the plan's safety check (``app.planning.safety``): ``{}`` when it has none.
        self.safety = safety_of(comparison.result)
        #: label -> its method's contacts: (first sample index, finding dict, label text).
        self.contacts = {label: self._contacts(label) for label in self.labels}

    def method_of(self, label: str) -> str:
        """The planned method a trajectory label shows (``standard``/``optimized`` are the
        comparison's ``shown`` pair)."""
        if label in LABELS:
            return self.comparison.shown[LABELS.index(label)]
        return label

    def _contacts(self, label: str) -> list[tuple[int, dict[str, Any], str]]:
        method = self.method_of(label)
        out = []
        for finding in self.safety.get("findings") or []:
            if finding.get("method") != method:
                continue
            links = [link for link in finding.get("links") or [] if link in self.link_paths]
            if not links:
                continue  # a link the viewer's URDF does not draw
            index = self.comparison.index_at(float(finding.get("time", 0.0)))
            out.append((index, {**finding, "links": links}, contact_text(finding)))
        return out

    @property
    def mount_plane_height(self) -> float | None:
        """The mounting plane the plan was checked against [m, base frame], or None (not
        checked, or the check had no plane)."""
        if self.safety.get("checked") is not True:
            return None
        height = self.safety.get("mount_plane_height")
        return None if height is None else float(height)

    def _animated(self, label: str) -> list[tuple[str, str]]:
        """(joint, "wxyz" | "position") pairs that change along one trajectory."""
        pairs = []
        for joint in self.joint_wxyz[label]:
            for prop, values in (
                ("wxyz", self.joint_wxyz[label][joint]),
                ("position", self.joint_position[label][joint]),
            ):
                if np.ptp(values, axis=0).max() > 1e-12:
                    pairs.append((joint, prop))
        return pairs

    def _prepare_human(self) -> PreparedHuman | None:
        """The recorded human placed beside the robots, or None without one."""
        c = self.comparison
        if c.human is None:
            return None
        shoulder, scale = human_placement(self.robot_boxes("side_by_side"), c.human.reach)
        return PreparedHuman(c.human, c.phase_bounds_deg, shoulder=shoulder, scale=scale)

    @property
    def floor(self) -> float:
        """Height of the floor [m]: z = 0, or under a robot that hangs below its base (the
        human arm's shoulder is its origin)."""
        return min(float(union(list(self.bounds.values()))[0][2]), 0.0)

    def boxes(self, layout: Layout) -> list[Box]:
        """World boxes of everything shown: both robots and the human [m]."""
        out = self.robot_boxes(layout)
        if self.human is not None:
            out.append(human_box(self.human.shoulder, self.human.scale * self.human.replay.reach))
        return out

    def slot_offsets(self, layout: Layout) -> dict[str, tuple[float, float, float]]:
        """Where each robot's root goes [m]: side by side along x (the camera looks from the
        side, across the arms' sagittal x-z plane), or the ghost shifted a little along x."""
        if layout == "side_by_side":
            return {"standard": (0.0, 0.0, 0.0), "optimized": (self.side_offset, 0.0, 0.0)}
        return {"standard": (0.0, 0.0, 0.0), "optimized": (self.ghost_shift, 0.0, 0.0)}

    @property
    def ghost_shift(self) -> float:
        """Shift of the ghost over the solid robot [m], so their rest poses (where both
        trajectories start and end) do not coincide."""
        return max(0.08, 0.15 * self.reach)

    def robot_boxes(self, layout: Layout) -> list[Box]:
        """World boxes of both robots (every trajectory, so a method switch stays in view)."""
        everything = union(list(self.bounds.values()))
        return [shifted(everything, offset) for offset in self.slot_offsets(layout).values()]

    @property
    def side_offset(self) -> float:
        """Distance between the two robots side by side [m]."""
        lo, hi = union(list(self.bounds.values()))
        return float(hi[0] - lo[0]) + 0.3

    def phase_points(self, label: str) -> list[tuple[str, FloatArray]]:
        """Where along the payload path each phase starts: [(phase, (3,) position)]."""
        out: list[tuple[str, FloatArray]] = []
        previous = None
        for i, phase in enumerate(self.phases[label]):
            if phase != previous:
                out.append((phase, self.payload_path[label][i]))
                previous = phase
        return out


def rpy_to_wxyz(rpy: Sequence[float]) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of URDF roll, pitch, yaw [rad] (fixed x, y, z axes)."""
    half = 0.5 * np.asarray(rpy, np.float64)
    cr, cp, cy = np.cos(half)
    sr, sp, sy = np.sin(half)
    return (
        float(cr * cp * cy + sr * sp * sy),
        float(sr * cp * cy - cr * sp * sy),
        float(cr * sp * cy + sr * cp * sy),
        float(cr * cp * sy - sr * sp * cy),
    )


def z_to_wxyz(normal: FloatArray) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of a rotation taking the z axis to the unit ``normal``."""
    n = np.asarray(normal, np.float64)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = helper - float(helper @ n) * n
    x /= np.linalg.norm(x)
    rotation = np.column_stack([x, np.cross(n, x), n])
    w, qx, qy, qz = (float(v) for v in matrices_to_wxyz(rotation[None])[0])
    return w, qx, qy, qz


def safety_of(result: Mapping[str, Any]) -> dict[str, Any]:
    """The safety check stored with a plan's result or a simulation's plan, or ``{}``."""
    safety = result.get("safety")
    if not isinstance(safety, Mapping):
        plan = result.get("plan")
        safety = plan.get("safety") if isinstance(plan, Mapping) else None
    return dict(safety) if isinstance(safety, Mapping) else {}


def contact_text(finding: Mapping[str, Any]) -> str:
    """A contact's label: ``contact: wrist_2_link – mount plane, 422 mm deep at t=0.51 s``."""
    links = list(finding.get("links") or ["?"])
    if finding.get("kind") == "self":
        what = f"{links[0]} – {links[-1]}"
    else:
        what = f"{links[0]} – {finding.get('obstacle') or 'obstacle'}"
    depth = 1000.0 * float(finding.get("depth", float("nan")))
    return (
        f"contact: {what}, {depth:.0f} mm deep at "
        f"t={float(finding.get('deepest_time', float('nan'))):.2f} s "
        f"(from t={float(finding.get('time', float('nan'))):.2f} s)"
    )


def _unresolved_meshes(
    urdf: Any,
    source: str | Path,
    package_dirs: Sequence[Path],
    allowed_roots: Sequence[Path] | None,
) -> list[str]:
    """Visual mesh references of a yourdfpy URDF that resolve to no (allowed) file, once each."""
    from app.planning.robots import resolve_mesh

    base = Path(source).parent if isinstance(source, Path) else None
    out: list[str] = []
    for link in urdf.robot.links:
        for visual in link.visuals:
            mesh = getattr(visual.geometry, "mesh", None)
            name = getattr(mesh, "filename", None)
            if not name or name in out:
                continue
            found = resolve_mesh(
                name, base_dir=base, package_dirs=package_dirs, allowed_roots=allowed_roots
            )
            if found is None:
                out.append(name)
    return out


def _link_corners(meshes: Sequence[LinkMesh]) -> dict[str, FloatArray]:
    """link -> (8, 3) corners of the box around its visual meshes, in the link's frame [m]."""
    out: dict[str, FloatArray] = {}
    for link in {m.link for m in meshes}:
        verts = [m.vertices for m in meshes if m.link == link and len(m.vertices)]
        if verts:
            out[link] = corners(box_of(np.concatenate(verts).astype(np.float64)))
    return out


#: Poses per trajectory used for a robot's box (plenty for a smooth motion).
BOX_SAMPLES = 60


def _robot_box(
    world: Mapping[str, FloatArray],
    link_corners: Mapping[str, FloatArray],
    payload: FloatArray,
    comparison: Comparison,
) -> Box:
    """The box a robot sweeps: its links' mesh boxes at evenly spaced poses, and the payload."""
    idx = np.unique(np.linspace(0, len(payload) - 1, BOX_SAMPLES).round().astype(int))
    points = [payload[idx]]
    pads = [np.full(len(idx), 0.5 * float(np.max(comparison.payload_size, initial=0.06)))]
    for link, poses in world.items():
        local = link_corners.get(link, np.zeros((1, 3)))
        moved = np.einsum("tij,kj->tki", poses[idx, :3, :3], local) + poses[idx, None, :3, 3]
        points.append(moved.reshape(-1, 3))
        pads.append(np.full(moved.shape[0] * moved.shape[1], 0.01))
    return box_of(np.concatenate(points), np.concatenate(pads))


def trace_tube(
    path: FloatArray,
    *,
    samples: int = TRACE_SAMPLES,
    radius: float = TRACE_RADIUS,
    sides: int = TRACE_SIDES,
) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
    """A closed-sided tube along a path, for drawing a trace as one plain mesh.

    viser's line segments are instanced fat lines (two passes with world-unit thickness); a
    software WebGL renderer pays for every instance, and two 300-segment traces took a headless
    SwiftShader canvas from about 55 to 18 frames per second. A tube of a few hundred triangles
    is one ordinary draw.

    Args:
        path: (T, 3) points [m].
        samples: most rings (the path is subsampled evenly, its last point kept).
        radius: tube radius [m].
        sides: vertices per ring.

    Returns:
        vertices (N * sides, 3) and faces (2 * sides * (N - 1), 3) for the N rings kept; both
        empty when the path does not move.
    """
    path = np.asarray(path, dtype=np.float64)
    step = max(1, -(-(len(path) - 1) // max(samples - 1, 1)))
    picked = path[::step]
    if len(path) and (len(picked) == 0 or not np.array_equal(picked[-1], path[-1])):
        picked = np.vstack([picked, path[-1:]])
    # Drop repeated points (a pose held still) so every tangent is defined.
    keep = [0] if len(picked) else []
    for i in range(1, len(picked)):
        if np.linalg.norm(picked[i] - picked[keep[-1]]) > 1e-6:
            keep.append(i)
    pts = picked[keep]
    if len(pts) < 2:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32)
    tangent = np.gradient(pts, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    # Parallel transport: each ring's normal is the previous one with its tangent part removed,
    # so the tube does not twist.
    seed = np.eye(3)[int(np.argmin(np.abs(tangent[0])))]
    normals = np.empty_like(pts)
    normal = seed - tangent[0] * (seed @ tangent[0])
    for i, t in enumerate(tangent):
        normal = normal - t * (normal @ t)
        normal /= np.linalg.norm(normal)
        normals[i] = normal
    binormals = np.cross(tangent, normals)
    angle = 2.0 * np.pi * np.arange(sides) / sides
    ring = (
        np.cos(angle)[None, :, None] * normals[:, None, :]
        + np.sin(angle)[None, :, None] * binormals[:, None, :]
    )
    vertices = (pts[:, None, :] + radius * ring).reshape(-1, 3)
    rings, around = np.meshgrid(np.arange(len(pts) - 1), np.arange(sides), indexing="ij")
    a = rings * sides + around
    b = rings * sides + (around + 1) % sides
    faces = np.stack(
        [np.stack([a, b, a + sides], -1), np.stack([b, b + sides, a + sides], -1)], axis=2
    ).reshape(-1, 3)
    return vertices.astype(np.float32), faces.astype(np.uint32)


def load_link_meshes(
    source: str | Path,
    package_dirs: Sequence[Path] = (),
    allowed_roots: Sequence[Path] | None = None,
) -> list[LinkMesh]:
    """The visual meshes of the URDF at ``source`` (a path or its text) in their link frames:
    a top-level function, so a limited child process can run it and send the arrays back."""
    urdf = load_urdf(source, meshes=True, package_dirs=package_dirs, allowed_roots=allowed_roots)
    return _link_meshes(urdf)


def _link_meshes(urdf: Any) -> list[LinkMesh]:
    """Visual meshes of a yourdfpy URDF (primitives already meshed) in their link frames."""
    scene = urdf.scene
    if scene is None:
        return []
    parents = scene.graph.transforms.parents
    meshes = []
    for node in scene.graph.nodes_geometry:
        transform, geometry_name = scene.graph.get(frame_to=node, frame_from=parents[node])
        geometry = scene.geometry[geometry_name]
        if not hasattr(geometry, "faces"):  # a COLLADA file may carry lines or points too
            continue
        mesh = geometry.copy()
        mesh.apply_transform(transform)
        color = getattr(mesh.visual, "main_color", None)
        rgb = (160, 160, 165) if color is None else tuple(int(c) for c in color[:3])
        meshes.append(
            LinkMesh(
                link=str(parents[node]),
                vertices=np.asarray(mesh.vertices, dtype=np.float32),
                faces=np.asarray(mesh.faces, dtype=np.uint32),
                color=(rgb[0], rgb[1], rgb[2]),
            )
        )
    return meshes


def configure_lighting(scene: Any) -> None:
    """Server-wide lighting: a hemisphere and a key light, no environment map, no shadows.

    The environment map and shadow maps cost a software-rendered WebGL canvas (a browser without
    a GPU, the headless tests) about four fifths of its frame rate; flat lights keep playback
    fluid there and look alike on a GPU.
    """
    scene.configure_environment_map(None)
    scene.configure_default_lights(False, cast_shadow=False)
    scene.add_light_hemisphere(
        "/lights/sky", sky_color=(255, 255, 255), ground_color=(125, 125, 135), intensity=2.2
    )
    scene.add_light_directional("/lights/key", intensity=1.6, wxyz=(0.88, 0.28, -0.36, 0.1))


class ComparisonScene:
    """The scene of one comparison on one viser target; built once, then only posed.

    Two robots: the solid one (slot ``standard``, its URDF colours) and the ghost (slot
    ``optimized``, translucent in its method's colour); each shows one of the comparison's
    trajectories (``set_methods``), by default the standard quintic and the paper's. The
    recorded human, when the comparison has one, stands beside them.

    Args:
        target: a ``viser.ClientHandle`` (one tab) or ``viser.ViserServer``.
        prepared: the precomputed comparison.
        layout: ``"side_by_side"`` (default) or ``"ghost"`` (the ghost over the solid robot,
            shifted a little sideways so the rest poses do not coincide).
    """

    def __init__(
        self, target: Any, prepared: PreparedComparison, *, layout: Layout = "side_by_side"
    ):
        self.target = target
        self.prepared = prepared
        scene = target.scene
        self.shown: dict[str, str] = dict(
            zip(LABELS, prepared.comparison.default_pair, strict=True)
        )
        self._frames: dict[str, dict[str, Any]] = {slot: {} for slot in LABELS}
        self._roots: dict[str, Any] = {}
        self._ghost_meshes: list[Any] = []
        self._static_ghost: list[Any] = []
        self._labels: dict[str, Any] = {}
        self._names: dict[str, Any] = {}
        self._lamps: dict[str, Any] = {}
        self._traces: dict[str, list[Any]] = {slot: [] for slot in LABELS}
        #: slot -> (first contact index, its marker and label handles, shown now).
        self._contacts: dict[str, list[tuple[int, list[Any]]]] = {slot: [] for slot in LABELS}
        self._contact_shown: dict[str, list[bool]] = {slot: [] for slot in LABELS}
        self.mount_plane: dict[str, Any] = {}
        self.obstacles: dict[str, list[Any]] = {}
        self._phase: dict[str, str] = {}
        #: the phase of each robot (and the human) at the pose shown.
        self.phases_now: dict[str, str] = {}
        self.index = -1
        self._add_floor(scene)
        for slot in LABELS:
            self._add_robot(scene, slot)
        self.human: HumanFigure | None = None
        self.no_human: Any = None
        if prepared.human is not None:
            self.human = HumanFigure(scene, f"{ROOT}/human", prepared.human)
        else:
            self.no_human = scene.add_label(
                f"{ROOT}/no_human",
                no_human_text(prepared.comparison),
                font_screen_scale=0.8,
                anchor="bottom-center",
                position=(float(union(prepared.robot_boxes("side_by_side"))[1][0]) + 0.5, 0.0, 0.8),
            )
        self.layout: Layout = "side_by_side"
        self.set_layout(layout)
        self.show(0)

    def _add_floor(self, scene: Any) -> None:
        # Just under everything: the grid's shader costs a software renderer per pixel it covers.
        lo, hi = union(self.prepared.boxes("side_by_side"))
        scene.add_grid(
            f"{ROOT}/floor",
            width=float(hi[0] - lo[0]) + 0.6,
            height=float(hi[1] - lo[1]) + 0.6,
            position=(
                float(0.5 * (lo[0] + hi[0])),
                float(0.5 * (lo[1] + hi[1])),
                self.prepared.floor,
            ),
            cell_size=0.25,
            section_size=1.0,
            shadow_opacity=0.0,
        )

    def _add_robot(self, scene: Any, slot: str) -> None:
        prepared = self.prepared
        ghost = slot == "optimized"
        label = self.shown[slot]
        self._roots[slot] = scene.add_frame(f"{ROOT}/{slot}", show_axes=False)
        for joint in prepared.chain.joints:
            node = self._link_node(slot, joint.child)
            self._frames[slot][joint.name] = scene.add_frame(node, show_axes=False)
        for k, mesh in enumerate(prepared.meshes):
            handle = scene.add_mesh_simple(
                f"{self._link_node(slot, mesh.link)}/visual_{k}",
                mesh.vertices,
                mesh.faces,
                color=rgb(trajectory_colour(label)) if ghost else mesh.color,
                opacity=GHOST_OPACITY if ghost else None,
                cast_shadow=False,
                receive_shadow=False,
            )
            if ghost:
                self._ghost_meshes.append(handle)
                if mesh.link not in prepared.moving_links:
                    self._static_ghost.append(handle)
        self._add_payload(scene, slot)
        self._add_trace(scene, slot)
        self._add_contacts(scene, slot)
        self._add_mount_plane(scene, slot)
        self._add_obstacles(scene, slot)
        c = prepared.comparison
        body = self._link_node(slot, c.payload_body)
        com = tuple(float(v) for v in c.payload_com)
        # On the payload body, so they move with it at no cost; the solid robot's label above
        # the payload, the ghost's below, so the two never overlap in the ghost layout.
        self._labels[slot] = scene.add_label(
            f"{body}/phase_label",
            "",
            font_screen_scale=0.9,
            anchor="top-center" if ghost else "bottom-center",
            position=com,
        )
        self._lamps[slot] = scene.add_icosphere(
            f"{body}/phase_lamp", radius=0.022, color=PHASE_COLORS["A"], position=com
        )
        top = float(prepared.bounds[label][1][2]) + 0.12
        self._names[slot] = scene.add_label(
            f"{ROOT}/{slot}/name",
            slot_name(slot, label),
            font_screen_scale=1.0,
            anchor="bottom-center",
            position=(0.0, 0.0, top),
        )

    def _link_node(self, slot: str, link: str) -> str:
        return f"{ROOT}/{slot}/" + "/".join(self.prepared.link_paths[link])

    def _add_payload(self, scene: Any, slot: str) -> None:
        c = self.prepared.comparison
        parent = self._link_node(slot, c.payload_body)
        ghost = slot == "optimized"
        color = rgb(trajectory_colour(self.shown[slot])) if ghost else PAYLOAD_COLOR
        opacity = GHOST_OPACITY if ghost else 0.85
        if np.all(c.payload_size > 0.0):
            handle = scene.add_box(
                f"{parent}/payload",
                color=color,
                dimensions=tuple(float(v) for v in c.payload_size),
                opacity=opacity,
                position=tuple(float(v) for v in c.payload_com),
            )
        else:
            # A point mass (a dumbbell in the hand): a sphere whose size grows with the mass.
            radius = 0.03 + 0.005 * min(c.payload_mass, 20.0)
            handle = scene.add_icosphere(
                f"{parent}/payload",
                radius=radius,
                color=color,
                opacity=opacity,
                position=tuple(float(v) for v in c.payload_com),
            )
        if ghost:
            self._ghost_meshes.append(handle)

    def _add_trace(self, scene: Any, slot: str) -> None:
        """The payload's path of the slot's trajectory, with its phase starts (replaced when
        the slot changes method: not in the playback loop)."""
        for handle in self._traces[slot]:
            handle.remove()
        self._traces[slot] = []
        label = self.shown[slot]
        vertices, faces = self.prepared.traces[label]
        if len(faces):
            self._traces[slot].append(
                scene.add_mesh_simple(
                    f"{ROOT}/{slot}/trace",
                    vertices,
                    faces,
                    color=rgb(trajectory_colour(label)),
                    flat_shading=False,
                    cast_shadow=False,
                    receive_shadow=False,
                )
            )
        for k, (phase, pos) in enumerate(self.prepared.phase_points(label)):
            self._traces[slot].append(
                scene.add_icosphere(
                    f"{ROOT}/{slot}/phase_start_{k}",
                    radius=0.018,
                    color=PHASE_COLORS[phase],
                    position=tuple(float(v) for v in pos),
                )
            )

    def _add_mount_plane(self, scene: Any, slot: str) -> None:
        """The mounting plane the plan was checked against: a translucent slab in the slot's
        base frame, its top face at the plane's height, over the robot's reach."""
        height = self.prepared.mount_plane_height
        if height is None:
            return
        lo, hi = union([self.prepared.bounds[label] for label in self.prepared.labels])
        size = 2.0 * max(float(np.max(np.abs(lo[:2]))), float(np.max(np.abs(hi[:2]))), 0.2)
        self.mount_plane[slot] = scene.add_box(
            f"{ROOT}/{slot}/mount_plane",
            color=MOUNT_PLANE_COLOR,
            dimensions=(size, size, MOUNT_PLANE_THICKNESS),
            opacity=MOUNT_PLANE_OPACITY,
            position=(0.0, 0.0, height - 0.5 * MOUNT_PLANE_THICKNESS),
        )
        if slot == "optimized":  # overlaid, one plane is enough
            self._static_ghost.append(self.mount_plane[slot])

    def _add_obstacles(self, scene: Any, slot: str) -> None:
        """The sidecar's obstacles, translucent, in the slot's base frame (a plane as a slab
        on its free side's boundary, over the robot's reach)."""
        reach = max(self.prepared.reach, 0.5)
        for k, obstacle in enumerate(self.prepared.comparison.obstacles):
            node = f"{ROOT}/{slot}/obstacle_{k}"
            position = np.asarray(obstacle["position"], np.float64)
            common = {"color": OBSTACLE_COLOR, "opacity": OBSTACLE_OPACITY}
            if obstacle["kind"] == "box":
                handle = scene.add_box(
                    node,
                    dimensions=tuple(float(v) for v in obstacle["size"]),
                    wxyz=rpy_to_wxyz(obstacle["rpy"]),
                    position=tuple(float(v) for v in position),
                    **common,
                )
            elif obstacle["kind"] == "cylinder":
                handle = scene.add_cylinder(
                    node,
                    radius=float(obstacle["radius"]),
                    height=float(obstacle["length"]),
                    wxyz=rpy_to_wxyz(obstacle["rpy"]),
                    position=tuple(float(v) for v in position),
                    **common,
                )
            else:  # a half-space: the slab's top face on the plane, nearest the base
                normal = np.asarray(obstacle["normal"], np.float64)
                normal = normal / np.linalg.norm(normal)
                foot = float(position @ normal) * normal  # the plane's point nearest the base
                centre = foot - 0.5 * MOUNT_PLANE_THICKNESS * normal
                handle = scene.add_box(
                    node,
                    dimensions=(2.0 * reach, 2.0 * reach, MOUNT_PLANE_THICKNESS),
                    wxyz=z_to_wxyz(normal),
                    position=tuple(float(v) for v in centre),
                    **common,
                )
            self.obstacles.setdefault(slot, []).append(handle)
            if slot == "optimized":  # overlaid, one set is enough
                self._static_ghost.append(handle)

    def _add_contacts(self, scene: Any, slot: str) -> None:
        """The contacts of the slot's method: a red sphere on every link involved and a label
        saying what touches what, how deep and when; shown from the first contact on
        (replaced when the slot changes method: not in the playback loop)."""
        for _, handles in self._contacts[slot]:
            for handle in handles:
                handle.remove()
        self._contacts[slot] = []
        self._contact_shown[slot] = []
        for k, (index, finding, text) in enumerate(self.prepared.contacts[self.shown[slot]]):
            handles = []
            for m, link in enumerate(finding["links"]):
                handles.append(
                    scene.add_icosphere(
                        f"{self._link_node(slot, link)}/contact_{k}_{m}",
                        radius=CONTACT_RADIUS,
                        color=CONTACT_COLOR,
                        opacity=0.8,
                        visible=False,
                    )
                )
            handles.append(
                scene.add_label(
                    f"{self._link_node(slot, finding['links'][0])}/contact_{k}_label",
                    text,
                    font_screen_scale=0.8,
                    anchor="top-left",
                    visible=False,
                )
            )
            self._contacts[slot].append((index, handles))
            self._contact_shown[slot].append(False)

    def contacts_shown(self, slot: str) -> list[str]:
        """The contact labels of a slot visible at the pose shown."""
        texts = [text for _, _, text in self.prepared.contacts[self.shown[slot]]]
        return [text for text, shown in zip(texts, self._contact_shown[slot], strict=True) if shown]

    def _show_contacts(self, index: int) -> None:
        """Markers of contacts that began at or before sample ``index`` visible, the others
        hidden; a message only when one changes."""
        for slot in LABELS:
            for k, (first, handles) in enumerate(self._contacts[slot]):
                visible = index >= first
                if self._contact_shown[slot][k] != visible:
                    self._contact_shown[slot][k] = visible
                    for handle in handles:
                        handle.visible = visible

    def set_methods(self, solid: str, ghost: str) -> None:
        """Show trajectory ``solid`` on the solid robot and ``ghost`` on the ghost (names of
        ``prepared.labels``); recolours the ghost and redraws the traces, no new robot."""
        for name in (solid, ghost):
            if name not in self.prepared.labels:
                raise ValueError(
                    f"unknown trajectory {name!r} (expected one of {self.prepared.labels})"
                )
        changed = [slot for slot, name in zip(LABELS, (solid, ghost), strict=True)
                   if self.shown[slot] != name]  # fmt: skip
        for slot, name in zip(LABELS, (solid, ghost), strict=True):
            self.shown[slot] = name
        for slot in changed:
            self._add_trace(self.target.scene, slot)
            self._add_contacts(self.target.scene, slot)
            self._names[slot].text = slot_name(slot, self.shown[slot])
            self._phase.pop(slot, None)
        if "optimized" in changed:
            colour = rgb(trajectory_colour(ghost))
            for handle in self._ghost_meshes:
                handle.color = colour
        if changed:
            index, self.index = self.index, -1  # every joint: the new trajectory's pose
            self.show(index)

    def set_layout(self, layout: Layout) -> None:
        """Side by side or ghost (moves the roots, changes opacity; no new nodes)."""
        if layout not in LAYOUTS:
            raise ValueError(f"unknown layout {layout!r} (expected one of {LAYOUTS})")
        for slot, offset in self.prepared.slot_offsets(layout).items():
            self._roots[slot].position = offset
        opacity = GHOST_OPACITY if layout == "ghost" else 1.0
        for handle in self._ghost_meshes:
            handle.opacity = opacity
        # Overlaid, the ghost's fixed base would only tint the solid one's.
        for handle in self._static_ghost:
            handle.visible = layout == "side_by_side"
        self.layout = layout

    def show(self, index: int) -> dict[str, str]:
        """Pose both robots and the human at sample ``index``; returns the phase of each
        (``standard``, ``optimized`` and, with a human, ``human``).

        Wrap calls in ``target.atomic()`` so a browser never draws half a pose.
        """
        p = self.prepared
        index = int(min(max(index, 0), len(p.comparison.t) - 1))
        for slot in LABELS:
            label, frames = self.shown[slot], self._frames[slot]
            if self.index < 0:
                # First pose: every frame, so the scene is right whatever it showed before.
                for joint, frame in frames.items():
                    frame.wxyz = p.joint_wxyz[label][joint][index]
                    frame.position = p.joint_position[label][joint][index]
            elif index != self.index:
                for joint, prop in p.animated[label]:
                    source = p.joint_wxyz if prop == "wxyz" else p.joint_position
                    setattr(frames[joint], prop, source[label][joint][index])
        self.index = index
        self._show_contacts(index)
        phases = {slot: p.phases[self.shown[slot]][index] for slot in LABELS}
        for slot, phase in phases.items():
            # Labels change only at a phase boundary: no message per frame.
            if self._phase.get(slot) != phase:
                self._phase[slot] = phase
                self._labels[slot].text = f"phase {phase}"
                self._lamps[slot].color = PHASE_COLORS[phase]
        if self.human is not None:
            phases["human"] = self.human.show(index)
        self.phases_now = phases
        return phases

    def camera(
        self, *, aspect: float = 1.6, covered_right: float = 0.0
    ) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """A camera position and look-at point that frame both robots and the human [m], left
        of a panel covering the right ``covered_right`` fraction of the canvas."""
        return frame_camera(
            self.prepared.boxes(self.layout), aspect=aspect, covered_right=covered_right
        )


def slot_name(slot: str, label: str) -> str:
    """The legend over a robot: which trajectory it shows, drawn how."""
    drawn = "solid" if slot == "standard" else "ghost"
    return f"{drawn}: {trajectory_label(label)}"


def no_human_text(comparison: Comparison) -> str:
    """Why no recorded human stands beside the robots."""
    return comparison.human_note or "no recorded human: this comparison has no analysed lift"


class PreparedCache:
    """Prepared comparisons by (kind, id), most recently used kept; finished results never
    change, so an entry stays valid.

    Args:
        loader: ``(kind, id) -> Comparison``.
        size: comparisons kept in memory.
        human: ``comparison -> comparison`` with the recorded human attached (or a note why
            there is none); the service's ``HumanReplayLoader``.
        mesh_reader: where the robot's meshes are parsed (see :class:`PreparedComparison`).
    """

    def __init__(
        self,
        loader: Callable[[str, int], Comparison],
        *,
        size: int = 8,
        human: Callable[[Comparison], Comparison] | None = None,
        mesh_reader: MeshReader | None = None,
    ) -> None:
        self.loader = loader
        self.size = size
        self.human = human
        self.mesh_reader = mesh_reader
        self._items: OrderedDict[tuple[str, int, Any], PreparedComparison] = OrderedDict()
        self._lock = threading.Lock()

    def __call__(
        self, kind: str, result_id: int, methods: tuple[str, str] | None = None
    ) -> PreparedComparison:
        """The prepared comparison; ``methods`` picks the two planned methods shown (None: the
        quintic and the paper's); the robot's URDF file, package folders and locks come with
        the comparison, so meshes show."""
        key = (kind, int(result_id), methods)
        with self._lock:
            hit = self._items.get(key)
            if hit is not None:
                self._items.move_to_end(key)
                return hit
        if methods is None:
            comparison = self.loader(kind, int(result_id))
        else:
            comparison = self.loader(kind, int(result_id), methods)  # type: ignore[call-arg]
        if self.human is not None:
            comparison = self.human(comparison)
        prepared = PreparedComparison(
            comparison,
            urdf_path=comparison.urdf_path,
            package_dirs=comparison.package_dirs,
            allowed_roots=comparison.allowed_roots,
            locks=comparison.locks,
            mesh_reader=self.mesh_reader,
        )
        with self._lock:
            self._items[key] = prepared
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        return prepared
