"""One entry point for the CLI and the service: recordings in, lifts, phases, onsets and a
HumanTemplate out.

Per recording: EMG envelopes and onsets; arm angles from landmarks or markers; one clock (the
EMG clock; pose times + offset); lifts from the elbow angle, or from EMG bursts without one;
A/B/C phases with per-phase EMG and kinematics; per-lift activation order and energetics. Then
one template over all lifts. Arrays a dashboard plots stay on the result objects; ``to_dict`` is
the JSON summary (degrees at this edge, seconds on the common clock).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any, Literal, TypedDict, Unpack

import numpy as np
from numpy.typing import NDArray

from app.analysis.emg import (
    NYQUIST_CAP,
    activation_order,
    detect_onsets,
    emg_process,
    peak_times,
    saturation_flags,
)
from app.analysis.energetics import ArmDynamics, Energetics, human_arm_dynamics, lift_energetics
from app.analysis.pose import ArmAngles, angles_from_channels, arm_angles
from app.analysis.segmentation import Lift, Phase, detect_emg_lifts, detect_lifts, split_phases
from app.analysis.sync import estimate_offset
from app.analysis.template import LiftProfile, build_template, consensus_order, lift_profile
from app.names import MAX_VIDEO_SECONDS, PHASE_BOUNDS_DEG
from app.options import Options, option
from app.planning.human_template import HumanTemplate
from app.recordings.types import SITES, Channel, RateCheck, Recording, RecordingError, rate_check

logger = logging.getLogger("bioplan.analysis")

#: EMG onsets are searched from this long before a lift's start [s] (EMG leads the movement;
#: a muscle that bears the load early switches on well before the forearm moves), but never
#: before the previous lift's end.
ONSET_LEAD = 1.0
#: Energetics run on the angles thinned to at least this rate [Hz]: the angles are low-passed
#: at 6 Hz, so 250 Hz loses nothing, while a 2 kHz goniometer made the arm's inverse dynamics
#: half of a long session's analysis.
ENERGETICS_RATE = 250.0
#: A lift is low-quality when more than this share of its frames is (pose detection quality:
#: the arm poorly seen, limbs of implausible lengths, or another person tracked); it is kept
#: out of the template unless the analysis keeps low-quality lifts.
MAX_LOW_QUALITY_SHARE = 0.2
#: Why low-quality lifts are left out, as the template's provenance says it.
LOW_QUALITY_REASON = "low pose quality"


@dataclass(frozen=True)
class MuscleSeries:
    """One EMG channel, processed.

    Attributes:
        muscle: the site (``deltoid``, ``triceps``, ``biceps``, ``forearm``) when mapped, else
            the channel name.
        channel: channel name in the file.
        t: (N,) sample times [s] on the common (EMG) clock.
        raw: (N,) raw EMG [unit].
        filtered: (N,) band-passed EMG [unit].
        envelope: (N,) linear envelope [unit].
        onsets: (M, 2) onset/offset times [s].
        saturated_fraction: share of samples flagged as clipped.
        unit: the EMG unit (``"V"`` after the readers' conversion).
    """

    muscle: str
    channel: str
    t: NDArray[np.float64]
    raw: NDArray[np.float64]
    filtered: NDArray[np.float64]
    envelope: NDArray[np.float64]
    onsets: NDArray[np.float64]
    saturated_fraction: float
    unit: str

    @property
    def rate(self) -> float:
        return float(1.0 / (self.t[1] - self.t[0])) if len(self.t) > 1 else 0.0

    @cached_property
    def peak(self) -> float:
        # Cached: every phase of every lift divides by it (hundreds of passes over 1 M samples).
        return float(np.max(self.envelope))


@dataclass(frozen=True)
class PhaseStats:
    """One phase of one lift with its EMG and kinematics.

    Attributes:
        phase: name, part and times [s].
        emg_mean, emg_peak: muscle -> mean / peak envelope over the phase, as a fraction of that
            muscle's envelope peak over the whole recording.
        peak_velocity: largest |elbow velocity| [rad/s] (NaN if unknown).
        peak_acceleration: largest |elbow acceleration| [rad/s^2] (NaN if unknown).
    """

    phase: Phase
    emg_mean: dict[str, float]
    emg_peak: dict[str, float]
    peak_velocity: float
    peak_acceleration: float

    def to_dict(self) -> dict[str, Any]:
        return {
            **self.phase.to_dict(),
            "duration_s": self.phase.duration,
            "emg_mean": self.emg_mean,
            "emg_peak": self.emg_peak,
            "peak_velocity_deg_s": _deg(self.peak_velocity),
            "peak_acceleration_deg_s2": _deg(self.peak_acceleration),
        }


@dataclass(frozen=True)
class LiftReport:
    """One lift with everything measured on it.

    Attributes:
        index: 1-based number within its recording.
        lift: start/top/end [s] on the common clock.
        phases: per-phase statistics (empty for EMG-only lifts).
        onsets: muscle -> onset time relative to the lift's start [s] (negative = before).
        activation_order: muscles by onset.
        emg_peak_times: muscle -> time of the envelope peak during the concentric part [s].
        profile: the kinematic/EMG features that feed the template.
        energetics: torques, power and energies (None without angles or dynamics).
        low_quality_share: share of the lift's pose frames that are low-quality (None without
            a per-frame quality, e.g. motion capture or EMG-only lifts).
        low_quality: more than :data:`MAX_LOW_QUALITY_SHARE` of its frames are low-quality;
            such a lift is left out of the template unless low-quality lifts are kept.
        quality_reasons: why its frames are low-quality: reason -> frames.
    """

    index: int
    lift: Lift
    phases: list[PhaseStats]
    onsets: dict[str, float]
    activation_order: tuple[str, ...]
    emg_peak_times: dict[str, float]
    profile: LiftProfile
    energetics: Energetics | None = None
    low_quality_share: float | None = None
    low_quality: bool = False
    quality_reasons: dict[str, int] = field(default_factory=dict)

    @property
    def emg_peak_after_velocity_peak(self) -> dict[str, float]:
        """muscle -> envelope peak time minus the elbow-velocity peak time [s] (the EMG peaks
        aligned with the kinematic characteristic point; negative = EMG first)."""
        frac = self.profile.peak_velocity_time_fraction
        if not np.isfinite(frac):
            return {}
        t_peak = self.lift.start + frac * (self.lift.top - self.lift.start)
        return {m: t - t_peak for m, t in self.emg_peak_times.items()}

    def to_dict(self) -> dict[str, Any]:
        lift, prof = self.lift, self.profile
        return {
            "index": self.index,
            "source": lift.source,
            "start_s": lift.start,
            "top_s": lift.top,
            "end_s": lift.end,
            "concentric_s": [lift.start, lift.top],
            "hold_s": list(lift.hold),
            "eccentric_s": list(lift.eccentric),
            "start_angle_deg": _deg(lift.start_angle),
            "top_angle_deg": _deg(lift.top_angle),
            "end_angle_deg": _deg(lift.end_angle),
            "peak_velocity_deg_s": _deg(prof.peak_velocity),
            "peak_velocity_angle_deg": _deg(prof.peak_velocity_angle),
            "peak_velocity_time_fraction": _num(prof.peak_velocity_time_fraction),
            "peak_velocity_range_fraction": _num(prof.peak_velocity_range_fraction),
            "kinematics_rejected": prof.rejected or None,
            "phases": [p.to_dict() for p in self.phases],
            "onsets_s": self.onsets,
            "activation_order": list(self.activation_order),
            "emg_peak_s": self.emg_peak_times,
            "emg_peak_time_fraction": prof.emg_peak_time_fraction,
            "emg_peak_after_velocity_peak_s": self.emg_peak_after_velocity_peak,
            "energetics": self.energetics.to_dict() if self.energetics else None,
            "quality": None
            if self.low_quality_share is None
            else {
                "low_quality_share": self.low_quality_share,
                "low_quality": self.low_quality,
                "reasons": dict(self.quality_reasons),
            },
        }


@dataclass(frozen=True)
class RecordingAnalysis:
    """Everything measured on one recording (or one merged session).

    Attributes:
        source: file name(s).
        format: detected format(s).
        emg: processed EMG channels.
        angles: arm angles on the pose clock (None without pose).
        offset: t_emg = t_pose + offset [s].
        lifts: the lifts found.
        warnings: what was assumed or skipped.
        rate_check: an implausible stored EMG rate and the suggested one (None when plausible).
    """

    source: str
    format: str
    emg: list[MuscleSeries]
    angles: ArmAngles | None
    offset: float
    lifts: list[LiftReport]
    warnings: list[str] = field(default_factory=list)
    rate_check: RateCheck | None = None

    @property
    def pose_t(self) -> NDArray[np.float64] | None:
        """(T,) pose sample times on the common clock [s]."""
        return None if self.angles is None else self.angles.t + self.offset

    def to_dict(self) -> dict[str, Any]:
        pose: dict[str, Any] | None = None
        if self.angles is not None:
            a = self.angles
            elbow = a.elbow[np.isfinite(a.elbow)]
            pose = {
                "side": a.side,
                "rate_hz": a.rate,
                "samples": len(a.t),
                "valid_fraction": float(a.valid.mean()),
                "gaps_s": (a.gaps + self.offset).tolist(),
                "elbow_range_deg": [_deg(float(elbow.min())), _deg(float(elbow.max()))]
                if elbow.size
                else None,
                "quality": None if a.quality is None else a.quality.summary(),
            }
        return {
            "source": self.source,
            "format": self.format,
            "offset_s": self.offset,
            "emg": {
                m.muscle: {
                    "channel": m.channel,
                    "rate_hz": m.rate,
                    "unit": m.unit,
                    "onsets_s": m.onsets.tolist(),
                    "saturated_fraction": m.saturated_fraction,
                }
                for m in self.emg
            },
            "pose": pose,
            "lifts": [lift.to_dict() for lift in self.lifts],
            "warnings": list(self.warnings),
            "rate_check": None if self.rate_check is None else self.rate_check.to_dict(),
        }


@dataclass(frozen=True)
class AnalysisResult:
    """The analysis of one or more recordings and the template built from all their lifts."""

    recordings: list[RecordingAnalysis]
    template: HumanTemplate
    settings: dict[str, Any]
    warnings: list[str] = field(default_factory=list)

    @property
    def lifts(self) -> list[LiftReport]:
        return [lift for rec in self.recordings for lift in rec.lifts]

    @property
    def activation_order(self) -> tuple[str, ...]:
        return consensus_order([r.activation_order for r in self.lifts if r.activation_order])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: per file lifts with phases and stats, onsets per muscle,
        activation order, the template, warnings."""
        return {
            "files": [rec.to_dict() for rec in self.recordings],
            "n_lifts": len(self.lifts),
            "activation_order": list(self.activation_order),
            "template": self.template.to_dict(),
            "settings": self.settings,
            "warnings": list(self.warnings),
        }

    def summary(self) -> str:
        """Human-readable report of lifts, phases, onsets and the template."""
        lines: list[str] = []
        for rec in self.recordings:
            lines.append(f"{rec.source} ({rec.format})")
            if rec.emg:
                muscles = ", ".join(f"{m.muscle} [{m.channel}]" for m in rec.emg)
                lines.append(f"  EMG: {muscles}")
            if rec.angles is not None:
                a = rec.angles
                lines.append(
                    f"  pose: {a.side} arm, {a.rate:g} Hz, {100 * a.valid.mean():.0f}% valid, "
                    f"{len(a.gaps)} gap(s); clock offset {rec.offset:+.3f} s"
                )
            # With channels mapped to the method's sites, the text shows those (JSON has all).
            names = {m.muscle for m in rec.emg}
            shown = names & set(SITES) or names
            if shown != names:
                lines.append(
                    f"  (per-lift EMG below for {', '.join(sorted(shown))}; all in --json)"
                )
            lines.append(f"  lifts: {len(rec.lifts)}")
            for r in rec.lifts:
                lines.extend(_lift_lines(r, shown))
            for w in rec.warnings:
                lines.append(f"  warning: {w}")
        tpl = self.template
        lines.append(f"template ({tpl.source}):")
        lines.append(
            f"  peak velocity at {tpl.peak_velocity_angle_deg:.1f}"
            f" +- {tpl.peak_velocity_angle_sd_deg:.1f} deg elbow flexion"
        )
        if tpl.peak_velocity_range_fraction is not None and tpl.lift_range_deg is not None:
            lo, hi = tpl.lift_range_deg
            lines.append(
                f"  = {100 * tpl.peak_velocity_range_fraction:.0f}"
                f" +- {100 * tpl.peak_velocity_range_fraction_sd:.0f}% of the lifts' range"
                f" ({lo:.0f} -> {hi:.0f} deg); the planner places the peak there on the robot's"
                " stroke"
            )
        if tpl.peak_velocity_time_fraction is not None:
            lines.append(f"  at {100 * tpl.peak_velocity_time_fraction:.0f}% of the lifting time")
        if tpl.activation_order:
            lines.append(f"  activation order: {' -> '.join(tpl.activation_order)}")
        for w in self.warnings:
            lines.append(f"warning: {w}")
        return "\n".join(lines)


