"""Sagittal-plane arm angles from pose landmarks or motion-capture markers.

Conventions (DESIGN.md): radians inside; shoulder flexion is the angle of the upper arm
(shoulder -> elbow) from the trunk's downward direction (shoulder -> hip), positive forward;
elbow flexion is 180 deg minus the included angle at the elbow, 0 with the forearm straight.

Time series are cleaned before they are differentiated: samples whose landmark confidence is low
are masked, short holes are interpolated, long holes and jumps (frames skipped by the recorder)
split the series into segments, and each segment is low-passed (zero-phase Butterworth) and
differentiated on its own, so no derivative is ever taken across a gap. Derivatives within half a
derivative window of a gap are left NaN.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from app.analysis._checks import scipy_signal, true_runs
from app.recordings import FrameQuality, arm_quality, image_landmarks
from app.recordings.types import Channel, Recording, RecordingError

Side = Literal["left", "right"]
DerivativeMethod = Literal["savgol", "spline"]
ROLES = ("shoulder", "elbow", "wrist", "hip")


@dataclass(frozen=True)
class ArmAngles:
    """Joint angles of one arm over time, with derivatives and the gaps they respect.

    Attributes:
        t: (T,) sample times [s] on the pose clock.
        shoulder: (T,) shoulder flexion [rad], NaN in gaps.
        elbow: (T,) elbow flexion [rad], NaN in gaps.
        shoulder_velocity, elbow_velocity: (T,) angular velocities [rad/s].
        shoulder_acceleration, elbow_acceleration: (T,) angular accelerations [rad/s^2].
        wrist_acceleration: (T, D) linear acceleration of the wrist [position unit/s^2]
            (D = 3 for markers, 2 for image landmarks).
        valid: (T,) True where the angles are measured or interpolated across a short hole.
        segments: (S, 2) [start, stop) sample indices of the gap-free stretches.
        gaps: (G, 2) (start, end) times [s] of the long holes and jumps between segments.
        rate: sampling rate [Hz].
        side: which arm (``"left"``, ``"right"``, or ``"unspecified"`` for a one-arm marker set).
        position_unit: unit of the positions behind ``wrist_acceleration`` (``"m"``, ``"px"``,
            ``"norm"``).
        quality: per-frame detection quality of the arm's image landmarks (visibility, limb
            lengths, who is tracked), None for markers and joint-angle channels.
    """

    t: NDArray[np.float64]
    shoulder: NDArray[np.float64]
    elbow: NDArray[np.float64]
    shoulder_velocity: NDArray[np.float64]
    elbow_velocity: NDArray[np.float64]
    shoulder_acceleration: NDArray[np.float64]
    elbow_acceleration: NDArray[np.float64]
    wrist_acceleration: NDArray[np.float64]
    valid: NDArray[np.bool_]
    segments: NDArray[np.intp]
    gaps: NDArray[np.float64]
    rate: float
    side: str
    position_unit: str
    quality: FrameQuality | None = None

    def low_quality_share(self, t0: float, t1: float) -> float:
        """Share of the frames in [t0, t1] (pose clock [s]) that are low-quality (0 without a
        quality track or frames)."""
        if self.quality is None:
            return 0.0
        inside = (self.t >= t0 - 1e-9) & (self.t <= t1 + 1e-9)
        return float(self.quality.low[inside].mean()) if inside.any() else 0.0

    @property
    def q(self) -> NDArray[np.float64]:
        """(T, 2) (shoulder flexion, elbow flexion) [rad]."""
        return np.stack([self.shoulder, self.elbow], axis=1)

    @property
    def qd(self) -> NDArray[np.float64]:
        """(T, 2) joint velocities [rad/s]."""
        return np.stack([self.shoulder_velocity, self.elbow_velocity], axis=1)

    @property
    def qdd(self) -> NDArray[np.float64]:
        """(T, 2) joint accelerations [rad/s^2]."""
        return np.stack([self.shoulder_acceleration, self.elbow_acceleration], axis=1)


# ---------------------------------------------------------------------------------------------
# geometry


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    with np.errstate(invalid="ignore", divide="ignore"):
        out: NDArray[np.float64] = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return out


def _cross2(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    out: NDArray[np.float64] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def joint_angles(
    shoulder: NDArray[np.float64],
    elbow: NDArray[np.float64],
    wrist: NDArray[np.float64],
    *,
    hip: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Shoulder and elbow flexion from joint-centre positions.

    Points are (T, 2) in a y-up plane (image coordinates must be flipped first) or (T, 3) in a
    z-up lab frame. In 3-D the sagittal plane is the plane the elbow flexes in: its normal is the
    mean elbow axis (upper arm x forearm) over the frames where the elbow is clearly bent.
    Without a hip, the trunk's downward direction is the frame's -y (2-D) or -z (3-D).
    "Forward" is the side the forearm points to when the elbow is bent, which is where a curl
    carries the hand.

    Args:
        shoulder, elbow, wrist: (T, D) positions, NaN where missing.
        hip: (T, D) hip (or pelvis centre) positions, or None.

    Returns:
        (shoulder flexion, elbow flexion), each (T,) [rad], NaN where a point is missing.
    """
    upper = elbow - shoulder
    fore = wrist - elbow
    dim = shoulder.shape[1]
    if dim == 2:
        cross = _cross2(upper, fore)
        elbow_flex = np.arctan2(np.abs(cross), np.einsum("ij,ij->i", upper, fore))
        down = _unit(hip - shoulder) if hip is not None else np.tile([0.0, -1.0], (len(upper), 1))
        fwd = np.stack([-down[:, 1], down[:, 0]], axis=1)
        up_p, fore_p = upper, fore
    else:
        crossv = np.cross(upper, fore)
        elbow_flex = np.arctan2(np.linalg.norm(crossv, axis=1), np.einsum("ij,ij->i", upper, fore))
        normal = _sagittal_normal(crossv, elbow_flex)
        raw_down = hip - shoulder if hip is not None else np.tile([0.0, 0.0, -1.0], (len(upper), 1))
        down = _unit(raw_down - np.outer(raw_down @ normal, normal))
        fwd = np.cross(normal, down)
        up_p = upper - np.outer(upper @ normal, normal)
        fore_p = fore - np.outer(fore @ normal, normal)
    # Make "forward" the side the bent forearm points to (the hand comes forward in a curl).
    bent = elbow_flex > np.deg2rad(45.0)
    if not np.any(bent):
        bent = np.isfinite(elbow_flex)
    if np.any(bent) and np.nanmedian(np.einsum("ij,ij->i", fore_p[bent], fwd[bent])) < 0:
        fwd = -fwd
    shoulder_flex = np.arctan2(np.einsum("ij,ij->i", up_p, fwd), np.einsum("ij,ij->i", up_p, down))
    return shoulder_flex, elbow_flex


