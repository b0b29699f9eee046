"""What the recording detail page plots beyond the raw channels: the analysis, as series.

The service's analysis job stores a JSON summary; envelopes, angles and velocities stay on the
analysis objects. ``RecordingSignals`` runs the analysis package on a stored recording once
(reading the stored bytes with the upload's reader options, as the job does), keeps the result
in a small cache, and cuts min/max-downsampled windows of it for the plots, so zooming into a
long recording fetches only the samples the screen can show.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from app.analysis import AnalysisResult
    from app.api.deps import Services

FloatArray = NDArray[np.float64]


class SignalsError(LookupError):
    """The recording does not exist."""


def _window(
    t: FloatArray, y: FloatArray, points: int, t0: float | None, t1: float | None
) -> dict[str, list[Any]]:
    """Min/max-downsampled samples of ``y(t)`` in [t0, t1], with a null where data is missing.

    Downsampling drops missing (NaN) samples; a plot would then draw a straight line across
    a gap in the pose (a hidden arm, skipped video frames). One null in the middle of every
    run of missing samples keeps the gap visible.
    """
    from app.api.downsample import minmax_downsample

    keep = np.ones(t.shape, dtype=bool)
    if t0 is not None:
        keep &= t >= t0
    if t1 is not None:
        keep &= t <= t1
    tw, yw = t[keep], np.where(np.isfinite(y[keep]), y[keep], np.nan)
    ts, ys = minmax_downsample(tw, yw, points)
    missing = np.isnan(yw)
    if not missing.any():
        return {"t": ts.tolist(), "y": ys.tolist()}
    edges = np.diff(missing.astype(np.int8), prepend=0, append=0)
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    gaps = 0.5 * (tw[starts] + tw[ends - 1])
    t_all = np.concatenate([ts, gaps])
    y_all: list[float | None] = [*ys.tolist(), *([None] * len(gaps))]
    order = np.argsort(t_all, kind="stable")
    return {"t": t_all[order].tolist(), "y": [y_all[i] for i in order]}


def _deg(x: float) -> float | None:
    return None if not math.isfinite(x) else math.degrees(x)


def _num(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


@dataclass(frozen=True)
class RecordingSignals:
    """The analysis of one recording, ready to be cut into plot windows.

    Attributes:
        recording_id: the stored recording.
        result: the analysis (``app.analysis.AnalysisResult``).
    """

    recording_id: int
    result: AnalysisResult

    def series(
        self, *, points: int = 2000, t0: float | None = None, t1: float | None = None
    ) -> dict[str, Any]:
        """Envelopes with onsets, arm angles and velocities, lifts with phases, the template.

        Args:
            points: largest number of samples per series (min/max downsampling).
            t0, t1: window [s] on the recording's common (EMG) clock; None = from start / to end.

        Returns:
            JSON-ready ``{"recording_id", "window", "emg": [{"muscle", "channel", "unit",
            "envelope": {"t", "y"}, "onsets"}], "angles": {"shoulder_deg", "elbow_deg",
            "shoulder_velocity_deg_s", "elbow_velocity_deg_s"} | None, "lifts": [...],
            "template": {...}, "activation_order", "warnings"}``. Angles in degrees.
        """
        if points < 2:
            raise ValueError(f"points must be >= 2, got {points}")
        if t0 is not None and t1 is not None and t1 <= t0:
            raise ValueError(f"the window end t1={t1} must be after its start t0={t0}")
        emg: list[dict[str, Any]] = []
        angles: dict[str, Any] | None = None
        lifts: list[dict[str, Any]] = []
        span = [math.inf, -math.inf]
        for rec in self.result.recordings:
            for m in rec.emg:
                span = [min(span[0], float(m.t[0])), max(span[1], float(m.t[-1]))]
                emg.append(
                    {
                        "muscle": m.muscle,
                        "channel": m.channel,
                        "file": rec.source,
                        "unit": m.unit,
                        "envelope": _window(m.t, m.envelope, points, t0, t1),
                        "onsets": [[float(a), float(b)] for a, b in np.asarray(m.onsets)],
                    }
                )
            if rec.angles is not None and angles is None:
                a = rec.angles
                t = a.t + rec.offset
                span = [min(span[0], float(t[0])), max(span[1], float(t[-1]))]
                angles = {
                    "file": rec.source,
                    "side": a.side,
                    "shoulder_deg": _window(t, np.degrees(a.shoulder), points, t0, t1),
                    "elbow_deg": _window(t, np.degrees(a.elbow), points, t0, t1),
                    "shoulder_velocity_deg_s": _window(
                        t, np.degrees(a.shoulder_velocity), points, t0, t1
                    ),
                    "elbow_velocity_deg_s": _window(
                        t, np.degrees(a.elbow_velocity), points, t0, t1
                    ),
                }
            for report in rec.lifts:
                lift = report.lift
                lifts.append(
                    {
                        "file": rec.source,
                        "index": report.index,
                        "source": lift.source,
                        "start_s": lift.start,
                        "top_s": lift.top,
                        "end_s": lift.end,
                        "peak_velocity_angle_deg": _deg(report.profile.peak_velocity_angle),
                        "phases": [
                            {
                                "name": p.phase.name,
                                "part": p.phase.part,
                                "start_s": p.phase.start,
                                "end_s": p.phase.end,
                            }
                            for p in report.phases
                        ],
                        "activation_order": list(report.activation_order),
                    }
                )
        template = {k: _num(v) for k, v in self.result.template.to_dict().items()}
        return {
            "recording_id": self.recording_id,
            "points": points,
            "window": [t0, t1],
            "span": [None if not math.isfinite(s) else s for s in span],
            "emg": emg,
            "angles": angles,
            "lifts": lifts,
            "template": template,
            "activation_order": list(self.result.activation_order),
            "warnings": list(self.result.warnings)
            + [w for rec in self.result.recordings for w in rec.warnings],
        }


def analyse_stored(
    files: Sequence[tuple[str, bytes]], options: dict[str, Any], load_kg: float | None
) -> AnalysisResult:
    """Analyse stored files as the analysis job does (same reader options and defaults).

    Args:
        files: (file name, bytes) of the recording session.
        options: the reader options stored at upload (rate, emg_rate, muscle_map, ...).
        load_kg: the recorded load; the job's default (12 kg) when None.
    """
    from app.analysis import analyze_recordings
    from app.recordings import read_bytes

    read_options = {k: v for k, v in options.items() if v is not None}
    if "image_size" in read_options:
        read_options["image_size"] = tuple(read_options["image_size"])
    recordings = [read_bytes(data, name, **read_options) for name, data in files]
    kwargs: dict[str, Any] = {"muscle_map": read_options.get("muscle_map")}
    if read_options.get("emg_rate") is not None:
        kwargs["emg_rate"] = read_options["emg_rate"]
    if load_kg is not None:
        kwargs["load_mass"] = float(load_kg)
    return analyze_recordings(recordings, **kwargs)


class SignalsCache:
    """Analyses of stored recordings, most recently used kept (they take seconds to compute).

    Args:
        size: recordings kept in memory.
    """

    def __init__(self, size: int = 4) -> None:
        self.size = size
        self._items: OrderedDict[tuple[int, tuple[str, ...]], RecordingSignals] = OrderedDict()
        self._lock = threading.Lock()
        self._busy: dict[tuple[int, tuple[str, ...]], threading.Lock] = {}

    def get(self, services: Services, recording_id: int) -> RecordingSignals:
        """The analysis of a stored recording (computed on first use).

        Raises:
            SignalsError: no such recording.
            ValueError: the analysis refuses the recording (message says why).
        """
        from app.db import crud

        with services.sessions() as session:
            rec = crud.get_recording(session=session, recording_id=recording_id)
            if rec is None:
                raise SignalsError(f"recording {recording_id} does not exist")
            hashes = tuple(f.sha256 for f in rec.files)
            names = [f.original_name for f in rec.files]
            options = dict(rec.options or {})
            load_kg = rec.load_kg
        key = (recording_id, hashes)
        with self._lock:
            hit = self._items.get(key)
            if hit is not None:
                self._items.move_to_end(key)
                return hit
            busy = self._busy.setdefault(key, threading.Lock())
        # One computation per recording at a time; a second request waits for the first.
        with busy:
            with self._lock:
                hit = self._items.get(key)
            if hit is not None:
                return hit
            files = [(n, services.blobs.get(h)) for n, h in zip(names, hashes, strict=True)]
            signals = RecordingSignals(recording_id, analyse_stored(files, options, load_kg))
            with self._lock:
                self._items[key] = signals
                while len(self._items) > self.size:
                    self._items.popitem(last=False)
                self._busy.pop(key, None)
        return signals
