"""Forward kinematics of a URDF chain, vectorised over a whole trajectory.

The viewer needs every joint frame's pose at every sample of a trajectory (to play it back and
to record an export) and the payload body's path (the end-effector trace). Evaluating them once,
as arrays, keeps the playback loop down to assigning precomputed poses; yourdfpy's per-sample
``update_cfg`` is used only to read the model (and, in tests, as the reference).
"""

from __future__ import annotations

import io
import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.errors import BioPlanError

FloatArray = NDArray[np.float64]
logger = logging.getLogger(__name__)

#: Joint types that move with their coordinate; anything else is held at its origin.
_REVOLUTE = ("revolute", "continuous")
_PRISMATIC = ("prismatic",)


class KinematicsError(BioPlanError):
    """A URDF or a joint trajectory the viewer cannot use; the message says what was expected."""


@dataclass(frozen=True)
class UrdfJoint:
    """One URDF joint.

    Attributes:
        name: joint name.
        type: URDF joint type (``revolute``, ``continuous``, ``prismatic``, ``fixed``, ...).
        parent, child: link names.
        origin: (4, 4) parent link -> joint frame at zero displacement.
        axis: (3,) unit axis in the joint frame.
    """

    name: str
    type: str
    parent: str
    child: str
    origin: FloatArray
    axis: FloatArray

    @property
    def moves(self) -> bool:
        return self.type in _REVOLUTE or self.type in _PRISMATIC


_XML_DECLARATION = re.compile(r"^\s*<\?xml[^>]*\?>")


#: Caps on a mesh the viewer loads (``use_mesh_limits``; None: the library's defaults).
_mesh_limits: Any = None


def use_mesh_limits(limits: Any) -> None:
    """Check every mesh against ``limits`` (an ``app.planning.robots.MeshLimits``, the
    server's ``BIOPLAN_MAX_MESH_MB``/``BIOPLAN_MAX_MESH_TRIANGLES``) before loading it; None
    restores the library's defaults."""
    global _mesh_limits
    _mesh_limits = limits


def _missing(fname: str) -> str:
    return f"/nonexistent/bioplan-missing-mesh/{fname}"


def _mesh_handler(
    base_dir: Path | None, package_dirs: Sequence[Path], allowed_roots: Sequence[Path] | None
) -> Any:
    """yourdfpy's filename handler: ``package://``, ``file://`` and relative mesh paths.

    A mesh that cannot be found (or lies outside ``allowed_roots``) resolves to a path that
    does not exist; yourdfpy then skips that mesh and the rest of the robot is still drawn.
    So does a mesh past the mesh limits (``use_mesh_limits``), with a warning: it is never
    parsed in this process (a stored 300 MB STL took 45 s and 3 GB to draw).
    """
    from app.planning.robots import MeshLimits, check_mesh, resolve_mesh

    def handler(fname: str) -> str:
        found = resolve_mesh(
            fname, base_dir=base_dir, package_dirs=package_dirs, allowed_roots=allowed_roots
        )
        if found is None:
            return _missing(fname)
        problem = check_mesh(found, _mesh_limits or MeshLimits())
        if problem is not None:
            logger.warning("mesh not drawn: %s", problem)
            return _missing(fname)
        return str(found)

    return handler