def _sagittal_normal(
    crossv: NDArray[np.float64], elbow_flex: NDArray[np.float64]
) -> NDArray[np.float64]:
    axes = _unit(crossv)
    use = np.isfinite(axes).all(axis=1) & (elbow_flex > np.deg2rad(20.0))
    if use.sum() < 3:
        use = np.isfinite(axes).all(axis=1)
    if not use.any():
        return np.array([1.0, 0.0, 0.0])
    chosen = axes[use]
    # Flip every axis to agree with the first before averaging (the sign is arbitrary).
    chosen = chosen * np.sign(chosen @ chosen[0])[:, None]
    mean = chosen.mean(axis=0)
    normal: NDArray[np.float64] = mean / np.linalg.norm(mean)
    return normal


# ---------------------------------------------------------------------------------------------
# landmark lookup


def _key(name: str) -> str:
    return name.split(":")[-1].strip().lower().replace(" ", "_")


def _candidates(side: Side) -> dict[str, list[tuple[str, ...]]]:
    s = side[0]
    return {
        "shoulder": [(f"{side}_shoulder",), (f"{s}sho",), ("acro_tip",), ("acro",)],
        "elbow": [(f"{side}_elbow",), (f"{s}elb",), ("epicl", "epicm"), ("elb",)],
        "wrist": [(f"{side}_wrist",), (f"{s}wra", f"{s}wrb"), ("stylr", "stylu"), ("wrist",)],
        "hip": [
            (f"{side}_hip",),
            (f"{s}asi", f"{s}psi"),
            ("asisr", "asisl", "psisr", "psisl"),
            ("asisr", "asisl"),
        ],
    }


def _position_channels(recording: Recording) -> dict[str, Channel]:
    return {
        _key(name): ch
        for name, ch in recording.channels.items()
        if ch.kind in ("landmark", "marker") and ch.data.ndim == 2 and ch.data.shape[1] >= 2
    }


