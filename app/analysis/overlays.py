"""Plot-ready series of an analysis: decimated once, stored with it, cut into windows on request.

A 10-minute session at 2 kHz has 1.2 M samples per channel, and its analysis takes seconds. The
recording detail page must not wait for either. The analysis job therefore keeps what the page
plots (EMG envelopes with onsets, shoulder and elbow angles and velocities, lifts with their
A/B/C phases, the template) as :class:`AnalysisOverlays`: every series min/max-decimated to
``rate`` samples per second, which keeps each 1/``rate``-second bucket's extremes. The stored
form (:meth:`AnalysisOverlays.to_arrays`) is a few MB for ten minutes, and a window of it at
screen resolution (:meth:`AnalysisOverlays.window`) takes milliseconds.

Envelopes are low-passed at 6 Hz and the arm moves below 10 Hz, so 200 samples per second (min
and max of every 10 ms) lose nothing a plot can show, even zoomed to a single lift.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
from numpy.typing import NDArray

from app.analysis.downsample import minmax_downsample
from app.analysis.segmentation import PhaseMeta
from app.errors import BioPlanError
from app.jsonsafe import json_safe

if TYPE_CHECKING:
    from app.analysis.pipeline import AnalysisResult, LiftReport, RecordingAnalysis

FloatArray = NDArray[np.float64]

#: Samples per second kept of every series (min/max pairs of 10 ms buckets).
OVERLAY_RATE = 200.0
_META_KEY = "meta.json"
_ANGLE_SERIES = ("shoulder_deg", "elbow_deg", "shoulder_velocity_deg_s", "elbow_velocity_deg_s")


class OverlaysError(BioPlanError):
    """Stored overlays that this module did not write, or an impossible window."""


class LiftMeta(TypedDict):
    """A lift in the overlays' meta (``meta["lifts"]``): times [s] on its file's clock."""

    file: str
    index: int
    source: str
    start_s: float
    top_s: float
    hold_s: list[float]
    end_s: float
    peak_velocity_angle_deg: float
    phases: list[PhaseMeta]
    activation_order: list[str]


def _lift_meta(source: str, report: LiftReport) -> LiftMeta:
    """One lift of file ``source``: its times [s] on the file's clock, phases and order."""
    lift = report.lift
    return {
        "file": source,
        "index": report.index,
        "source": lift.source,
        "start_s": lift.start,
        "top_s": lift.top,
        "hold_s": list(lift.hold),
        "end_s": lift.end,
        "peak_velocity_angle_deg": math.degrees(report.profile.peak_velocity_angle),
        "phases": [p.phase.to_dict() for p in report.phases],
        "activation_order": list(report.activation_order),
    }


def _file_meta(rec: RecordingAnalysis) -> dict[str, Any]:
    """One file of the analysis: its span on its clock, side, warnings and rate check."""
    times = [m.t for m in rec.emg] + ([rec.angles.t + rec.offset] if rec.angles else [])
    starts = [float(t[0]) for t in times if len(t)]
    ends = [float(t[-1]) for t in times if len(t)]
    return {
        "file": rec.source,
        "format": rec.format,
        "span": [min(starts), max(ends)] if starts else None,
        "angles": None if rec.angles is None else {"file": rec.source, "side": rec.angles.side},
        "lifts": len(rec.lifts),
        "warnings": list(rec.warnings),
        "rate_check": None if rec.rate_check is None else rec.rate_check.to_dict(),
    }