def load_urdf(
    source: str | bytes | Path,
    *,
    meshes: bool = False,
    base_dir: Path | None = None,
    package_dirs: Sequence[Path] = (),
    allowed_roots: Sequence[Path] | None = None,
) -> Any:
    """A ``yourdfpy.URDF`` from a file path or URDF text (str or bytes).

    Text is parsed whatever its XML declaration says: bytes as they are, a ``str`` with its
    ``<?xml ... encoding=...?>`` declaration removed (lxml refuses a str that declares an
    encoding, as every UR file does).

    Args:
        source: path of a ``.urdf`` file, or the URDF XML itself.
        meshes: build the visual scene graph (meshes loaded, primitives meshed).
        base_dir: folder that relative mesh paths start from (default: the file's folder).
        package_dirs: folders holding ``package://`` packages (the file's ancestors are tried
            too, see ``app.planning.robots.resolve_mesh``).
        allowed_roots: when given, meshes outside these folders are not read (uploads).

    Raises:
        KinematicsError: the file is missing or is not a URDF.
    """
    import yourdfpy  # type: ignore[import-untyped]

    handle: Any
    if isinstance(source, bytes):
        handle, name = io.BytesIO(source), "URDF text"
    elif isinstance(source, str) and source.lstrip().startswith("<"):
        handle, name = io.StringIO(_XML_DECLARATION.sub("", source, count=1)), "URDF text"
    else:
        path = Path(source)
        if not path.is_file():
            raise KinematicsError(f"URDF file not found: {path}")
        handle, name = io.BytesIO(path.read_bytes()), str(path)
        base_dir = base_dir or path.resolve().parent
    try:
        return yourdfpy.URDF.load(
            handle,
            build_scene_graph=meshes,
            load_meshes=meshes,
            build_collision_scene_graph=False,
            filename_handler=_mesh_handler(base_dir, package_dirs, allowed_roots),
        )
    except Exception as exc:  # yourdfpy raises assorted lxml/ValueError types
        detail = " ".join(str(exc).split())
        raise KinematicsError(f"{name}: not a readable URDF ({detail})") from None


class UrdfChain:
    """The kinematic tree of a URDF, for batched forward kinematics.

    Args:
        urdf: a ``yourdfpy.URDF`` (see :func:`load_urdf`).

    Attributes:
        root: the base link.
        joints: joints ordered parent before child.
    """

    def __init__(self, urdf: Any) -> None:
        joints: dict[str, UrdfJoint] = {}
        for j in urdf.joint_map.values():
            origin = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=np.float64)
            axis = np.array([1.0, 0.0, 0.0]) if j.axis is None else np.asarray(j.axis, float)
            norm = float(np.linalg.norm(axis))
            if j.type in _REVOLUTE + _PRISMATIC and norm == 0.0:
                raise KinematicsError(f"joint {j.name!r} has a zero axis: expected a unit vector")
            joints[j.name] = UrdfJoint(
                name=str(j.name),
                type=str(j.type),
                parent=str(j.parent),
                child=str(j.child),
                origin=origin,
                axis=axis / (norm or 1.0),
            )
        children = {j.child for j in joints.values()}
        roots = [str(name) for name in urdf.link_map if name not in children]
        if len(roots) != 1:
            raise KinematicsError(f"the URDF has {len(roots)} root links {roots}: expected one")
        self.root = roots[0]
        # Breadth-first from the root: every joint after the joint that moves its parent.
        order: list[UrdfJoint] = []
        frontier = [self.root]
        while frontier:
            link = frontier.pop(0)
            for j in joints.values():
                if j.parent == link:
                    order.append(j)
                    frontier.append(j.child)
        self.joints: tuple[UrdfJoint, ...] = tuple(order)
        self.links: tuple[str, ...] = (self.root, *(j.child for j in order))
        self._parent_joint = {j.child: j for j in order}

    @classmethod
    def from_source(cls, source: str | Path) -> UrdfChain:
        """The chain of a URDF file (or URDF text)."""
        return cls(load_urdf(source))

    def link_path(self, link: str) -> list[str]:
        """Link names from the root down to ``link`` (inclusive)."""
        if link not in self.links:
            raise KinematicsError(f"unknown link {link!r} (expected one of {list(self.links)})")
        path = [link]
        while path[-1] != self.root:
            path.append(self._parent_joint[path[-1]].parent)
        return path[::-1]

    def _coordinates(self, q: FloatArray, joint_names: Sequence[str]) -> dict[str, FloatArray]:
        q = np.asarray(q, dtype=np.float64)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != len(joint_names):
            raise KinematicsError(
                f"joint trajectory has shape {q.shape}: expected (T, {len(joint_names)}) for "
                f"joints {list(joint_names)}"
            )
        known = {j.name for j in self.joints if j.moves}
        unknown = sorted(set(joint_names) - known)
        if unknown:
            raise KinematicsError(
                f"joints {unknown} are not movable joints of the URDF (expected some of "
                f"{sorted(known)})"
            )
        if not np.all(np.isfinite(q)):
            raise KinematicsError("joint trajectory contains NaN or inf: expected finite angles")
        return {name: q[:, i] for i, name in enumerate(joint_names)}

    def joint_transforms(self, q: FloatArray, joint_names: Sequence[str]) -> dict[str, FloatArray]:
        """Parent link -> child link transform of every joint along a trajectory.

        Args:
            q: (T, n) joint coordinates [rad or m] in the order of ``joint_names``; joints not
                named stay at zero.
            joint_names: (n,) names of the columns of ``q``.

        Returns:
            joint name -> (T, 4, 4) homogeneous transforms.
        """
        coords = self._coordinates(q, joint_names)
        n = next(iter(coords.values())).shape[0] if coords else 1
        out: dict[str, FloatArray] = {}
        for j in self.joints:
            motion = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
            value = coords.get(j.name)
            if value is not None and j.type in _REVOLUTE:
                motion[:, :3, :3] = axis_angle_matrices(j.axis, value)
            elif value is not None and j.type in _PRISMATIC:
                motion[:, :3, 3] = value[:, None] * j.axis[None, :]
            out[j.name] = np.einsum("ij,tjk->tik", j.origin, motion)
        return out

    def link_poses(self, q: FloatArray, joint_names: Sequence[str]) -> dict[str, FloatArray]:
        """World pose of every link along a trajectory (the root link at the origin).

        Returns:
            link name -> (T, 4, 4) homogeneous transforms [m].
        """
        local = self.joint_transforms(q, joint_names)
        n = next(iter(local.values())).shape[0] if local else 1
        world: dict[str, FloatArray] = {self.root: np.broadcast_to(np.eye(4), (n, 4, 4)).copy()}
        for j in self.joints:
            world[j.child] = world[j.parent] @ local[j.name]
        return world