#: Marker sets whose names the automatic lookup may miss, by preset name: role -> names, of
#: which the ones present in the recording are averaged (so Plug-in Gait's wrist is RWRA, RWRB or
#: their midpoint). A preset without a side (``plugin_gait``) tries both and keeps the better one.
#: Plug-in Gait: Vicon's upper-body model; OpenCap: the ``*_study`` markers of its marker
#: augmenter (lateral and medial elbow and wrist); Pose2Sim: OpenPose/COCO keypoint names in its
#: TRC output.
_PRESET_FAMILIES: dict[str, dict[str, tuple[str, ...]]] = {
    "plugin_gait": {
        "shoulder": ("{S}SHO",),
        "elbow": ("{S}ELB",),
        "wrist": ("{S}WRA", "{S}WRB"),
        "hip": ("{S}ASI", "{S}PSI"),
    },
    "opencap": {
        "shoulder": ("{s}_shoulder_study",),
        "elbow": ("{s}_lelbow_study", "{s}_melbow_study"),
        "wrist": ("{s}_lwrist_study", "{s}_mwrist_study"),
        "hip": ("{s}.ASIS_study", "{s}.PSIS_study"),
    },
    "pose2sim": {
        "shoulder": ("{S}Shoulder",),
        "elbow": ("{S}Elbow",),
        "wrist": ("{S}Wrist",),
        "hip": ("{S}Hip",),
    },
}


def _preset(family: str, side: Side) -> dict[str, tuple[str, ...]]:
    # OpenCap writes r_... for the right and L_... for the left; names match case-insensitively.
    letter = {"S": side[0].upper(), "s": "r" if side == "right" else "L"}
    return {
        role: tuple(n.format(**letter) for n in names)
        for role, names in _PRESET_FAMILIES[family].items()
    }


#: Named landmark presets: name -> (side or None for either, role -> candidate names).
LANDMARK_PRESETS: dict[str, tuple[Side | None, dict[str, tuple[str, ...]]]] = {
    **{f: (None, _preset(f, "right")) for f in _PRESET_FAMILIES},
    **{f"{f}_{s}": (s, _preset(f, s)) for f in _PRESET_FAMILIES for s in ("right", "left")},
}


@dataclass(frozen=True)
class LandmarkSpec:
    """Which channels are the arm's joints: a preset or an explicit role -> names mapping.

    Attributes:
        roles: role -> channel names; explicit names must all be present (several are
            averaged); a preset's names are candidates (those present are averaged).
        preset: the preset's name, or None for an explicit mapping.
        side: the preset's side, None when it has none.
    """

    roles: Mapping[str, tuple[str, ...]]
    preset: str | None = None
    side: Side | None = None

    def for_side(self, side: Side) -> Mapping[str, tuple[str, ...]]:
        """The role -> names to look for on ``side`` (a side-less preset's names of that side)."""
        if self.preset is None or self.side is not None:
            return self.roles
        return _preset(self.preset, side)

    def to_text(self) -> str:
        if self.preset is not None:
            return self.preset
        return ",".join(f"{r}={'+'.join(n)}" for r, n in self.roles.items())


#: What ``arm_angles(landmarks=...)`` takes: a preset name, role=NAME text, a mapping, a spec.
LandmarkOption = str | Mapping[str, str | Sequence[str]] | LandmarkSpec


def _presets_text() -> str:
    return ", ".join(LANDMARK_PRESETS)


def landmark_spec(spec: LandmarkOption) -> LandmarkSpec:
    """A landmark mapping from a preset name, ``"shoulder=RSHO,elbow=RELB,wrist=RWRA"`` (several
    names joined by ``+`` are averaged: ``wrist=RWRA+RWRB``) or a role -> name(s) mapping.

    Raises:
        RecordingError: an unknown preset or role, or a malformed mapping; the message lists
            the presets.
    """
    if isinstance(spec, LandmarkSpec):
        return spec
    if isinstance(spec, str):
        text = spec.strip()
        key = text.lower().replace("-", "_").replace(" ", "_")
        if key in LANDMARK_PRESETS:
            preset_side, preset_roles = LANDMARK_PRESETS[key]
            return LandmarkSpec(roles=preset_roles, preset=key, side=preset_side)
        if "=" not in text:
            raise RecordingError(
                f"unknown landmark preset {spec!r}",
                expected=f"one of {_presets_text()}, or role=NAME pairs such as"
                " 'shoulder=RSHO,elbow=RELB,wrist=RWRA'",
            )
        pairs: dict[str, str | Sequence[str]] = {}
        for part in filter(None, (p.strip() for p in text.split(","))):
            role, sep, names = part.partition("=")
            split = [n.strip() for n in names.split("+") if n.strip()]
            if not sep or not split:
                raise RecordingError(
                    f"landmark mapping {part!r} is not role=NAME",
                    expected="e.g. 'shoulder=RSHO,elbow=RELB,wrist=RWRA' or a preset"
                    f" ({_presets_text()})",
                )
            pairs[role.strip().lower()] = split
        spec = pairs
    roles: dict[str, tuple[str, ...]] = {}
    for role, value in spec.items():
        if role not in ROLES:
            raise RecordingError(
                f"unknown landmark role {role!r}",
                expected=f"roles among {', '.join(ROLES)} (or a preset: {_presets_text()})",
            )
        chosen = (value,) if isinstance(value, str) else tuple(value)
        if not chosen or not all(isinstance(n, str) and n.strip() for n in chosen):
            raise RecordingError(
                f"landmark role {role!r} names no channel", expected="one or more channel names"
            )
        roles[role] = chosen
    return LandmarkSpec(roles=roles)


