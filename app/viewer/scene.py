"""The comparison scene: both robots from their URDF, the payload, end-effector traces, phases.

``PreparedComparison`` does all the arithmetic once per comparison (meshes in link frames, every
joint frame's pose at every sample, the payload's path); ``ComparisonScene`` creates the nodes
once on a viser target (one browser tab's ``ClientHandle``, or a server used for an export) and
``show(index)`` only assigns precomputed poses, which is all the playback loop does.

The standard robot is drawn in its URDF colours; the optimised one in amber, either as a
translucent ghost over the standard one or beside it (``set_layout``).
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
from app.viewer.comparison import LABELS, Comparison
from app.viewer.kinematics import UrdfChain, load_urdf, matrices_to_wxyz

FloatArray = NDArray[np.float64]
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
GHOST_OPACITY = 0.4
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

    Attributes:
        link_paths: link -> names from the root link down to it.
        meshes: visual meshes in their link frames.
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
    ) -> None:
        self.comparison = comparison
        urdf = load_urdf(
            urdf_path if urdf_path is not None else comparison.urdf,
            meshes=True,
            package_dirs=package_dirs,
            allowed_roots=allowed_roots,
        )
        self.chain = UrdfChain(urdf)
        self.link_paths = {link: self.chain.link_path(link) for link in self.chain.links}
        self.meshes = _link_meshes(urdf)
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
        com = np.append(comparison.payload_com, 1.0)
        for label in LABELS:
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
        stacked = np.concatenate(list(self.payload_path.values()))
        self.reach = float(np.max(np.linalg.norm(stacked[:, :2], axis=1), initial=0.3))
        self.height = float(np.max(stacked[:, 2], initial=1.0))
        self.traces = {label: trace_tube(self.payload_path[label]) for label in LABELS}
        self.phases = {
            label: [comparison.phase_at(label, i) for i in range(len(comparison.t))]
            for label in LABELS
        }
        #: label -> (joint, property) pairs that change along the trajectory: all a playback
        #: frame sends (a revolute joint's frame turns but never moves its origin).
        self.animated: dict[str, list[tuple[str, str]]] = {}
        for label in LABELS:
            pairs = []
            for joint in self.joint_wxyz[label]:
                for prop, values in (
                    ("wxyz", self.joint_wxyz[label][joint]),
                    ("position", self.joint_position[label][joint]),
                ):
                    if np.ptp(values, axis=0).max() > 1e-12:
                        pairs.append((joint, prop))
            self.animated[label] = pairs

    @property
    def side_offset(self) -> float:
        """Distance between the two robots side by side [m]."""
        return 2.0 * self.reach + 0.4

    def phase_points(self, label: str) -> list[tuple[str, FloatArray]]:
        """Where along the payload path each phase starts: [(phase, (3,) position)]."""
        out: list[tuple[str, FloatArray]] = []
        previous = None
        for i, phase in enumerate(self.phases[label]):
            if phase != previous:
                out.append((phase, self.payload_path[label][i]))
                previous = phase
        return out


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

    Args:
        target: a ``viser.ClientHandle`` (one tab) or ``viser.ViserServer``.
        prepared: the precomputed comparison.
        layout: ``"ghost"`` (optimised over standard, translucent) or ``"side_by_side"``.
    """

    def __init__(self, target: Any, prepared: PreparedComparison, *, layout: Layout = "ghost"):
        self.target = target
        self.prepared = prepared
        scene = target.scene
        self._frames: dict[str, dict[str, Any]] = {label: {} for label in LABELS}
        self._roots: dict[str, Any] = {}
        self._ghost_meshes: list[Any] = []
        self._static_ghost: list[Any] = []
        self._labels: dict[str, Any] = {}
        self._phase: dict[str, str] = {}
        self.index = -1
        chain = prepared.chain
        # Just under both robots in either layout: the grid's shader costs a software renderer
        # per pixel it covers.
        scene.add_grid(
            f"{ROOT}/floor",
            width=2.0 * prepared.reach + 1.0,
            height=prepared.side_offset + 2.0 * prepared.reach + 1.0,
            cell_size=0.25,
            section_size=1.0,
            shadow_opacity=0.0,
        )
        for label in LABELS:
            root = scene.add_frame(f"{ROOT}/{label}", show_axes=False)
            self._roots[label] = root
            optimized = label == "optimized"
            for joint in chain.joints:
                name = self._link_node(label, joint.child)
                self._frames[label][joint.name] = scene.add_frame(name, show_axes=False)
            for k, mesh in enumerate(prepared.meshes):
                handle = scene.add_mesh_simple(
                    f"{self._link_node(label, mesh.link)}/visual_{k}",
                    mesh.vertices,
                    mesh.faces,
                    color=COLORS["optimized"] if optimized else mesh.color,
                    opacity=GHOST_OPACITY if optimized else None,
                    cast_shadow=False,
                    receive_shadow=False,
                )
                if optimized:
                    self._ghost_meshes.append(handle)
                    if mesh.link not in prepared.moving_links:
                        self._static_ghost.append(handle)
            self._add_payload(scene, label)
            self._add_trace(scene, label)
            # On the payload body, so it moves with it at no cost; the standard's label above
            # the payload, the optimised one's below, so the two never overlap.
            self._labels[label] = scene.add_label(
                f"{self._link_node(label, prepared.comparison.payload_body)}/phase_label",
                "",
                font_screen_scale=0.9,
                anchor="top-center" if optimized else "bottom-center",
                position=tuple(float(v) for v in prepared.comparison.payload_com),
            )
        self.layout: Layout = "ghost"
        self.set_layout(layout)
        self.show(0)

    def _link_node(self, label: str, link: str) -> str:
        return f"{ROOT}/{label}/" + "/".join(self.prepared.link_paths[link])

    def _add_payload(self, scene: Any, label: str) -> None:
        c = self.prepared.comparison
        parent = self._link_node(label, c.payload_body)
        color = COLORS["optimized"] if label == "optimized" else PAYLOAD_COLOR
        opacity = GHOST_OPACITY if label == "optimized" else 0.85
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
        if label == "optimized":
            self._ghost_meshes.append(handle)

    def _add_trace(self, scene: Any, label: str) -> None:
        vertices, faces = self.prepared.traces[label]
        if len(faces):
            scene.add_mesh_simple(
                f"{ROOT}/{label}/trace",
                vertices,
                faces,
                color=COLORS[label],
                flat_shading=False,
                cast_shadow=False,
                receive_shadow=False,
            )
        for k, (phase, pos) in enumerate(self.prepared.phase_points(label)):
            scene.add_icosphere(
                f"{ROOT}/{label}/phase_start_{k}",
                radius=0.018,
                color=PHASE_COLORS[phase],
                position=tuple(float(v) for v in pos),
            )

    def set_layout(self, layout: Layout) -> None:
        """Ghost overlay or side by side (moves the roots, changes opacity; no new nodes)."""
        if layout not in LAYOUTS:
            raise ValueError(f"unknown layout {layout!r} (expected one of {LAYOUTS})")
        half = 0.5 * self.prepared.side_offset if layout == "side_by_side" else 0.0
        self._roots["standard"].position = (0.0, half, 0.0)
        self._roots["optimized"].position = (0.0, -half, 0.0)
        opacity = GHOST_OPACITY if layout == "ghost" else 1.0
        for handle in self._ghost_meshes:
            handle.opacity = opacity
        # Overlaid, the optimised robot's fixed base would only tint the standard one's.
        for handle in self._static_ghost:
            handle.visible = layout == "side_by_side"
        self.layout = layout

    def show(self, index: int) -> dict[str, str]:
        """Pose both robots at sample ``index``; returns the phase of each trajectory.

        Wrap calls in ``target.atomic()`` so a browser never draws half a pose.
        """
        p = self.prepared
        index = int(min(max(index, 0), len(p.comparison.t) - 1))
        if self.index < 0:
            # First pose: every frame, so the scene is right whatever it showed before.
            for label in LABELS:
                for joint, frame in self._frames[label].items():
                    frame.wxyz = p.joint_wxyz[label][joint][index]
                    frame.position = p.joint_position[label][joint][index]
        elif index != self.index:
            for label in LABELS:
                frames = self._frames[label]
                for joint, prop in p.animated[label]:
                    source = p.joint_wxyz if prop == "wxyz" else p.joint_position
                    setattr(frames[joint], prop, source[label][joint][index])
        self.index = index
        phases = {label: p.phases[label][index] for label in LABELS}
        for label, phase in phases.items():
            # Labels change only at a phase boundary: no message per frame.
            if self._phase.get(label) != phase:
                self._phase[label] = phase
                handle = self._labels[label]
                handle.text = f"{'standard' if label == 'standard' else 'optimised'}: {phase}"
        return phases

    def camera(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """A camera position and look-at point that frame both robots [m]."""
        p = self.prepared
        side = 0.5 * p.side_offset
        side = side if self.layout == "side_by_side" else 0.0
        look = (0.4 * p.reach, 0.0, 0.55 * p.height)
        dist = 1.25 * max(p.reach + side, 0.8 * p.height, 0.8)
        return (look[0] + 0.8 * dist, look[1] - 1.0 * dist, look[2] + 0.35 * dist), look


class PreparedCache:
    """Prepared comparisons by (kind, id), most recently used kept; finished results never
    change, so an entry stays valid.

    Args:
        loader: ``(kind, id) -> Comparison``.
        size: comparisons kept in memory.
    """

    def __init__(self, loader: Callable[[str, int], Comparison], *, size: int = 8) -> None:
        self.loader = loader
        self.size = size
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
        prepared = PreparedComparison(
            comparison,
            urdf_path=comparison.urdf_path,
            package_dirs=comparison.package_dirs,
            allowed_roots=comparison.allowed_roots,
            locks=comparison.locks,
        )
        with self._lock:
            self._items[key] = prepared
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        return prepared