def axis_angle_matrices(axis: FloatArray, angles: FloatArray) -> FloatArray:
    """Rotation matrices about a unit axis (Rodrigues' formula).

    Args:
        axis: (3,) unit axis.
        angles: (T,) angles [rad].

    Returns:
        (T, 3, 3) rotation matrices.
    """
    x, y, z = (float(v) for v in axis)
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    s = np.sin(angles)[:, None, None]
    c = np.cos(angles)[:, None, None]
    return np.asarray(np.eye(3)[None] + s * k[None] + (1.0 - c) * (k @ k)[None], np.float64)


def matrices_to_wxyz(rotations: FloatArray) -> FloatArray:
    """Unit quaternions (w, x, y, z) of rotation matrices, w >= 0.

    Args:
        rotations: (..., 3, 3) rotation matrices.

    Returns:
        (..., 4) quaternions.
    """
    r = np.asarray(rotations, dtype=np.float64)
    m00, m11, m22 = r[..., 0, 0], r[..., 1, 1], r[..., 2, 2]
    # Four candidate magnitudes; the largest one is numerically safe to divide by.
    cand = np.stack(
        [
            1.0 + m00 + m11 + m22,
            1.0 + m00 - m11 - m22,
            1.0 - m00 + m11 - m22,
            1.0 - m00 - m11 + m22,
        ],
        axis=-1,
    )
    pick = np.argmax(cand, axis=-1)
    big = 0.5 * np.sqrt(np.maximum(np.take_along_axis(cand, pick[..., None], -1)[..., 0], 1e-300))
    inv = 0.25 / big
    d21, d02, d10 = (
        r[..., 2, 1] - r[..., 1, 2],
        r[..., 0, 2] - r[..., 2, 0],
        r[..., 1, 0] - r[..., 0, 1],
    )
    s21, s02, s10 = (
        r[..., 2, 1] + r[..., 1, 2],
        r[..., 0, 2] + r[..., 2, 0],
        r[..., 1, 0] + r[..., 0, 1],
    )
    options = np.stack(
        [
            np.stack([big, d21 * inv, d02 * inv, d10 * inv], -1),
            np.stack([d21 * inv, big, s10 * inv, s02 * inv], -1),
            np.stack([d02 * inv, s10 * inv, big, s21 * inv], -1),
            np.stack([d10 * inv, s02 * inv, s21 * inv, big], -1),
        ],
        axis=-2,
    )
    quat = np.take_along_axis(options, pick[..., None, None], -2)[..., 0, :]
    quat = np.where(quat[..., :1] < 0.0, -quat, quat)
    return np.asarray(quat / np.linalg.norm(quat, axis=-1, keepdims=True), np.float64)