def _resolve(
    recording: Recording,
    side: Side,
    landmarks: LandmarkSpec | None,
) -> tuple[dict[str, list[Channel]], bool]:
    """Channels per role for one side, and whether the names were side-specific.

    An explicit mapping's names must all exist; a preset's present names are averaged, and a
    role none of them names is missing (the hip then falls back to the automatic names).
    """
    available = _position_channels(recording)
    found: dict[str, list[Channel]] = {}
    sided = False
    given = landmarks.for_side(side) if landmarks is not None else {}
    preset = landmarks is not None and landmarks.preset is not None
    for role, options in _candidates(side).items():
        names = given.get(role, ())
        if preset:
            present = [n for n in names if _key(n) in available]
            if present:
                found[role] = [available[_key(n)] for n in present]
                sided = True
                continue
            if role != "hip":
                continue  # this side lacks the role: no arm here
        elif names:
            missing = [n for n in names if _key(n) not in available]
            if missing:
                raise RecordingError(
                    f"landmark(s) {missing} given for the {role} are not in the recording",
                    file=recording.source,
                    expected=f"names among {sorted(available)[:20]}",
                )
            found[role] = [available[_key(n)] for n in names]
            continue
        for option in options:
            if all(name in available for name in option):
                found[role] = [available[name] for name in option]
                sided = sided or option[0].startswith((side, side[0]))
                break
    return found, sided


def _points(
    channels: list[Channel],
    *,
    min_visibility: float,
    image_size: tuple[float, float] | None,
) -> tuple[NDArray[np.float64], str]:
    """(T, D) mean position of the channels, NaN where any is missing or not visible."""
    stacks = []
    unit = channels[0].unit
    for ch in channels:
        data = np.array(ch.data, dtype=np.float64)
        if ch.confidence is not None:
            data[np.asarray(ch.confidence) < min_visibility] = np.nan
        if unit == "norm":
            # Image landmarks: the depth estimate is unreliable, keep x, y and flip y to point up.
            xy = data[:, :2].copy()
            if image_size is not None:
                xy[:, 0] *= image_size[0]
                xy[:, 1] *= image_size[1]
            xy[:, 1] = -xy[:, 1]
            data = xy
        else:
            data = data[:, :3]
        stacks.append(data)
    pos = np.mean(np.stack(stacks), axis=0) if len(stacks) > 1 else stacks[0]
    if unit == "norm":
        unit = "px" if image_size is not None else "norm"
    return pos, unit


def _confidence(channels: list[Channel], min_visibility: float) -> tuple[float, float]:
    """(share of usable samples, mean visibility) of an arm's landmarks: the side with more
    usable samples wins, and on a tie the one MediaPipe sees better."""
    scores, visibility = [], []
    for ch in channels:
        finite = np.isfinite(ch.data).all(axis=1)
        conf = np.ones(ch.n_samples) if ch.confidence is None else np.asarray(ch.confidence)
        finite &= conf >= min_visibility
        scores.append(float(finite.mean()))
        visibility.append(float(np.nanmean(conf)) if conf.size else 0.0)
    return float(np.mean(scores)), float(np.mean(visibility))


# ---------------------------------------------------------------------------------------------
# time-series cleaning


