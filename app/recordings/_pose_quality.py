"""How far a pose track can be trusted, frame by frame: who is tracked, and is the arm real.

MediaPipe Pose 0.10.21 tracks one person. With two people in the picture it may jump from one
to the other (or onto trees, a shadow...), and the landmarks teleport. Two checks, numpy only:

- identity: the torso's centre (mean of shoulders and hips) and size (mean shoulder-hip
  distance) between consecutive frames with a pose; a move of more than ``max_jump`` torso
  lengths (plus ``max_speed`` torso lengths per second of elapsed time) or a change of size by
  more than a factor ``1 + max_scale_change`` is a switch. The stretches between switches are
  matched to the persons seen before (by the same test, from where that person was last seen)
  and the person seen in most frames is *the tracked person*.
- the arm: the visibility of its shoulder, elbow and wrist (the smallest of the three), and the
  lengths of upper arm and forearm in the image against their median over the tracked
  person's well-seen frames: a skeleton drawn on something else has limbs of other lengths.

A frame's score is the arm's visibility where the frame shows the tracked person with plausible
limb lengths, else 0; a frame is low-quality when its score is below ``min_visibility``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
#: A landmark as (T, 2) image positions (x, y on one scale) and (T,) visibility.
Landmark = tuple[F64, F64]
TORSO = ("left_shoulder", "right_shoulder", "left_hip", "right_hip")


@dataclass(frozen=True)
class Identity:
    """Who the pose track follows, frame by frame.

    Attributes:
        person: (T,) person number per frame (0 = the tracked person, seen in most frames;
            1, 2... others in order of appearance), -1 where there is no pose.
        switches: frame indices where the track jumped to another person.
        n_persons: persons the track followed.
    """

    person: NDArray[np.intp]
    switches: tuple[int, ...]
    n_persons: int

    def other_frames(self) -> NDArray[np.intp]:
        """Indices of the frames that show someone else than the tracked person."""
        return np.flatnonzero(self.person > 0)


def _torso(lms: Mapping[str, Landmark], n: int) -> tuple[F64, F64]:
    """(T, 2) torso centre and (T,) torso length; NaN where unknown."""
    pts = [np.asarray(lms[k][0], dtype=np.float64)[:, :2] for k in TORSO if k in lms]
    sizes = [
        np.linalg.norm(lms[f"{s}_shoulder"][0][:, :2] - lms[f"{s}_hip"][0][:, :2], axis=1)
        for s in ("left", "right")
        if f"{s}_shoulder" in lms and f"{s}_hip" in lms
    ]
    return _nanmean(pts, (n, 2)), _nanmean(sizes, (n,))


def _nanmean(arrays: list[F64], shape: tuple[int, ...]) -> F64:
    """Element-wise mean of the finite values (NaN where none), without numpy's warning."""
    if not arrays:
        return np.full(shape, np.nan)
    stack = np.stack([np.asarray(a, dtype=np.float64) for a in arrays])
    ok = np.isfinite(stack)
    count = ok.sum(axis=0)
    total = np.where(ok, stack, 0.0).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out: F64 = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    if len(shape) == 2:  # a point is known only when both of its coordinates are
        out[~np.isfinite(out).all(axis=1)] = np.nan
    return out


def _same(
    c0: F64, s0: float, c1: F64, s1: float, dt: float, max_jump: float, max_speed: float,
    max_scale_change: float,
) -> bool:  # fmt: skip
    """Whether a torso at (c1, s1) can be the one at (c0, s0) ``dt`` seconds earlier."""
    ref = max(s0, s1)
    if not (np.isfinite(ref) and ref > 0):
        return True
    moved = float(np.linalg.norm(c1 - c0)) / ref
    if moved > max_jump + max_speed * dt:
        return False
    ratio = max(s0, s1) / max(min(s0, s1), 1e-12)
    return bool(ratio <= (1.0 + max_scale_change) * (1.0 + 0.5 * dt))