def downsample_with_gaps(
    t: FloatArray,
    y: FloatArray,
    points: int,
    t0: float | None = None,
    t1: float | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Min/max-downsampled samples of ``y(t)`` in [t0, t1], with one NaN marking each gap.

    Downsampling drops missing (NaN) samples, and a plot would then draw a straight line across
    a gap in the pose (a hidden arm, skipped video frames). One NaN in the middle of every run
    of missing samples keeps the gap visible; applying this twice (store, then window) keeps it
    too.

    Args:
        t: (N,) sample times [s], increasing.
        y: (N,) samples, NaN where missing.
        points: largest number of valid samples returned (>= 2); gap markers come on top.
        t0, t1: window [s]; None = from the start / to the end.

    Returns:
        (t_out, y_out), (M,) each, in time order; y_out is NaN exactly at the gap markers.
    """
    i0 = 0 if t0 is None else int(np.searchsorted(t, t0, side="left"))
    i1 = len(t) if t1 is None else int(np.searchsorted(t, t1, side="right"))
    tw = np.asarray(t[i0:i1], dtype=np.float64)
    yw = np.asarray(y[i0:i1], dtype=np.float64)
    missing = ~np.isfinite(yw)
    yw = np.where(missing, np.nan, yw)
    ts, ys = minmax_downsample(tw, yw, points)
    if not missing.any():
        return ts, ys
    edges = np.diff(missing.astype(np.int8), prepend=0, append=0)
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    gaps = 0.5 * (tw[starts] + tw[ends - 1])
    t_all = np.concatenate([ts, gaps])
    y_all = np.concatenate([ys, np.full(len(gaps), np.nan)])
    order = np.argsort(t_all, kind="stable")
    return t_all[order], y_all[order]


def _json_series(t: FloatArray, y: FloatArray) -> dict[str, list[Any]]:
    """``{"t", "y"}`` lists with null where y is NaN (a gap)."""
    return {"t": t.tolist(), "y": [None if math.isnan(v) else v for v in y.tolist()]}


@dataclass(frozen=True)
class AnalysisOverlays:
    """What the recording detail page draws of an analysis, decimated for storage.

    Attributes:
        meta: JSON-ready description: ``emg`` [{"muscle", "channel", "file", "unit", "onsets"
            (M, 2) [s]}], ``angles`` {"file", "side"} or None, ``lifts`` [{"file", "index",
            "source", "start_s", "top_s", "end_s", "peak_velocity_angle_deg", "phases"
            [{"name", "part", "start_s", "end_s"}], "activation_order"}], ``template``,
            ``activation_order``, ``warnings``, ``span`` [first, last] sample time [s], ``rate``.
        series: name -> (t (N,) [s], y (N,)) with NaN marking gaps; names are ``emg.<i>`` (the
            i-th entry of meta["emg"], envelope in its unit) and ``angles.<name>`` for the
            shoulder and elbow angles [deg] and velocities [deg/s].
    """

    meta: dict[str, Any]
    series: dict[str, tuple[FloatArray, FloatArray]]

    @classmethod
    def from_result(cls, result: AnalysisResult, *, rate: float = OVERLAY_RATE) -> AnalysisOverlays:
        """Decimate an analysis to ``rate`` samples per second per series.

        Args:
            result: the analysis (``app.analysis.analyze_recordings``).
            rate: samples per second kept [1/s] (> 0).
        """
        if not (math.isfinite(rate) and rate > 0):
            raise OverlaysError(f"rate must be a positive number of samples per second, got {rate}")
        series: dict[str, tuple[FloatArray, FloatArray]] = {}
        span = [math.inf, -math.inf]

        def keep(name: str, t: FloatArray, y: FloatArray) -> None:
            if not len(t):
                return
            span[0], span[1] = min(span[0], float(t[0])), max(span[1], float(t[-1]))
            points = max(2, math.ceil(rate * float(t[-1] - t[0])))
            series[name] = downsample_with_gaps(t, y, points)

        emg: list[dict[str, Any]] = []
        angles: dict[str, Any] | None = None
        lifts: list[LiftMeta] = []
        files: list[dict[str, Any]] = []
        for rec in result.recordings:
            for m in rec.emg:
                keep(f"emg.{len(emg)}", m.t, m.envelope)
                emg.append(
                    {
                        "muscle": m.muscle,
                        "channel": m.channel,
                        "file": rec.source,
                        "unit": m.unit,
                        "onsets": [[float(a), float(b)] for a, b in np.asarray(m.onsets)],
                    }
                )
            if rec.angles is not None:
                a = rec.angles
                t = a.t + rec.offset
                values = (a.shoulder, a.elbow, a.shoulder_velocity, a.elbow_velocity)
                k = len(files)
                for name, values_rad in zip(_ANGLE_SERIES, values, strict=True):
                    keep(f"files.{k}.angles.{name}", t, np.degrees(values_rad))
                angles = angles or {"file": rec.source, "side": a.side}
            files.append(_file_meta(rec))
            lifts.extend(_lift_meta(rec.source, report) for report in rec.lifts)
        meta = {
            "rate": rate,
            "span": span,  # inf (no series at all) becomes null
            "emg": emg,
            "angles": angles,
            "lifts": lifts,
            # Separate trials: each file on its own clock, with its own span, angles, lifts
            # (entries of "lifts" and "emg" name their "file") and warnings.
            "session": result.settings.get("session", "separate"),
            "files": files,
            "template": result.template.to_dict(),
            "activation_order": list(result.activation_order),
            "warnings": list(result.warnings)
            + [w for rec in result.recordings for w in rec.warnings],
        }
        return cls(meta=json_safe(meta), series=series)

    def window(
        self, *, points: int = 2000, t0: float | None = None, t1: float | None = None
    ) -> dict[str, Any]:
        """The overlays inside [t0, t1], at most ``points`` samples per series, JSON-ready.

        Args:
            points: largest number of samples per series (min/max downsampling).
            t0, t1: window [s] on the recording's common (EMG) clock; None = from start / to end.
                ``t0 == t1`` is one instant: the samples stored at exactly that time.

        Returns:
            ``meta`` plus ``"window": [t0, t1]``, ``"points"``, each ``emg`` entry with
            ``"envelope": {"t", "y"}`` and ``angles`` with ``shoulder_deg``, ``elbow_deg``,
            ``shoulder_velocity_deg_s`` and ``elbow_velocity_deg_s`` as ``{"t", "y"}`` (null
            marks a gap).

        Raises:
            OverlaysError: points < 2 or t1 < t0.
        """
        if points < 2:
            raise OverlaysError(f"points must be >= 2, got {points}")
        if t0 is not None and t1 is not None and t1 < t0:
            raise OverlaysError(f"the window end t1={t1} must not be before its start t0={t0}")

        def cut(name: str) -> dict[str, list[Any]]:
            if name not in self.series:
                return {"t": [], "y": []}
            t, y = self.series[name]
            return _json_series(*downsample_with_gaps(t, y, points, t0, t1))

        out = dict(self.meta)
        out["window"] = [t0, t1]
        out["points"] = points
        out["emg"] = [{**e, "envelope": cut(f"emg.{i}")} for i, e in enumerate(self.meta["emg"])]
        out["files"] = [
            {**f, "angles": None}
            if f.get("angles") is None
            else {
                **f,
                "angles": {
                    **f["angles"],
                    **{n: cut(f"files.{k}.angles.{n}") for n in _ANGLE_SERIES},
                },
            }
            for k, f in enumerate(self.meta.get("files", []))
        ]
        if self.meta["angles"] is not None:
            # The first file with angles; overlays stored before per-file entries existed
            # hold its series under "angles.<name>".
            first = next(
                (k for k, f in enumerate(self.meta.get("files", [])) if f.get("angles")), None
            )
            prefix = "angles" if first is None else f"files.{first}.angles"
            out["angles"] = {
                **self.meta["angles"],
                **{name: cut(f"{prefix}.{name}") for name in _ANGLE_SERIES},
            }
        return out

    def to_arrays(self) -> dict[str, NDArray[np.generic]]:
        """Named arrays for storage (``.npz``): times float64, values float32, meta as UTF-8."""
        meta = json.dumps(self.meta, allow_nan=False).encode()
        arrays: dict[str, NDArray[np.generic]] = {_META_KEY: np.frombuffer(meta, dtype=np.uint8)}
        for name, (t, y) in self.series.items():
            arrays[f"{name}.t"] = np.asarray(t, dtype=np.float64)
            # Plots need 7 digits, not 16: float32 halves what is stored.
            arrays[f"{name}.y"] = np.asarray(y, dtype=np.float32)
        return arrays

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray[np.generic]]) -> AnalysisOverlays:
        """Inverse of :meth:`to_arrays`.

        Raises:
            OverlaysError: the arrays were not written by :meth:`to_arrays`.
        """
        if _META_KEY not in arrays:
            raise OverlaysError(f"stored overlays have no {_META_KEY!r} entry")
        try:
            meta = json.loads(np.asarray(arrays[_META_KEY], dtype=np.uint8).tobytes())
        except (ValueError, UnicodeDecodeError) as exc:
            raise OverlaysError(f"stored overlays have unreadable metadata: {exc}") from None
        series: dict[str, tuple[FloatArray, FloatArray]] = {}
        for key in arrays:
            if not key.endswith(".t"):
                continue
            name = key[:-2]
            if f"{name}.y" not in arrays:
                raise OverlaysError(f"stored overlays have times but no values for {name!r}")
            t = np.asarray(arrays[key], dtype=np.float64)
            y = np.asarray(arrays[f"{name}.y"], dtype=np.float64)
            if t.shape != y.shape or t.ndim != 1:
                raise OverlaysError(f"stored series {name!r} has shapes {t.shape} and {y.shape}")
            series[name] = (t, y)
        return cls(meta=meta, series=series)