def _segments(
    t: NDArray[np.float64],
    y: NDArray[np.float64],
    *,
    rate: float,
    max_gap: float,
    max_speed: float,
    jump_columns: int,
) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.float64]]:
    """Interpolate short holes; split at long holes, time gaps and jumps.

    Returns (filled y, (S, 2) segment index ranges, (G, 2) gap times).
    """
    y = y.copy()
    n = len(t)
    finite = np.asarray(np.isfinite(y).all(axis=1), dtype=bool)
    y[~finite] = np.nan
    idx = np.flatnonzero(finite)
    # breaks[i]: the series must not be joined between sample i and i + 1. Explicit clocks
    # with a missing frame break (the derivative filters assume a uniform grid), and so does a
    # jump: an angle change between two valid samples faster than any arm moves.
    breaks = np.diff(t) > 1.5 / rate
    if len(idx) > 1:
        step = np.abs(np.diff(y[idx, :jump_columns], axis=0)).max(axis=1)
        jump = step > max_speed * np.diff(t[idx])
        breaks[idx[1:][jump] - 1] = True
    # Fill holes short enough and not crossing a break.
    for start, stop in true_runs(~finite):
        if start == 0 or stop == n:
            continue
        if (stop - start) / rate > max_gap or breaks[start - 1 : stop].any():
            continue
        lo, hi = start - 1, stop
        w = (t[start:stop] - t[lo]) / (t[hi] - t[lo])
        y[start:stop] = y[lo] + w[:, None] * (y[hi] - y[lo])
    ok = np.asarray(np.isfinite(y).all(axis=1), dtype=bool)
    runs = true_runs(ok)
    segs: list[tuple[int, int]] = []
    for start, stop in runs:
        cuts = start + 1 + np.flatnonzero(breaks[start : stop - 1])
        edges = np.concatenate(([start], cuts, [stop]))
        segs.extend(itertools.pairwise(edges.tolist()))
    segments = np.array(segs, dtype=np.intp).reshape(-1, 2)
    gaps = (
        np.stack([t[segments[:-1, 1] - 1], t[segments[1:, 0]]], axis=1)
        if len(segments) > 1
        else np.zeros((0, 2))
    )
    return y, segments, gaps


def savgol(
    y: NDArray[np.float64], n_win: int, polyorder: int, *, deriv: int, delta: float
) -> NDArray[np.float64]:
    """``scipy.signal.savgol_filter(y, ..., axis=0, mode="interp")``, computed by overlap-add
    FFT convolution in the interior.

    Args:
        y: (N, K) samples, N >= n_win.
        n_win: odd window length [samples]; polyorder, deriv, delta as for ``savgol_filter``.

    Returns:
        (N, K) the filtered derivative. The same numbers as ``savgol_filter`` (to rounding);
        for a 2 kHz goniometer (301-sample window) direct correlation cost most of a long
        session's analysis, the FFT a small fraction of it.
    """
    signal = scipy_signal()
    n, half = len(y), n_win // 2
    if n < 4 * n_win:
        return np.asarray(
            signal.savgol_filter(
                y, n_win, polyorder, deriv=deriv, delta=delta, axis=0, mode="interp"
            )
        )
    coeffs = signal.savgol_coeffs(n_win, polyorder, deriv=deriv, delta=delta, use="conv")
    out = np.empty_like(y)
    out[half : n - half] = signal.oaconvolve(y, coeffs[:, None], mode="valid", axes=0)
    # The ends: "interp" fits one polynomial to the first (last) window; same as on a slice.
    edge = {"deriv": deriv, "delta": delta, "axis": 0, "mode": "interp"}
    out[:half] = signal.savgol_filter(y[:n_win], n_win, polyorder, **edge)[:half]
    out[n - half :] = signal.savgol_filter(y[n - n_win :], n_win, polyorder, **edge)[n_win - half :]
    return out


