"""The recorded human in the viewer: a two-link arm (upper arm, forearm) with a torso and head.

``PreparedHuman`` turns an :class:`~app.analysis.HumanReplay` into per-sample joint rotations and
phases once; ``HumanFigure`` creates its nodes once on a viser target and ``show(index)`` only
assigns two rotations (and recolours the hand at a phase boundary), like the robots.

Frames: the figure's root sits at the shoulder, x forward, z up. Both joints turn about -y, so
a positive angle swings the hanging segment (along -z) forward: R(q) (0, 0, -1) = (sin q, 0,
-cos q), the analysis' convention (``app.analysis.replay``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.analysis.replay import HumanReplay
from app.names import PHASES
from app.viewer.comparison import PHASES as PHASE_LABELS
from app.viewer.comparison import phase_of

FloatArray = NDArray[np.float64]

SKIN = (222, 170, 130)
BODY = (150, 155, 170)
PHASE_COLORS = {p.name: tuple(int(p.colour[i : i + 2], 16) for i in (1, 3, 5)) for p in PHASES}


def about_minus_y(angles: FloatArray) -> FloatArray:
    """(T, 4) wxyz quaternions of rotations by ``angles`` (T,) [rad] about -y."""
    half = 0.5 * np.asarray(angles, dtype=np.float64)
    zero = np.zeros_like(half)
    return np.stack([np.cos(half), zero, -np.sin(half), zero], axis=1)


class PreparedHuman:
    """A replayed lift, ready to show: rotations and phases per sample of the plan's grid.

    Args:
        replay: the lift on the plan's time grid.
        phase_bounds_deg: (A/B, B/C) elbow-flexion bounds [deg] (the comparison's).
        shoulder: where the shoulder goes in the world [m].
        scale: drawing scale of the arm (1 = life size).

    Attributes:
        shoulder_wxyz, elbow_wxyz: (T, 4) joint rotations.
        phases: (T,) phase letter of each sample (the elbow flexion against the bounds).
    """

    def __init__(
        self,
        replay: HumanReplay,
        phase_bounds_deg: tuple[float, float],
        *,
        shoulder: tuple[float, float, float],
        scale: float,
    ) -> None:
        self.replay = replay
        self.shoulder = shoulder
        self.scale = float(scale)
        self.shoulder_wxyz = about_minus_y(replay.shoulder)
        self.elbow_wxyz = about_minus_y(replay.elbow)
        self.phases = [phase_of(float(f), phase_bounds_deg) for f in replay.elbow_flexion_deg()]

    def hand_world(self) -> FloatArray:
        """(T, 3) world position of the drawn hand [m] (scaled, at the shoulder)."""
        at_elbow, hand = self.replay.points()
        del at_elbow
        s = np.asarray(self.shoulder)
        return s + self.scale * np.column_stack([hand[:, 0], np.zeros(len(hand)), hand[:, 1]])


class HumanFigure:
    """The human's nodes on one viser target (a tab or a server), built once then posed.

    Args:
        scene: the target's ``scene`` API.
        root: node path of the figure.
        prepared: the prepared human.
    """

    def __init__(self, scene: Any, root: str, prepared: PreparedHuman) -> None:
        self.prepared = prepared
        r = prepared.replay
        s = prepared.scale
        l1, l2 = s * r.upper_arm, s * r.forearm
        thick = 0.045 * s
        self.root = scene.add_frame(root, show_axes=False, position=prepared.shoulder)
        scene.add_box(
            f"{root}/torso",
            color=BODY,
            dimensions=(0.14 * s, 0.3 * s, 0.55 * s),
            position=(-0.09 * s, 0.2 * s, -0.26 * s),
        )
        scene.add_icosphere(
            f"{root}/head", radius=0.1 * s, color=BODY, position=(-0.06 * s, 0.2 * s, 0.2 * s)
        )
        self.upper = scene.add_frame(f"{root}/upper", show_axes=False)

        def add_limb(frame: str, joint: str, length: float) -> None:
            """A limb of ``length`` [m] hanging down (-z) from ``frame``, a sphere at its joint."""
            scene.add_box(
                f"{frame}/arm",
                color=SKIN,
                dimensions=(thick, thick, length),
                position=(0.0, 0.0, -0.5 * length),
            )
            scene.add_icosphere(f"{frame}/{joint}", radius=0.7 * thick, color=SKIN)

        add_limb(f"{root}/upper", "shoulder", l1)
        self.fore = scene.add_frame(f"{root}/upper/fore", show_axes=False, position=(0.0, 0.0, -l1))
        add_limb(f"{root}/upper/fore", "elbow", l2)
        self.hand = scene.add_icosphere(
            f"{root}/upper/fore/hand",
            radius=1.1 * thick,
            color=PHASE_COLORS["A"],
            position=(0.0, 0.0, -l2),
        )
        self.name = scene.add_label(
            f"{root}/name",
            _name(prepared),
            font_screen_scale=0.9,
            anchor="bottom-center",
            position=(0.0, 0.0, 0.38 * s),
        )
        self.phase_label = scene.add_label(
            f"{root}/upper/fore/phase",
            "",
            font_screen_scale=0.9,
            anchor="top-center",
            position=(0.0, 0.0, -l2 - 0.06 * s),
        )
        self.phase = ""
        self.index = -1

    def show(self, index: int) -> str:
        """Pose the arm at sample ``index``; returns its phase (the hand turns its colour)."""
        p = self.prepared
        index = int(min(max(index, 0), len(p.phases) - 1))
        if index != self.index:
            self.upper.wxyz = p.shoulder_wxyz[index]
            self.fore.wxyz = p.elbow_wxyz[index]
            self.index = index
        phase = p.phases[index]
        if phase != self.phase:  # a message only at a phase boundary
            self.phase = phase
            self.hand.color = PHASE_COLORS[phase]
            self.phase_label.text = f"human: {phase} ({PHASE_LABELS[phase]})"
        return phase


def _name(prepared: PreparedHuman) -> str:
    """The legend over the figure (which lift: in the panel's note)."""
    scale = "" if prepared.scale == 1.0 else f" (drawn {prepared.scale:.1f}x)"
    return f"recorded human{scale}"