def identity(
    lms: Mapping[str, Landmark],
    t: F64,
    *,
    max_jump: float = 0.5,
    max_speed: float = 3.0,
    max_scale_change: float = 0.4,
) -> Identity:
    """Which person each frame's pose belongs to (see the module's notes).

    Args:
        lms: landmark name -> ((T, 2) positions on one scale, (T,) visibility); the torso
            ones (shoulders, hips) are used.
        t: (T,) frame times [s].
        max_jump: largest move of the torso between two frames [torso lengths].
        max_speed: more allowed per second between the frames [torso lengths/s].
        max_scale_change: largest relative change of the torso's length between two frames.
    """
    n = len(t)
    centre, scale = _torso(lms, n)
    has = np.isfinite(centre).all(axis=1)
    label = np.full(n, -1, dtype=np.intp)
    last: list[tuple[F64, float, float]] = []  # per person: centre, scale, time last seen
    switches: list[int] = []
    prev = -1
    limits = (max_jump, max_speed, max_scale_change)
    for i in np.flatnonzero(has):
        c, s = centre[i], float(scale[i])
        if prev >= 0 and _same(centre[prev], float(scale[prev]), c, s, t[i] - t[prev], *limits):
            label[i] = label[prev]
        else:
            match = [
                p
                for p, (cp, sp, tp) in enumerate(last)
                if p != (label[prev] if prev >= 0 else -1)
                and _same(cp, sp, c, s, t[i] - tp, *limits)
            ]
            label[i] = match[0] if match else len(last)
            if not match:
                last.append((c, s, float(t[i])))
            if prev >= 0:
                switches.append(int(i))
        last[label[i]] = (c, s if np.isfinite(s) else last[label[i]][1], float(t[i]))
        prev = int(i)
    counts = np.bincount(label[label >= 0], minlength=len(last))
    # Renumber: the tracked person (most frames) is 0, the others by first appearance.
    order = [int(np.argmax(counts))] if len(last) else []
    order += [p for p in dict.fromkeys(label[label >= 0].tolist()) if p not in order]
    renumber = np.full(len(last) + 1, -1, dtype=np.intp)
    for new, old in enumerate(order):
        renumber[old] = new
    person = np.where(label >= 0, renumber[label], -1)
    return Identity(person=person, switches=tuple(switches), n_persons=len(order))


@dataclass(frozen=True)
class FrameQuality:
    """Per-frame quality of one arm's landmarks.

    Attributes:
        visibility: (T,) smallest visibility of shoulder, elbow and wrist (0 without a pose).
        upper_arm_ratio, forearm_ratio: (T,) segment length in the image / its median over the
            tracked person's well-seen frames (NaN where unknown).
        plausible: (T,) both lengths within the tolerance.
        person: (T,) person number (0 = the tracked person, -1 = no pose); see :class:`Identity`.
        score: (T,) visibility where the frame shows the tracked person with plausible limbs,
            else 0.
        low: (T,) score below ``min_visibility``.
        switches: frame indices where the track jumped to another person.
        n_persons: persons the track followed.
        min_visibility, length_tolerance: the thresholds used.
    """

    visibility: F64
    upper_arm_ratio: F64
    forearm_ratio: F64
    plausible: NDArray[np.bool_]
    person: NDArray[np.intp]
    score: F64
    low: NDArray[np.bool_]
    switches: tuple[int, ...] = ()
    n_persons: int = 1
    min_visibility: float = 0.5
    length_tolerance: float = 0.4
    reasons: dict[str, int] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """JSON-ready counts: frames, low-quality frames and why, persons, switches."""
        return {
            "frames": len(self.score),
            "low_quality_frames": int(self.low.sum()),
            "reasons": dict(self.reasons),
            "persons_tracked": self.n_persons,
            "switch_frames": list(self.switches),
            "other_person_frames": int((self.person > 0).sum()),
            "min_visibility": self.min_visibility,
            "length_tolerance": self.length_tolerance,
        }