def _lift_lines(r: LiftReport, shown: set[str]) -> list[str]:
    """The summary lines of one lift: times, angles, peak velocity, then per concentric phase
    its duration and mean EMG, the onsets and the energetics (EMG of muscles ``shown`` only)."""
    lines: list[str] = []
    lift = r.lift
    head = f"    #{r.index} {lift.start:7.2f}-{lift.top:7.2f}-{lift.end:7.2f} s ({lift.source})"
    if np.isfinite(lift.top_angle):
        head += f"  elbow {_deg(lift.start_angle):.0f}->{_deg(lift.top_angle):.0f} deg"
    if np.isfinite(r.profile.peak_velocity):
        head += (
            f"  v_peak {_deg(r.profile.peak_velocity):.0f} deg/s"
            f" at {_deg(r.profile.peak_velocity_angle):.0f} deg"
        )
    if r.low_quality:
        head += f"  LOW POSE QUALITY ({100 * (r.low_quality_share or 0):.0f}% of frames)"
    lines.append(head)
    for p in r.phases:
        if p.phase.part != "concentric":
            continue
        emg = " ".join(f"{m}={v:.2f}" for m, v in p.emg_mean.items() if m in shown)
        lines.append(
            f"       {p.phase.name}: {p.phase.duration:.2f} s"
            + (f"  EMG mean {emg}" if emg else "")
        )
    if r.activation_order:
        onset = ", ".join(f"{m} {r.onsets[m]:+.2f}s" for m in r.activation_order if m in shown)
        lines.append(f"       onsets: {onset}")
    if r.energetics is not None:
        m = r.energetics.metrics
        lines.append(
            f"       energy: pos_work {m['pos_work']:.1f} J"
            f" (floor dPE {m['delta_potential']:.1f} J),"
            f" peak power {m['peak_power']:.0f} W"
        )
    return lines


