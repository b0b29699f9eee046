"""Where things go in the viewer's scene: the camera that frames them all, the human beside.

Pure arithmetic on axis-aligned boxes (``(lo (3,), hi (3,))`` in world coordinates [m], z up),
so the framing is tested without a browser: every corner of every box lies inside the camera's
view, and a camera any closer would crop one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
Box = tuple[FloatArray, FloatArray]

#: Vertical field of view the viewer sets on each tab's camera [rad].
FOV = math.radians(50.0)
#: From the scene's centre towards the camera: from the side (-y, across the arms' sagittal
#: x-z plane, where the robots and the human stand in a row along x), a little in front, above.
VIEW_DIRECTION = (0.3, -1.0, 0.4)
#: Extra distance beyond the tightest framing (labels, the panel's edge).
MARGIN = 1.1


def box_of(points: FloatArray, pad: float | FloatArray = 0.0) -> Box:
    """The box around (N, 3) points, grown by ``pad`` [m] (a scalar or (N,) per point)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    grow = np.broadcast_to(np.asarray(pad, dtype=np.float64), (len(pts),))[:, None]
    return (pts - grow).min(axis=0), (pts + grow).max(axis=0)


def shifted(box: Box, offset: Sequence[float]) -> Box:
    """``box`` moved by ``offset`` (3,) [m]."""
    d = np.asarray(offset, dtype=np.float64)
    return box[0] + d, box[1] + d


def union(boxes: Sequence[Box]) -> Box:
    """The smallest box holding every box."""
    if not boxes:
        raise ValueError("union of no boxes")
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)


def corners(box: Box) -> FloatArray:
    """(8, 3) corners of a box."""
    lo, hi = box
    return np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]] for i in (0, 1)
                     for j in (0, 1) for k in (0, 1)])  # fmt: skip