def arm_quality(
    lms: Mapping[str, Landmark],
    t: F64,
    side: str,
    *,
    min_visibility: float = 0.5,
    length_tolerance: float = 0.4,
    who: Identity | None = None,
) -> FrameQuality:
    """Per-frame quality of the ``side`` arm (see the module's notes).

    Args:
        lms: landmark name -> ((T, 2) positions on one scale, (T,) visibility).
        t: (T,) frame times [s].
        side: ``"left"`` or ``"right"``.
        min_visibility: a frame whose score is below this is low-quality.
        length_tolerance: a segment length outside [median / (1 + tol), median * (1 + tol)]
            is implausible.
        who: the identity track (computed from the torso when None).
    """
    n = len(t)
    who = who if who is not None else identity(lms, t)
    names = [f"{side}_{j}" for j in ("shoulder", "elbow", "wrist")]
    if not all(k in lms for k in names):
        raise KeyError(f"no {side} arm landmarks")
    pos = [np.asarray(lms[k][0], dtype=np.float64)[:, :2] for k in names]
    vis = np.stack([np.nan_to_num(np.asarray(lms[k][1], dtype=np.float64)) for k in names])
    present = np.stack([np.isfinite(p).all(axis=1) for p in pos])
    visibility = np.where(present.all(axis=0), vis.min(axis=0), 0.0)
    ref = (visibility >= min_visibility) & (who.person == 0)
    ratios = []
    for a, b in ((pos[0], pos[1]), (pos[1], pos[2])):
        length = np.linalg.norm(b - a, axis=1)
        base = length[ref & np.isfinite(length)]
        med = float(np.median(base)) if base.size else float("nan")
        with np.errstate(invalid="ignore", divide="ignore"):
            ratios.append(length / med if med > 0 else np.full(n, np.nan))
    lo, hi = 1.0 / (1.0 + length_tolerance), 1.0 + length_tolerance
    with np.errstate(invalid="ignore"):
        plausible = np.all([(r >= lo) & (r <= hi) for r in ratios], axis=0)
    other = who.person != 0
    score = np.where(plausible & ~other, visibility, 0.0)
    low = score < min_visibility
    reasons = {
        "no_pose": int((who.person < 0).sum()),
        "other_person": int((who.person > 0).sum()),
        "implausible_lengths": int((~plausible & ~other & (visibility > 0)).sum()),
        "low_visibility": int(((visibility < min_visibility) & plausible & ~other).sum()),
    }
    return FrameQuality(
        visibility=visibility,
        upper_arm_ratio=ratios[0],
        forearm_ratio=ratios[1],
        plausible=np.asarray(plausible, dtype=bool),
        person=who.person,
        score=score,
        low=np.asarray(low, dtype=bool),
        switches=who.switches,
        n_persons=who.n_persons,
        min_visibility=min_visibility,
        length_tolerance=length_tolerance,
        reasons=reasons,
    )


def frame_ranges(frames: NDArray[np.intp], limit: int = 4) -> str:
    """``"12-40, 77, 90-95"``: consecutive frame indices as ranges (at most ``limit``)."""
    idx = np.asarray(frames, dtype=np.intp)
    if not idx.size:
        return "none"
    cuts = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate(([idx[0]], idx[cuts + 1]))
    stops = np.concatenate((idx[cuts], [idx[-1]]))
    parts = [f"{a}" if a == b else f"{a}-{b}" for a, b in zip(starts, stops, strict=True)]
    more = len(parts) - limit
    return ", ".join(parts[:limit]) + (f" and {more} more" if more > 0 else "")


def image_landmarks(channels: Mapping[str, Any]) -> dict[str, Landmark]:
    """name -> ((T, 2) x, y, (T,) visibility) of a recording's image-landmark channels."""
    out: dict[str, Landmark] = {}
    for name, ch in channels.items():
        if ch.kind != "landmark" or ch.data.ndim != 2:
            continue
        conf = ch.confidence if ch.confidence is not None else np.ones(ch.n_samples)
        key = name.split(":")[-1].strip().lower()
        out[key] = (np.asarray(ch.data, dtype=np.float64)[:, :2], np.asarray(conf, np.float64))
    return out