def _deg(x: float) -> float | None:
    return float(np.rad2deg(x)) if np.isfinite(x) else None


def _num(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


# ---------------------------------------------------------------------------------------------


def _site_for(channel: Channel, muscle_map: Mapping[str, str] | None) -> str | None:
    if muscle_map:
        name = channel.name.lower()
        for label, site in muscle_map.items():
            key = label.lower()
            if name == key or name.split(".")[0] == key or name.startswith(key):
                if site not in SITES:
                    raise RecordingError(
                        f"muscle map sends {label!r} to unknown site {site!r}",
                        expected=f"one of {', '.join(SITES)}",
                    )
                return site
    return channel.site


def _process_emg(
    recording: Recording,
    *,
    emg_rate: float | None,
    muscle_map: Mapping[str, str] | None,
    emg_options: Mapping[str, Any],
    warnings: list[str],
) -> list[MuscleSeries]:
    channels = recording.of_kind("emg")
    out: list[MuscleSeries] = []
    channels = _drop_unused(recording, channels, muscle_map, warnings)
    groups: dict[tuple[float, int, float], list[Channel]] = {}
    for ch in channels:
        rate = float(emg_rate) if emg_rate is not None else float(ch.rate)
        groups.setdefault((rate, ch.n_samples, float(ch.start)), []).append(ch)
    used: set[str] = set()
    for (rate, n, start), group in groups.items():
        names = [c.name for c in group]
        # (C, N) stacked, used as its (N, C) transpose: each channel stays contiguous, which
        # makes the per-channel checks and filters several times faster than an (N, C) block.
        x = np.stack([np.asarray(c.data, dtype=np.float64) for c in group]).T
        try:
            filtered, env = emg_process(x, rate, names=names, **emg_options)
        except RecordingError as exc:
            raise RecordingError(
                exc.message, file=recording.source, channel=exc.channel, expected=exc.expected
            ) from None
        _log_filters(recording.source, names, rate, emg_options)
        t = start + np.arange(n) / rate
        sat = saturation_flags(x)
        for j, ch in enumerate(group):
            muscle = _site_for(ch, muscle_map) or ch.name
            if muscle in used:
                muscle = ch.name
            used.add(muscle)
            onsets = detect_onsets(env[:, j], rate, name=ch.name) + start
            out.append(
                MuscleSeries(
                    muscle=muscle,
                    channel=ch.name,
                    t=t,
                    raw=x[:, j],
                    filtered=filtered[:, j],
                    envelope=env[:, j],
                    onsets=onsets,
                    saturated_fraction=float(sat[:, j].mean()),
                    unit=ch.unit,
                )
            )
    return out


def _log_filters(source: str, names: list[str], rate: float, options: Mapping[str, Any]) -> None:
    """Say which EMG channels are filtered how (the band's upper edge as capped below Nyquist)."""
    if not logger.isEnabledFor(logging.INFO):
        return
    band = options.get("band", (20.0, 450.0))
    shown = "none"
    if band is not None:
        high = min(float(band[1]), NYQUIST_CAP * rate / 2)
        capped = f" (capped from {band[1]:g} below Nyquist)" if high < float(band[1]) else ""
        shown = f"{band[0]:g}-{high:g} Hz{capped}"
    notch = options.get("notch")
    envelope = options.get("method", "lowpass")
    if envelope == "lowpass":
        envelope = f"low-pass {options.get('lowpass', 6.0):g} Hz"
    else:
        envelope = f"RMS {1000 * options.get('rms_window', 0.1):g} ms"
    logger.info(
        "%s: EMG %s at %g Hz: band-pass %s, notch %s, envelope %s",
        Path(source).name, ", ".join(names), rate, shown,
        f"{notch:g} Hz" if notch else "none", envelope,
    )  # fmt: skip


def _is_flat(ch: Channel) -> bool:
    data = np.asarray(ch.data, dtype=np.float64)
    finite = data[np.isfinite(data)]
    return finite.size > 0 and bool(np.all(finite == finite[0]))


def _drop_unused(
    recording: Recording,
    channels: list[Channel],
    muscle_map: Mapping[str, str] | None,
    warnings: list[str],
) -> list[Channel]:
    """Leave out flat (unused) EMG channels next to live ones, unless they are mapped to a
    site: a muscle the user asked for that carries no signal is an error, raised later."""
    flat = [c for c in channels if _is_flat(c)]
    if not flat or len(flat) == len(channels):
        return channels
    dropped = [c for c in flat if _site_for(c, muscle_map) is None]
    if dropped:
        warnings.append(
            f"{len(dropped)} flat (unused) EMG channel(s) left out: "
            + ", ".join(c.name for c in dropped[:8])
            + (" ..." if len(dropped) > 8 else "")
        )
    keep = {id(c) for c in dropped}
    return [c for c in channels if id(c) not in keep]


def _has_positions(recording: Recording) -> bool:
    return any(c.kind in ("landmark", "marker") for c in recording.channels.values())


def _span(t: NDArray[np.float64], t0: float, t1: float, tol: float = 0.0) -> slice:
    """Indices of the sorted times ``t`` inside [t0 - tol, t1 + tol], as a slice.

    Binary search instead of a boolean mask: a recording has hundreds of lifts and each lift
    several phases, and a mask over the whole recording per phase made a 10-minute 2 kHz
    session take minutes.
    """
    i0 = int(np.searchsorted(t, t0 - tol, side="left"))
    i1 = int(np.searchsorted(t, t1 + tol, side="right"))
    return slice(i0, max(i0, i1))


def _interval_stats(
    emg: Sequence[MuscleSeries], t0: float, t1: float
) -> tuple[dict[str, float], dict[str, float]]:
    means: dict[str, float] = {}
    peaks: dict[str, float] = {}
    for m in emg:
        seg = m.envelope[_span(m.t, t0, t1)]
        if not seg.size or m.peak <= 0:
            continue
        means[m.muscle] = float(seg.mean() / m.peak)
        peaks[m.muscle] = float(seg.max() / m.peak)
    return means, peaks


def _abs_peak(t: NDArray[np.float64], x: NDArray[np.float64], t0: float, t1: float) -> float:
    seg = x[_span(t, t0, t1, tol=1e-9)]
    seg = seg[np.isfinite(seg)]
    return float(np.max(np.abs(seg))) if seg.size else float("nan")


@dataclass(frozen=True)
class AnalysisOptions(Options):
    """What the user chose for one analysis; the same options rerun it unchanged.

    Attributes:
        emg_rate: true EMG sampling rate [Hz] when the file states a wrong one (None = stored).
        muscle_map: channel label -> site (``deltoid``, ``triceps``, ``biceps``, ``forearm``).
        exclude_channels: channel names left out of the analysis (case-insensitive).
        bounds: (A/B, B/C) elbow-flexion thresholds [rad].
        offset: t_emg = t_pose + offset [s]; ``"auto"`` = cross-correlation; None = 0.
        emg_options: options for :func:`emg_process`.
        pose_options: options for :func:`arm_angles` (``side``, ``min_visibility``...).
        keep_low_quality_lifts: keep lifts whose pose frames are mostly low-quality (another
            person tracked, the arm poorly seen, implausible limb lengths) in the template;
            by default they are flagged and left out.
    """

    emg_rate: float | None = option(
        None,
        help="true EMG sampling rate when the file states a wrong one",
        unit="Hz",
        gt=0,
        none_means="the stored rate",
    )
    muscle_map: Mapping[str, str] | None = option(
        None, help="channel label -> EMG site (deltoid, triceps, biceps, forearm)"
    )
    exclude_channels: frozenset[str] = option(
        frozenset(), help="channel names left out of the analysis (case-insensitive)"
    )
    bounds: tuple[float, float] = option(
        (float(np.deg2rad(PHASE_BOUNDS_DEG[0])), float(np.deg2rad(PHASE_BOUNDS_DEG[1]))),
        help="A/B and B/C elbow-flexion thresholds",
        unit="rad",
        api=False,  # the API and the CLI take them in degrees (phase_bounds_deg)
    )
    offset: float | Literal["auto"] | None = option(
        None,
        help='t_emg = t_pose + offset; "auto": by cross-correlation',
        unit="s",
        none_means="0",
    )
    emg_options: Mapping[str, Any] = option(
        help="options of emg_process (band, envelope)", default_factory=dict, api=False
    )
    pose_options: Mapping[str, Any] = option(
        help="options of arm_angles (side, min_visibility...)", default_factory=dict, api=False
    )
    keep_low_quality_lifts: bool = option(
        False,
        help="keep lifts on mostly low-quality pose frames (another person tracked, arm poorly "
        "seen, implausible limb lengths) in the template; default: flagged, left out",
    )

    def __post_init__(self) -> None:
        # JSON gives lists: the channels are a set, the bounds a pair.
        object.__setattr__(self, "exclude_channels", frozenset(self.exclude_channels))
        object.__setattr__(self, "bounds", tuple(float(b) for b in self.bounds))
        super().__post_init__()


def _without_excluded(recording: Recording, exclude: frozenset[str]) -> Recording:
    if not exclude:
        return recording
    keep = {k: c for k, c in recording.channels.items() if k.lower() not in exclude}
    return replace(recording, channels=keep)


def _arm(
    recording: Recording, has_emg: bool, pose_options: Mapping[str, Any], warnings: list[str]
) -> ArmAngles | None:
    """Arm angles from landmarks or markers, else from joint-angle channels (None without)."""
    side = pose_options.get("side")
    name = Path(recording.source).name
    if not _has_positions(recording):
        angles = angles_from_channels(recording, side=side)
        if angles is not None:
            warnings.append("arm angles from joint-angle channels (taken as flexion)")
        found = "joint-angle channels" if angles is not None else "nothing (EMG only)"
        logger.info("%s: arm angles from %s", name, found)
        return angles
    try:
        angles = arm_angles(recording, **pose_options)
    except RecordingError as exc:
        fallback = angles_from_channels(recording, side=side)
        if fallback is None and not has_emg:
            raise
        warnings.append(f"landmarks not used: {exc}")
        logger.info("%s: landmarks not used (%s); arm angles from %s", name, exc,
                    "joint-angle channels" if fallback is not None else "nothing")  # fmt: skip
        return fallback
    logger.info("%s: arm angles from %s of the %s arm, %.3g Hz", name,
                "image landmarks" if angles.quality is not None else "markers",
                angles.side, angles.rate)  # fmt: skip
    assumption = image_size_assumption(recording)
    if assumption:
        warnings.append(assumption)
    return angles


def image_size_assumption(recording: Recording) -> str | None:
    """The assumption made for normalised landmarks without a known image size, or None."""
    if not str(recording.metadata.get("coordinates", "")).startswith("normalised"):
        return None
    return (
        f"{recording.source}: video size unknown, so angles come from normalised x, y as if"
        " the frame were square (up to tens of degrees off for a 16:9 video); give the image"
        " size (--image-size W H) to correct it"
    )


def _clock_offset(
    emg: list[MuscleSeries],
    angles: ArmAngles | None,
    offset: float | Literal["auto"] | None,
    warnings: list[str],
) -> float:
    """t_emg = t_pose + offset [s] for this recording."""
    if angles is None or not emg:
        return float(offset) if isinstance(offset, int | float) else 0.0
    if offset == "auto":
        envs = np.stack([m.envelope for m in emg if len(m.t) == len(emg[0].t)], axis=1)
        shift = estimate_offset(
            envs,
            emg[0].rate,
            np.abs(angles.elbow_acceleration),
            angles.t,
            emg_start=float(emg[0].t[0]),
        )
        warnings.append(f"clock offset estimated by cross-correlation: {shift:+.3f} s")
        return shift
    return 0.0 if offset is None else float(offset)


def _find_lifts(
    emg: list[MuscleSeries], angles: ArmAngles | None, shift: float, warnings: list[str]
) -> list[Lift]:
    """Lifts from the elbow angle (on the common clock), else from EMG bursts."""
    lifts: list[Lift] = []
    if angles is not None:
        lifts = detect_lifts(angles.elbow, angles.t + shift, segments=angles.segments)
        if not lifts:
            warnings.append("no lift found in the elbow angle")
    if not lifts and emg:
        env = np.stack([m.envelope for m in emg if len(m.t) == len(emg[0].t)], axis=1)
        lifts = detect_emg_lifts(env, emg[0].rate, start=float(emg[0].t[0]))
        if lifts:
            warnings.append(
                "lifts found from EMG bursts (no usable elbow angle); tops are estimates, there"
                " are no phases, and the template's kinematics stay the paper's defaults"
            )
    return lifts


def _phase_stats(
    emg: list[MuscleSeries], angles: ArmAngles, tc: NDArray[np.float64], phases: list[Phase]
) -> list[PhaseStats]:
    out: list[PhaseStats] = []
    for ph in phases:
        means, peaks = _interval_stats(emg, ph.start, ph.end)
        out.append(
            PhaseStats(
                phase=ph,
                emg_mean=means,
                emg_peak=peaks,
                peak_velocity=_abs_peak(tc, angles.elbow_velocity, ph.start, ph.end),
                peak_acceleration=_abs_peak(tc, angles.elbow_acceleration, ph.start, ph.end),
            )
        )
    return out


@dataclass(frozen=True)
class _Context:
    """What every lift of one recording is measured against."""

    emg: list[MuscleSeries]
    angles: ArmAngles | None
    tc: NDArray[np.float64] | None
    dyn: ArmDynamics | None
    bounds: tuple[float, float]
    warnings: list[str]
    # (T, 2) joint angles, velocities, accelerations: ArmAngles stacks them on every access,
    # so once per recording here, not once per lift (that was O(lifts x samples)).
    q: NDArray[np.float64] | None = None
    qd: NDArray[np.float64] | None = None
    qdd: NDArray[np.float64] | None = None


def _lift_report(
    i: int,
    lift: Lift,
    order: list[tuple[str, float]],
    peaks: dict[str, float],
    ctx: _Context,
) -> LiftReport:
    """Phases, profile and energetics of lift number ``i`` (1-based)."""
    names = [m for m, _ in order]
    angles, tc = ctx.angles, ctx.tc
    if angles is None or tc is None or lift.source != "angle":
        # An EMG-only lift's top is the EMG's own burst peak: no EMG timing against it.
        profile = lift_profile(lift, activation_order=names)
        return LiftReport(
            i, lift, [], {m: t - lift.start for m, t in order}, tuple(names), {}, profile
        )
    phases = _phase_stats(
        ctx.emg, angles, tc, split_phases(angles.elbow, tc, lift, bounds=ctx.bounds)
    )
    profile = lift_profile(
        lift,
        t=tc,
        elbow=angles.elbow,
        elbow_velocity=angles.elbow_velocity,
        elbow_acceleration=angles.elbow_acceleration,
        activation_order=names,
        emg_peak_times=peaks,
    )
    if profile.rejected:
        ctx.warnings.append(f"lift {i}: no kinematics for the template ({profile.rejected})")
    energetics: Energetics | None = None
    if ctx.dyn is not None and ctx.q is not None and ctx.qd is not None and ctx.qdd is not None:
        # Only the lift's samples go in: the whole recording per lift is O(lifts x N).
        span = _span(tc, lift.start, lift.end, tol=1e-9)
        step = max(1, int(angles.rate // ENERGETICS_RATE))
        idx = np.arange(span.start, span.stop)
        idx = np.unique(np.append(idx[::step], idx[-1:]))  # keep the lift's last sample
        try:
            energetics = lift_energetics(
                tc[idx],
                ctx.q[idx],
                ctx.qd[idx],
                ctx.qdd[idx],
                ctx.dyn,
                interval=(lift.start, lift.end),
                phases=[p.phase for p in phases],
            )
        except RecordingError as exc:
            ctx.warnings.append(f"lift {i}: no energetics ({exc.message})")
    return LiftReport(
        index=i,
        lift=lift,
        phases=phases,
        onsets={m: t - lift.start for m, t in order},
        activation_order=tuple(names),
        emg_peak_times=peaks,
        profile=profile,
        energetics=energetics,
    )


def _lift_reports(lifts: list[Lift], ctx: _Context) -> list[LiftReport]:
    onsets = {m.muscle: m.onsets for m in ctx.emg}
    # Envelope peak time of every muscle in every lift's concentric part, one pass per muscle.
    rising = [[lift.start, lift.top] for lift in lifts]
    peak_table = (
        {m.muscle: peak_times(m.envelope, m.rate, rising, start=float(m.t[0])) for m in ctx.emg}
        if lifts
        else {}
    )
    reports: list[LiftReport] = []
    prev_end = -np.inf
    for i, lift in enumerate(lifts, start=1):
        window = (max(lift.start - ONSET_LEAD, prev_end), lift.top)
        prev_end = lift.end
        order = activation_order(onsets, window)
        peaks = {
            muscle: float(table[i - 1])
            for muscle, table in peak_table.items()
            if np.isfinite(table[i - 1])
        }
        reports.append(_lift_report(i, lift, order, peaks, ctx))
    return reports


def _with_quality(
    reports: list[LiftReport], angles: ArmAngles | None, shift: float, warnings: list[str]
) -> list[LiftReport]:
    """The lifts with their pose quality: share of low-quality frames, flagged above
    :data:`MAX_LOW_QUALITY_SHARE` (a warning names them)."""
    if angles is None or angles.quality is None:
        return reports
    q = angles.quality
    out: list[LiftReport] = []
    for r in reports:
        if r.lift.source != "angle":
            out.append(r)
            continue
        t0, t1 = r.lift.start - shift, r.lift.end - shift
        inside = (angles.t >= t0 - 1e-9) & (angles.t <= t1 + 1e-9)
        share = angles.low_quality_share(t0, t1)
        reasons = {
            "no_pose": int((q.person[inside] < 0).sum()),
            "other_person": int((q.person[inside] > 0).sum()),
            "implausible_lengths": int((inside & ~q.plausible & (q.person == 0)).sum()),
            "low_visibility": int(
                (inside & q.plausible & (q.person == 0) & (q.visibility < q.min_visibility)).sum()
            ),
        }
        out.append(
            replace(
                r,
                low_quality_share=share,
                low_quality=share > MAX_LOW_QUALITY_SHARE,
                quality_reasons={k: v for k, v in reasons.items() if v},
            )
        )
    flagged = [r for r in out if r.low_quality]
    if flagged:
        why = sorted({k.replace("_", " ") for r in flagged for k in r.quality_reasons})
        warnings.append(
            f"{len(flagged)} lift(s) ({', '.join(f'#{r.index}' for r in flagged)}) rest on"
            f" low-quality pose frames (more than {100 * MAX_LOW_QUALITY_SHARE:.0f}%: "
            + ", ".join(why)
            + "); left out of the template unless low-quality lifts are kept"
        )
    return out


def _analyze_one(
    recording: Recording,
    options: AnalysisOptions,
    dynamics: Callable[[], ArmDynamics | None],
) -> RecordingAnalysis:
    warnings: list[str] = [str(w) for w in recording.metadata.get("warnings", ())]
    recording = _without_excluded(recording, options.exclude_channels)
    emg = _process_emg(
        recording,
        emg_rate=options.emg_rate,
        muscle_map=options.muscle_map,
        emg_options=options.emg_options,
        warnings=warnings,
    )
    angles = _arm(recording, bool(emg), options.pose_options, warnings)
    if not emg and angles is None:
        raise RecordingError(
            "nothing to analyse",
            file=recording.source,
            expected="EMG channels, or landmark/marker channels of an arm",
        )
    shift = _clock_offset(emg, angles, options.offset, warnings)
    lifts = _find_lifts(emg, angles, shift, warnings)
    logger.info(
        "%s: clock offset %+.3f s; %d repetition(s) found from %s",
        Path(recording.source).name, shift, len(lifts),
        ("the elbow angle" if lifts[0].source == "angle" else "EMG bursts") if lifts else "-",
    )  # fmt: skip
    ctx = _Context(
        emg=emg,
        angles=angles,
        tc=None if angles is None else angles.t + shift,
        dyn=dynamics() if angles is not None else None,
        bounds=options.bounds,
        warnings=warnings,
        q=None if angles is None else angles.q,
        qd=None if angles is None else angles.qd,
        qdd=None if angles is None else angles.qdd,
    )
    return RecordingAnalysis(
        source=recording.source,
        format=recording.format,
        emg=emg,
        angles=angles,
        offset=shift,
        lifts=_with_quality(_lift_reports(lifts, ctx), angles, shift, warnings),
        warnings=warnings,
        rate_check=rate_check(recording),
    )


def merge_recordings(recordings: Sequence[Recording]) -> Recording:
    """Channels of several files of one session (e.g. an EMG file and a pose file) as one
    recording; names that clash get the file name as a prefix. The files' warnings and what
    they say about their coordinates are kept."""
    channels: dict[str, Channel] = {}
    for rec in recordings:
        for name, ch in rec.channels.items():
            key = name if name not in channels else f"{rec.source}:{name}"
            channels[key] = replace(ch, name=key) if key != name else ch
    metadata: dict[str, Any] = {
        "merged": [r.source for r in recordings],
        "warnings": [
            f"{r.source}: {w}" for r in recordings for w in r.metadata.get("warnings", ())
        ],
    }
    for rec in recordings:
        for key in ("coordinates", "image_size", "rate_check"):
            if key in rec.metadata:
                metadata.setdefault(key, rec.metadata[key])
    return Recording(
        channels=channels,
        source=" + ".join(r.source for r in recordings),
        format=" + ".join(r.format for r in recordings),
        metadata=metadata,
    )


#: How files given together relate: one session recorded at the same time (their clocks are
#: joined), or separate trials (default: each keeps its own clock, lifts and warnings; the
#: template pools their lifts).
SessionMode = Literal["separate", "together"]


def analyze_recordings(
    recordings: Sequence[Recording],
    *,
    emg_rate: float | None = None,
    muscle_map: Mapping[str, str] | None = None,
    exclude_channels: Collection[str] = (),
    phase_bounds_deg: tuple[float, float] = (40.0, 90.0),
    body_mass: float = 75.0,
    body_height: float = 1.75,
    load_mass: float = 12.0,
    offset: float | Literal["auto"] | None = None,
    together: bool = False,
    emg_options: Mapping[str, Any] | None = None,
    pose_options: Mapping[str, Any] | None = None,
    keep_low_quality_lifts: bool = False,
) -> AnalysisResult:
    """Analyse recordings and build one HumanTemplate from all their lifts.

    Args:
        recordings: the recordings (separate trials unless ``together``).
        emg_rate: true EMG sampling rate [Hz] when the file states a wrong one.
        muscle_map: channel label -> site (deltoid, triceps, biceps, forearm), for channels
            the reader could not map, or to change the mapping without reading again.
        exclude_channels: channel names (case-insensitive) left out of the analysis; each must
            name a channel of some recording.
        phase_bounds_deg: (A/B, B/C) elbow-flexion thresholds [deg].
        body_mass: subject's mass [kg] for the arm model.
        body_height: subject's height [m] for the arm model.
        load_mass: dumbbell mass [kg].
        offset: t_emg = t_pose + offset [s]; None = same clock (0) for one file, ``"auto"``
            estimates it by cross-correlation (the default when ``together`` joins files).
        together: the recordings were recorded at the same time (e.g. EMG file + video
            landmarks): merge them onto one clock before analysis. Otherwise they are separate
            trials, each on its own clock with its own lifts; the template pools the lifts.
        emg_options: options for :func:`emg_filter`/:func:`emg_envelope` (band, notch,
            lowpass, method, ...).
        pose_options: options for :func:`arm_angles` (side, min_visibility, max_gap, ...).
        keep_low_quality_lifts: keep the lifts flagged for low pose quality (mostly frames of
            another person, a poorly seen arm or implausible limb lengths) in the template; by
            default they are left out and the template's ``source`` says how many and why.

    Returns:
        AnalysisResult.

    Raises:
        RecordingError: a recording with bad EMG, or with neither EMG nor an arm; an excluded
            channel that no recording has; bad phase bounds or body parameters.
    """
    if not recordings:
        raise RecordingError("no recordings given", expected="at least one file")
    bounds_deg = _check_bounds(phase_bounds_deg)
    _check_body(body_mass, body_height, load_mass)
    exclude = _check_excluded(recordings, exclude_channels)
    joined = together and len(recordings) > 1
    recs = [merge_recordings(recordings)] if joined else list(recordings)
    if joined and offset is None:
        offset = "auto"
    options = AnalysisOptions(
        emg_rate=emg_rate,
        muscle_map=muscle_map,
        exclude_channels=exclude,
        bounds=(float(np.deg2rad(bounds_deg[0])), float(np.deg2rad(bounds_deg[1]))),
        offset=offset,
        emg_options=emg_options or {},
        pose_options=pose_options or {},
        keep_low_quality_lifts=bool(keep_low_quality_lifts),
    )
    warnings: list[str] = []
    dynamics = _arm_model(body_mass, body_height, load_mass, warnings)
    analyses = [_analyze_one(rec, options, dynamics) for rec in recs]
    template = _pooled_template(recordings, analyses, options, bounds_deg, warnings)
    settings = _settings_echo(
        options,
        bounds_deg=bounds_deg,
        body=(body_mass, body_height, load_mass),
        together=together,
    )
    return AnalysisResult(
        recordings=analyses, template=template, settings=settings, warnings=warnings
    )


def _pooled_template(
    recordings: Sequence[Recording],
    analyses: Sequence[RecordingAnalysis],
    options: AnalysisOptions,
    bounds_deg: tuple[float, float],
    warnings: list[str],
) -> HumanTemplate:
    """The template from every analysed lift (low-quality ones left out unless kept);
    appends to ``warnings`` what the template assumed or could not measure."""
    assumptions = [a for rec in recordings if (a := image_size_assumption(rec))]
    lifts = [r for a in analyses for r in a.lifts]
    kept = [r for r in lifts if options.keep_low_quality_lifts or not r.low_quality]
    n_low = sum(r.low_quality for r in lifts)
    template = build_template(
        [r.profile for r in kept],
        phase_bounds_deg=bounds_deg,
        files=[r.source for r in recordings],
        assumptions=assumptions,
        left_out={LOW_QUALITY_REASON: len(lifts) - len(kept)} if len(kept) < len(lifts) else {},
    )
    logger.info(
        "template from %d of %d lift(s) (%d of low pose quality%s): peak velocity at %g deg%s",
        len(kept), len(lifts), n_low, ", kept" if options.keep_low_quality_lifts else ", left out",
        template.peak_velocity_angle_deg, " (the paper's default)" if template.is_paper_default
        else "",
    )  # fmt: skip
    if n_low and options.keep_low_quality_lifts:
        warnings.append(f"{n_low} lift(s) with low pose quality kept in the template on request")
    if template.is_paper_default:
        warnings.append(
            f"the template's kinematics are the paper's defaults ({template.source}): "
            f"peak velocity at {template.peak_velocity_angle_deg:g} deg, not measured here"
        )
    warnings.extend(assumptions)
    return template


def _settings_echo(
    options: AnalysisOptions,
    *,
    bounds_deg: tuple[float, float],
    body: tuple[float, float, float],
    together: bool,
) -> dict[str, Any]:
    """Every option of the analysis, JSON-ready, as the result echoes it."""
    return {
        "emg_rate_hz": options.emg_rate,
        "muscle_map": dict(options.muscle_map or {}),
        "exclude_channels": sorted(options.exclude_channels),
        "phase_bounds_deg": list(bounds_deg),
        "body_mass_kg": body[0],
        "body_height_m": body[1],
        "load_mass_kg": body[2],
        "offset_s": options.offset,
        "session": "together" if together else "separate",
        "emg": {"band_hz": [20.0, 450.0], "lowpass_hz": 6.0, "method": "lowpass"}
        | dict(options.emg_options),
        "pose": dict(options.pose_options),
        "keep_low_quality_lifts": options.keep_low_quality_lifts,
    }


def _check_bounds(phase_bounds_deg: tuple[float, float]) -> tuple[float, float]:
    lo, hi = float(phase_bounds_deg[0]), float(phase_bounds_deg[1])
    if not 0 < lo < hi < 180:
        raise RecordingError(
            f"phase bounds {phase_bounds_deg} deg", expected="0 < A/B bound < B/C bound < 180"
        )
    return lo, hi


def _check_body(body_mass: float, body_height: float, load_mass: float) -> None:
    for name, value, lo, hi in (
        ("body mass", body_mass, 20.0, 250.0),
        ("body height", body_height, 1.0, 2.5),
        ("load", load_mass, 0.0, 100.0),
    ):
        if not lo <= float(value) <= hi:
            raise RecordingError(f"{name} is {value}", expected=f"between {lo:g} and {hi:g}")


def _check_excluded(recordings: Sequence[Recording], names: Collection[str]) -> frozenset[str]:
    exclude = frozenset(str(n).strip().lower() for n in names)
    known = {k.lower() for rec in recordings for k in rec.channels}
    unknown = sorted(exclude - known)
    if unknown:
        shown = sorted({k for rec in recordings for k in rec.channels})
        listed = ", ".join(shown[:20]) + (" ..." if len(shown) > 20 else "")
        raise RecordingError(
            f"cannot exclude channel {unknown[0]!r}: no recording has it",
            expected=f"one of {listed}",
        )
    return exclude


def _arm_model(
    body_mass: float, body_height: float, load_mass: float, warnings: list[str]
) -> Callable[[], ArmDynamics | None]:
    """The human arm model, built on first use (EMG-only analyses never need it)."""
    cache: dict[str, ArmDynamics | None] = {}

    def dynamics() -> ArmDynamics | None:
        if "arm" not in cache:
            try:
                cache["arm"] = human_arm_dynamics(
                    body_mass=body_mass, body_height=body_height, load_mass=load_mass
                )
            except (ImportError, ValueError) as exc:
                warnings.append(f"no energetics: human arm model unavailable ({exc})")
                cache["arm"] = None
        return cache["arm"]

    return dynamics


class AnalysisKeywords(TypedDict, total=False):
    """The keyword arguments of :func:`analyze_recordings` (its signature holds the defaults),
    for functions that pass them through."""

    emg_rate: float | None
    muscle_map: Mapping[str, str] | None
    exclude_channels: Collection[str]
    phase_bounds_deg: tuple[float, float]
    body_mass: float
    body_height: float
    load_mass: float
    offset: float | Literal["auto"] | None
    together: bool
    emg_options: Mapping[str, Any] | None
    pose_options: Mapping[str, Any] | None
    keep_low_quality_lifts: bool


def analyze_files(
    paths: Sequence[str | Path],
    *,
    frame_rate: float | None = None,
    image_size: tuple[int, int] | None = None,
    pose_python: str | Path | None = None,
    max_video_seconds: float = MAX_VIDEO_SECONDS,
    **options: Unpack[AnalysisKeywords],
) -> AnalysisResult:
    """Read files with ``app.recordings.read_recording`` and analyse them.

    ``frame_rate`` [Hz] and ``image_size`` (width, height) [px] go to the reader for pose
    files that do not state them (MediaPipe CSV without timestamps). Videos (mp4, mov, avi)
    become pose first (:func:`app.recordings.extract_pose`, with ``pose_python`` and
    ``max_video_seconds``). ``options`` are those of :func:`analyze_recordings`; its
    ``emg_rate`` and ``muscle_map`` also go to the reader.
    """
    from app.recordings import extract_pose, is_video, read_recording

    recordings = [
        extract_pose(p, pose_python=pose_python, max_seconds=max_video_seconds).recording()
        if is_video(p)
        else read_recording(
            p,
            emg_rate=options.get("emg_rate"),
            muscle_map=options.get("muscle_map"),
            frame_rate=frame_rate,
            image_size=image_size,
        )
        for p in paths
    ]
    result = analyze_recordings(recordings, **options)
    result.settings["frame_rate_hz"] = frame_rate
    result.settings["image_size_px"] = list(image_size) if image_size else None
    return result