def smooth_and_differentiate(
    t: NDArray[np.float64],
    y: NDArray[np.float64],
    *,
    rate: float,
    segments: NDArray[np.intp],
    lowpass: float | None = 6.0,
    derivative: DerivativeMethod = "savgol",
    window: float = 0.15,
    polyorder: int = 3,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Low-pass and differentiate each segment on its own.

    Args:
        t: (T,) sample times [s].
        y: (T, K) signals (NaN outside the segments).
        rate: sampling rate [Hz].
        segments: (S, 2) [start, stop) index ranges free of gaps.
        lowpass: zero-phase Butterworth (order 4) cut-off [Hz], None to skip; skipped when it is
            not below 0.95 of Nyquist.
        derivative: ``"savgol"`` (Savitzky-Golay, ``polyorder`` over ``window`` seconds) or
            ``"spline"`` (cubic interpolating spline of the smoothed samples).
        window: derivative window [s]; derivatives within half of it of a gap are NaN.
        polyorder: Savitzky-Golay polynomial order.

    Returns:
        (smoothed, first derivative, second derivative), each (T, K), NaN outside segments.
    """
    signal = scipy_signal()
    smooth = np.full_like(y, np.nan)
    d1 = np.full_like(y, np.nan)
    d2 = np.full_like(y, np.nan)
    # Savitzky-Golay needs an odd window longer than the polynomial order.
    n_win = max(round(window * rate), polyorder + 1)
    n_win += 1 - n_win % 2
    half = n_win // 2
    sos = None
    if lowpass is not None and lowpass < 0.95 * rate / 2:
        sos = signal.butter(4, lowpass, fs=rate, output="sos")
    n = len(t)
    for start, stop in segments:
        seg = y[start:stop]
        length = stop - start
        if sos is not None and length > 1:
            pad = min(3 * (2 * len(sos) + 1), length - 1)
            seg = signal.sosfiltfilt(sos, seg, axis=0, padlen=pad)
        smooth[start:stop] = seg
        if length < n_win:
            continue
        if derivative == "spline":
            from scipy.interpolate import CubicSpline

            spline = CubicSpline(t[start:stop], seg, axis=0)
            d1[start:stop] = spline(t[start:stop], 1)
            d2[start:stop] = spline(t[start:stop], 2)
        else:
            d1[start:stop] = savgol(seg, n_win, polyorder, deriv=1, delta=1.0 / rate)
            d2[start:stop] = savgol(seg, n_win, polyorder, deriv=2, delta=1.0 / rate)
        # Near a gap the derivative window would reach across it: leave those samples NaN.
        if start > 0:
            d1[start : start + half] = np.nan
            d2[start : start + half] = np.nan
        if stop < n:
            d1[stop - half : stop] = np.nan
            d2[stop - half : stop] = np.nan
    return smooth, d1, d2


# ---------------------------------------------------------------------------------------------
# public entry point


def _choose_arm(
    recording: Recording,
    side: Side | None,
    landmarks: LandmarkOption | None,
    min_visibility: float,
) -> tuple[Side, dict[str, list[Channel]], bool]:
    """(side, channels per role, whether the names were sided) of the arm to use: ``side``,
    or the one with more usable samples (then higher mean visibility)."""
    if side not in (None, "left", "right"):
        raise RecordingError(f"unknown side {side!r}", expected="'left', 'right' or None")
    spec = None if landmarks is None else landmark_spec(landmarks)
    if spec is not None and spec.side is not None:
        if side is not None and side != spec.side:
            raise RecordingError(
                f"landmark preset {spec.preset!r} is the {spec.side} arm, but side {side!r}"
                " was asked for",
                file=recording.source,
                expected=f"side {spec.side!r}, or the preset of the {side} arm",
            )
        side = spec.side
    options: list[Side] = [side] if side is not None else ["left", "right"]
    resolved: list[tuple[tuple[float, float], Side, dict[str, list[Channel]], bool]] = []
    for s in options:
        found, sided = _resolve(recording, s, spec)
        if all(role in found for role in ("shoulder", "elbow", "wrist")):
            arm = [ch for role in ("shoulder", "elbow", "wrist") for ch in found[role]]
            resolved.append((_confidence(arm, min_visibility), s, found, sided))
    if not resolved:
        names = [
            name
            for name, ch in recording.channels.items()
            if ch.kind in ("landmark", "marker") and ch.data.ndim == 2
        ]
        shown = ", ".join(names[:30]) + (" ..." if len(names) > 30 else "")
        raise RecordingError(
            "no arm landmarks found"
            + (f" for the {side} side" if side else "")
            + (f" with landmarks {spec.to_text()!r}" if spec is not None else ""),
            file=recording.source,
            expected="shoulder, elbow and wrist landmarks or markers (e.g. left_shoulder, "
            "left_elbow, left_wrist; LSHO, LELB, LWRA+LWRB; or ACRO_tip, EPICl/EPICm, "
            f"STYLr/STYLu), or a landmark preset ({_presets_text()}) or mapping"
            " (shoulder=NAME,elbow=NAME,wrist=NAME)"
            + (f"; position channels present: {shown}" if names else "; none present"),
        )
    resolved.sort(key=lambda item: (-item[0][0], -item[0][1]))
    _, chosen_side, found, sided = resolved[0]
    lengths = {ch.n_samples for chans in found.values() for ch in chans}
    if len(lengths) != 1:
        raise RecordingError(
            f"arm landmarks have different lengths {sorted(lengths)}",
            file=recording.source,
            expected="landmarks sampled together",
        )
    return chosen_side, found, sided


def arm_angles(
    recording: Recording,
    *,
    side: Side | None = None,
    landmarks: LandmarkOption | None = None,
    min_visibility: float = 0.5,
    max_gap: float = 0.2,
    max_speed: float = 15.0,
    lowpass: float | None = 6.0,
    derivative: DerivativeMethod = "savgol",
    window: float = 0.15,
    image_size: tuple[float, float] | None = None,
) -> ArmAngles:
    """Shoulder and elbow flexion with velocities and accelerations from a pose recording.

    Args:
        recording: a recording with landmark or marker channels ((N, 2|3) positions). Names
            recognised per role: MediaPipe ``left_shoulder`` ..., Vicon Plug-in Gait ``LSHO``,
            ``LELB``, ``LWRA/LWRB``, ``LASI/LPSI``, or ``ACRO_tip``, ``EPICl/EPICm``,
            ``STYLr/STYLu``, ``ASIS*/PSIS*`` (averaged where several are listed).
        side: ``"left"`` or ``"right"``; None picks the side whose landmarks are visible most.
        landmarks: role (``shoulder``, ``elbow``, ``wrist``, ``hip``) -> channel name(s) to use
            instead of the automatic lookup (several names are averaged), the same as text
            (``"shoulder=RSHO,elbow=RELB,wrist=RWRA"``), or a preset of ``LANDMARK_PRESETS``
            (``plugin_gait_right``, ``opencap_left``, ``pose2sim``...).
        min_visibility: landmark samples with lower confidence are treated as missing.
        max_gap: holes up to this long [s] are interpolated; longer ones stay gaps.
        max_speed: an angle change faster than this between valid samples [rad/s] is a jump
            (frames skipped by the recorder) and splits the series.
        lowpass: zero-phase Butterworth cut-off [Hz] for angles and positions, None for none.
        derivative: ``"savgol"`` or ``"spline"``.
        window: derivative window [s].
        image_size: (width, height) [px] of the video behind raw normalised image landmarks, so
            x and y get the same scale. Ignored when ``recording.metadata`` has an
            ``"image_size"``: the reader then already scaled the coordinates.

    Returns:
        ArmAngles on the recording's pose clock.

    Raises:
        RecordingError: no shoulder, elbow and wrist landmarks for the side(s), or none valid.
    """
    chosen_side, found, sided = _choose_arm(recording, side, landmarks, min_visibility)
    first = found["shoulder"][0]
    rate = float(first.rate)
    t = np.asarray(first.times, dtype=np.float64)
    if "image_size" in recording.metadata:
        # The reader has already put x and y on one scale (units of the image height).
        image_size = None
    pts = {}
    unit = "m"
    for role, chans in found.items():
        pts[role], unit = _points(chans, min_visibility=min_visibility, image_size=image_size)
    shoulder_flex, elbow_flex = joint_angles(
        pts["shoulder"], pts["elbow"], pts["wrist"], hip=pts.get("hip")
    )
    if not np.isfinite(elbow_flex).any():
        raise RecordingError(
            "no frame has shoulder, elbow and wrist all visible",
            file=recording.source,
            expected=f"landmark confidence >= {min_visibility}",
        )
    return _angles_from_series(
        t,
        np.column_stack([shoulder_flex, elbow_flex, pts["wrist"]]),
        _Smoothing(rate, max_gap, max_speed, lowpass, derivative, window),
        side=chosen_side if sided else "unspecified",
        position_unit=unit,
        quality=_quality(recording, found, t, chosen_side, min_visibility),
    )


@dataclass(frozen=True)
class _Smoothing:
    """How a series of angles is cleaned and differentiated (see :func:`arm_angles`)."""

    rate: float
    max_gap: float
    max_speed: float
    lowpass: float | None
    derivative: DerivativeMethod
    window: float


def _angles_from_series(
    t: NDArray[np.float64],
    stacked: NDArray[np.float64],
    how: _Smoothing,
    *,
    side: str,
    position_unit: str,
    quality: FrameQuality | None = None,
) -> ArmAngles:
    """ArmAngles from (T, 2 + D) columns: shoulder and elbow flexion [rad], then D wrist
    position columns; holes filled, jumps split, smoothed and differentiated per segment."""
    filled, segments, gaps = _segments(
        t,
        stacked,
        rate=how.rate,
        max_gap=how.max_gap,
        max_speed=how.max_speed,
        jump_columns=2,
    )
    smooth, d1, d2 = smooth_and_differentiate(
        t,
        filled,
        rate=how.rate,
        segments=segments,
        lowpass=how.lowpass,
        derivative=how.derivative,
        window=how.window,
    )
    return ArmAngles(
        t=t,
        shoulder=smooth[:, 0],
        elbow=smooth[:, 1],
        shoulder_velocity=d1[:, 0],
        elbow_velocity=d1[:, 1],
        shoulder_acceleration=d2[:, 0],
        elbow_acceleration=d2[:, 1],
        wrist_acceleration=d2[:, 2:],
        valid=np.isfinite(smooth[:, 1]),
        segments=segments,
        gaps=gaps,
        rate=how.rate,
        side=side,
        position_unit=position_unit,
        quality=quality,
    )


def _quality(
    recording: Recording,
    found: dict[str, list[Channel]],
    t: NDArray[np.float64],
    side: Side,
    min_visibility: float,
) -> FrameQuality | None:
    """Per-frame quality of the arm when it comes from image landmarks (MediaPipe), else None."""
    arm = [ch for role in ("shoulder", "elbow", "wrist") for ch in found[role]]
    if not all(ch.kind == "landmark" for ch in arm):
        return None
    lms = image_landmarks(recording.channels)
    if any(len(v[0]) != len(t) for v in lms.values()):
        return None
    try:
        return arm_quality(lms, t, side, min_visibility=min_visibility)
    except KeyError:
        return None


#: Name fragments of joint-angle channels: goniometers and OpenSim coordinates (arm26
#: ``r_shoulder_elev``/``r_elbow_flex``, Rajagopal and MoBL ``arm_flex_r``/``elbow_flex_r``,
#: ``shoulder_elv``/``shoulder_ele``), with the preferred words first.
_JOINT_WORDS = {
    "elbow": (("elbow",), ("flex",)),
    "shoulder": (("shoulder", "arm_flex"), ("flex", "ele")),
}


def _side_of(name: str) -> str | None:
    # OpenSim 4 state paths: /jointset/r_elbow/r_elbow_flex/value -> r_elbow_flex
    parts = [p for p in name.lower().split("/") if p]
    if len(parts) >= 2 and parts[-1] in ("value", "speed"):
        parts.pop()
    low = parts[-1] if parts else name.lower()
    if low.endswith(("_r", "_right")) or low.startswith(("r_", "right_")):
        return "right"
    if low.endswith(("_l", "_left")) or low.startswith(("l_", "left_")):
        return "left"
    return None


def _angle_channel(recording: Recording, joint: str, side: str | None) -> Channel | None:
    """The joint's angle channel, of ``side`` when the names tell sides apart."""
    words, prefer = _JOINT_WORDS[joint]
    found = [
        ch
        for name, ch in recording.channels.items()
        if ch.kind == "angle" and ch.data.ndim == 1 and any(w in name.lower() for w in words)
    ]
    if side is not None and any(_side_of(ch.name) == side for ch in found):
        found = [ch for ch in found if _side_of(ch.name) in (side, None)]
    for word in prefer:
        for ch in found:
            if word in ch.name.lower():
                return ch
    return found[0] if found else None


def _elbow_channel(recording: Recording, side: str | None) -> Channel | None:
    """The elbow channel of ``side``, else of the side whose elbow moves most."""
    if side is not None:
        return _angle_channel(recording, "elbow", side)
    options = [c for c in (_angle_channel(recording, "elbow", s) for s in ("right", "left")) if c]
    if not options:
        return None
    return max(options, key=lambda c: float(np.nanmax(c.data) - np.nanmin(c.data)))


def angles_from_channels(
    recording: Recording,
    *,
    max_gap: float = 0.2,
    max_speed: float = 15.0,
    lowpass: float | None = 6.0,
    derivative: DerivativeMethod = "savgol",
    window: float = 0.15,
    side: str | None = None,
) -> ArmAngles | None:
    """Arm angles from joint-angle channels (goniometers, OpenSim coordinates) instead of points.

    The elbow channel is the ``angle`` channel whose name contains "elbow" (one with "flex"
    preferred); the shoulder one contains "shoulder" or "arm_flex" ("flex" preferred, then
    "ele" for elevation), so OpenSim's ``elbow_flex_r``, ``arm_flex_r``, ``shoulder_elv`` are
    recognised. With sided names (``_r``/``_l``, ``r_``/``l_``) both come from ``side``, or
    from the side whose elbow moves most. Both are taken as flexion in radians, as the
    readers deliver them. Without a shoulder channel the upper arm is taken as hanging (0 rad).

    Returns:
        ArmAngles (no wrist acceleration: shape (T, 0)), or None without an elbow channel.
    """
    elbow = _elbow_channel(recording, side)
    if elbow is None:
        return None
    shoulder = _angle_channel(recording, "shoulder", side or _side_of(elbow.name))
    rate = float(elbow.rate)
    t = np.asarray(elbow.times, dtype=np.float64)
    e = np.asarray(elbow.data, dtype=np.float64)
    if shoulder is not None and shoulder.n_samples == elbow.n_samples:
        s = np.asarray(shoulder.data, dtype=np.float64)
    else:
        s = np.zeros_like(e)
    return _angles_from_series(
        t,
        np.column_stack([s, e]),
        _Smoothing(rate, max_gap, max_speed, lowpass, derivative, window),
        side=_side_of(elbow.name) or "unspecified",
        position_unit="",
    )