def _basis(direction: Sequence[float] | FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Camera forward, right and up unit vectors for a camera looking along -direction, z up."""
    d = np.asarray(direction, dtype=np.float64)
    forward = -d / np.linalg.norm(d)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return forward, right, np.cross(right, forward)


def frame_camera(
    boxes: Sequence[Box],
    *,
    direction: Sequence[float] = VIEW_DIRECTION,
    fov: float = FOV,
    aspect: float = 1.6,
    margin: float = MARGIN,
    covered_right: float = 0.0,
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """A camera position and look-at point whose view holds every box.

    The camera looks at the centre of the boxes' union from along ``direction``. A corner at
    offset p from the centre is seen at depth D + p·f and at p·r (across) and p·u (up) off the
    axis; it is inside the view when |p·r| <= (D + p·f) tan(hfov/2) and |p·u| <= (D + p·f)
    tan(fov/2), so the smallest distance is the largest of |p·r| / tan(hfov/2) - p·f and
    |p·u| / tan(fov/2) - p·f over the corners; ``margin`` scales it. When a panel covers the
    right fraction c of the canvas, camera and look-at move right by D tan(hfov/2) c (the
    boxes' centre then appears at the centre of the uncovered part) and each corner must lie
    left of the panel; the shift makes that depth-dependent, so the distance is found by
    bisection (whether all corners fit is monotone in D).

    Args:
        boxes: world boxes [m] to keep in view.
        direction: from the look-at point towards the camera (any length).
        fov: vertical field of view [rad].
        aspect: width / height of the canvas (a 400 px wide phone is below 1).
        margin: distance factor (>= 1).
        covered_right: fraction of the canvas' width covered on the right (a panel), [0, 0.8].

    Returns:
        (position, look_at) [m].
    """
    lo, hi = union(boxes)
    centre = 0.5 * (lo + hi)
    forward, right, up = _basis(direction)
    tan_v = math.tan(0.5 * fov)
    tan_h = tan_v * max(aspect, 1e-3)
    covered = min(max(covered_right, 0.0), 0.8)
    p = corners((lo, hi)) - centre
    across, along, height = p @ right, p @ forward, p @ up

    def fits(distance: float) -> bool:
        depth = distance + along
        if np.any(depth <= 1e-6):
            return False
        x = (across - distance * tan_h * covered) / (depth * tan_h)
        y = height / (depth * tan_v)
        return bool(
            np.all(x >= -1.0) and np.all(x <= 1.0 - 2.0 * covered) and np.all(abs(y) <= 1.0)
        )

    # Without a panel, the closed form; the panel's shift makes it depth-dependent, so bisect
    # (fitting is monotone in the distance) from there.
    need = np.maximum(np.abs(across) / (tan_h * (1.0 - covered)), np.abs(height) / tan_v) - along
    low, high = 0.0, max(float(need.max()), float(np.abs(along).max()) + 0.05, 0.3)
    while not fits(high):
        low, high = high, 2.0 * high
    for _ in range(50):
        mid = 0.5 * (low + high)
        low, high = (low, mid) if fits(mid) else (mid, high)
    distance = margin * high
    centre = centre + right * (distance * tan_h * covered)  # the look-at point
    position = centre - forward * distance
    return tuple(float(v) for v in position), tuple(float(v) for v in centre)  # type: ignore[return-value]


def in_view(
    point: Sequence[float],
    position: Sequence[float],
    look_at: Sequence[float],
    *,
    fov: float = FOV,
    aspect: float = 1.6,
    covered_right: float = 0.0,
) -> bool:
    """Whether a point [m] lies inside the view of a camera at ``position`` looking at ``look_at``
    (z up, vertical field of view ``fov`` [rad]), left of a panel covering the right
    ``covered_right`` fraction of the canvas."""
    cam = np.asarray(position, dtype=np.float64)
    forward, right, up = _basis(cam - np.asarray(look_at, dtype=np.float64))
    v = np.asarray(point, dtype=np.float64) - cam
    depth = float(v @ forward)
    if depth <= 0.0:
        return False
    tan_v = math.tan(0.5 * fov)
    x = float(v @ right) / (depth * tan_v * aspect)  # -1 (left edge) .. 1 (right edge)
    inside_x = -1.0 - 1e-9 <= x <= 1.0 - 2.0 * covered_right + 1e-9
    return bool(inside_x and abs(v @ up) <= depth * tan_v + 1e-9)


def human_placement(
    robot_boxes: Sequence[Box], human_reach: float, *, gap: float = 0.25
) -> tuple[tuple[float, float, float], float]:
    """Where the human's shoulder goes and how much the arm is scaled, beside the robots.

    The arm is scaled to the robots' height (0.6 of it, at least life size, at most 2x) so it
    reads beside a 6-DOF arm, and the figure stands in the robots' row (along x) beyond their
    largest x by ``gap``, its shoulder at the height where the hanging hand clears the floor
    (z = 0, or the robots' lowest point when they hang below their base).

    Args:
        robot_boxes: world boxes of the robots [m].
        human_reach: the straight arm's length [m].
        gap: clearance between the robots' boxes and the human's [m].

    Returns:
        (shoulder position (3,) [m], scale).
    """
    lo, hi = union(robot_boxes)
    floor = min(float(lo[2]), 0.0)
    scale = float(np.clip(0.6 * (float(hi[2]) - floor) / max(human_reach, 1e-3), 1.0, 2.0))
    reach = scale * human_reach
    shoulder = (
        float(hi[0]) + gap + _BEHIND * reach,
        0.5 * float(lo[1] + hi[1]),
        floor + 1.1 * reach + 0.05,
    )
    return shoulder, scale


#: How far the figure reaches behind its shoulder (torso, an arm swung back), in arm lengths.
_BEHIND = 0.5


def human_box(shoulder: Sequence[float], reach: float) -> Box:
    """The box the scaled figure can take: its arm swept in the sagittal plane, torso, head."""
    s = np.asarray(shoulder, dtype=np.float64)
    lo = s + np.array([-_BEHIND * reach, -0.35 * reach, -reach])
    hi = s + np.array([reach, 0.6 * reach, 0.5 * reach])
    return lo, hi
