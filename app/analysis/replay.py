"""A recorded lift replayed beside a planned motion: time normalisation and a two-link arm.

The viewer shows the subject's lift next to the robot doing the plan. The lift runs on its own
clock (start at rest, top at full flexion, some seconds long); the plan runs from 0 to its
duration T. :func:`lift_time_map` maps the lift's start -> top onto 0 -> T, so both reach the
top together. The arm is the human model's sagittal two-link chain (``human_arm_2dof``): shoulder
at the origin, x forward, z up, shoulder flexion 0 = arm hanging, elbow flexion 0 = straight,

    elbow = l1 (sin qs, -cos qs),   hand = elbow + l2 (sin(qs + qe), -cos(qs + qe)),

with de Leva's segment lengths scaled to the subject's height (``human_arm_segments``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.analysis.overlays import AnalysisOverlays
from app.errors import BioPlanError

FloatArray = NDArray[np.float64]


class ReplayError(BioPlanError):
    """A lift that cannot be replayed (no angles, no such lift, an empty span)."""


def lift_time_map(t_plan: FloatArray, start: float, top: float) -> FloatArray:
    """Recording times [s] shown at each plan time: the lift's start -> top onto the plan's span.

    Args:
        t_plan: (T,) plan time grid [s], increasing.
        start, top: the lift's start and top on the recording's clock [s], ``top > start``.

    Returns:
        (T,) recording times [s]: ``start + (top - start) (t - t0) / (tT - t0)``.
    """
    t_plan = np.asarray(t_plan, dtype=np.float64)
    if not (math.isfinite(start) and math.isfinite(top) and top > start):
        raise ReplayError(f"a lift needs start < top, got start={start} s, top={top} s")
    span = float(t_plan[-1] - t_plan[0]) if len(t_plan) else 0.0
    if not span > 0.0:
        raise ReplayError("the plan's time grid must span a positive duration")
    out: FloatArray = start + (top - start) * (t_plan - t_plan[0]) / span
    return out


def resample_series(t: FloatArray, y: FloatArray, t_query: FloatArray) -> FloatArray | None:
    """``y`` linearly interpolated at ``t_query``, over its finite samples only.

    Returns:
        (Q,) values (held at the ends), or None when fewer than two samples are finite.
    """
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    ok = np.isfinite(t) & np.isfinite(y)
    if np.count_nonzero(ok) < 2:
        return None
    # Min/max-decimated series repeat times; np.interp needs them non-decreasing, which they are.
    order = np.argsort(t[ok], kind="stable")
    return np.interp(np.asarray(t_query, dtype=np.float64), t[ok][order], y[ok][order])


def two_link_points(
    shoulder: FloatArray, elbow: FloatArray, upper_arm: float, forearm: float
) -> tuple[FloatArray, FloatArray]:
    """Elbow and hand positions of the sagittal two-link arm.

    Args:
        shoulder: (T,) shoulder flexion [rad], 0 = arm hanging, positive forward.
        elbow: (T,) elbow flexion [rad], 0 = straight.
        upper_arm, forearm: segment lengths [m] (shoulder -> elbow, elbow -> hand).

    Returns:
        elbow (T, 2) and hand (T, 2) positions (x forward, z up) [m], shoulder at the origin.
    """
    qs = np.asarray(shoulder, dtype=np.float64)
    qe = qs + np.asarray(elbow, dtype=np.float64)
    at_elbow = upper_arm * np.stack([np.sin(qs), -np.cos(qs)], axis=-1)
    hand = at_elbow + forearm * np.stack([np.sin(qe), -np.cos(qe)], axis=-1)
    return at_elbow, hand


@dataclass(frozen=True)
class HumanReplay:
    """One recorded lift, on a plan's time grid, as a two-link arm.

    Attributes:
        t: (T,) plan time grid [s].
        shoulder, elbow: (T,) shoulder and elbow flexion [rad] at each plan time.
        upper_arm, forearm: segment lengths [m] (de Leva, scaled to ``body_height``).
        body_height: the subject's stature [m] the lengths were scaled from.
        lift: which lift: ``file``, ``index``, ``start_s``, ``top_s`` (recording clock [s]).
        notes: what had to be assumed (e.g. no shoulder angle recorded: held at 0).
    """

    t: FloatArray
    shoulder: FloatArray
    elbow: FloatArray
    upper_arm: float
    forearm: float
    body_height: float
    lift: dict[str, Any]
    notes: tuple[str, ...] = field(default=())

    @property
    def reach(self) -> float:
        """Length of the straight arm [m]."""
        return self.upper_arm + self.forearm

    def points(self) -> tuple[FloatArray, FloatArray]:
        """Elbow and hand (T, 2) positions (x forward, z up) [m]; see :func:`two_link_points`."""
        return two_link_points(self.shoulder, self.elbow, self.upper_arm, self.forearm)

    def elbow_flexion_deg(self) -> FloatArray:
        """(T,) elbow flexion [deg]."""
        return np.degrees(self.elbow)

    def describe(self) -> str:
        """One line: which lift of which file, over what span, scaled to what height."""
        lift = self.lift
        return (
            f"lift {lift['index'] + 1} of {lift['file']} ({lift['start_s']:.2f}-{lift['top_s']:.2f}"
            f" s), arm of a {self.body_height:.2f} m subject"
        )


def replay_lift(
    t_plan: FloatArray,
    t_rec: FloatArray,
    shoulder_deg: FloatArray | None,
    elbow_deg: FloatArray,
    *,
    start: float,
    top: float,
    body_height: float = 1.75,
    sex: str = "male",
    lift: dict[str, Any] | None = None,
) -> HumanReplay:
    """Replay one lift's recorded angles on a plan's time grid.

    Args:
        t_plan: (T,) plan time grid [s].
        t_rec: (N,) recording times of the angles [s].
        shoulder_deg: (N,) shoulder flexion [deg] (None or all-NaN: not recorded, held at 0).
        elbow_deg: (N,) elbow flexion [deg].
        start, top: the lift's start and top on the recording clock [s].
        body_height: subject stature [m] for de Leva's segment lengths.
        sex: ``"male"`` or ``"female"`` (de Leva's table).
        lift: description kept in :attr:`HumanReplay.lift` (default: start and top only).

    Raises:
        ReplayError: fewer than two elbow samples, or start >= top.
    """
    from app.planning.robots import human_arm_segments

    t_plan = np.asarray(t_plan, dtype=np.float64)
    when = lift_time_map(t_plan, start, top)
    elbow = resample_series(t_rec, elbow_deg, when)
    if elbow is None:
        raise ReplayError("the recording has no elbow angle to replay")
    notes: list[str] = []
    shoulder = None if shoulder_deg is None else resample_series(t_rec, shoulder_deg, when)
    if shoulder is None:
        notes.append("no shoulder angle recorded: the upper arm is drawn hanging (0 deg)")
        shoulder = np.zeros_like(elbow)
    seg = human_arm_segments(body_height=body_height, sex=sex)
    return HumanReplay(
        t=t_plan,
        shoulder=np.radians(shoulder),
        elbow=np.radians(elbow),
        upper_arm=float(seg.l1),
        forearm=float(seg.l2),
        body_height=float(body_height),
        lift=dict(lift or {"file": "", "index": 0, "start_s": start, "top_s": top}),
        notes=tuple(notes),
    )


def replay_from_overlays(
    overlays: AnalysisOverlays,
    t_plan: FloatArray,
    *,
    lift: int = 0,
    body_height: float = 1.75,
) -> HumanReplay:
    """Replay lift ``lift`` (0-based, among the lifts of files with angles) of a stored analysis.

    Args:
        overlays: the analysis' stored overlays (angles [deg] per file, lifts with their times).
        t_plan: (T,) plan time grid [s].
        lift: which lift with recorded angles.
        body_height: subject stature [m] (the analysis' ``settings.body_height_m``).

    Raises:
        ReplayError: the analysis has no lift with recorded angles, or not that many.
    """
    files = [f.get("file") for f in overlays.meta.get("files", [])]
    candidates = []
    for entry in overlays.meta.get("lifts", []):
        k = files.index(entry["file"]) if entry.get("file") in files else -1
        if f"files.{k}.angles.elbow_deg" in overlays.series:
            candidates.append((k, entry))
    if not candidates:
        raise ReplayError("the analysis has no lift with recorded elbow angles")
    if not 0 <= lift < len(candidates):
        raise ReplayError(f"lift {lift} does not exist: the analysis has {len(candidates)}")
    k, entry = candidates[lift]
    t_rec, elbow = overlays.series[f"files.{k}.angles.elbow_deg"]
    shoulder = overlays.series.get(f"files.{k}.angles.shoulder_deg")
    return replay_lift(
        t_plan,
        t_rec,
        None if shoulder is None else shoulder[1],
        elbow,
        start=float(entry["start_s"]),
        top=float(entry["top_s"]),
        body_height=body_height,
        lift={
            "file": str(entry["file"]),
            "index": int(entry.get("index", lift)),
            "start_s": float(entry["start_s"]),
            "top_s": float(entry["top_s"]),
        },
    )


def lifts_with_angles(overlays: AnalysisOverlays) -> int:
    """How many lifts of a stored analysis have recorded elbow angles (replayable)."""
    files = [f.get("file") for f in overlays.meta.get("files", [])]
    return sum(
        1
        for entry in overlays.meta.get("lifts", [])
        if entry.get("file") in files
        and f"files.{files.index(entry['file'])}.angles.elbow_deg" in overlays.series
    )
