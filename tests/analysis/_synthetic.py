"""Synthetic curls with known geometry, written as the files users upload.

The elbow follows a skewed cycloid whose velocity peak lies at a known fraction of the lift's
range (computed densely here, independently of the analysis). Landmarks are placed in pixels
on a side view and normalised by a 16:9 frame, as MediaPipe does, so angles from the raw
normalised coordinates are distorted and the image size undoes it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

REST_DEG, TOP_DEG = 20.0, 140.0
RISE_S, HOLD_S, LOWER_S, REST_S = 1.2, 0.5, 1.2, 1.1
#: Exponent of the time warp tau -> tau**SKEW: the elbow is fastest early in the rise.
SKEW = 0.7
IMAGE = (1920, 1080)
UPPER_ARM_PX, FOREARM_PX = 300.0, 260.0


def _shape(tau: F64) -> F64:
    """Skewed cycloid 0 -> 1 with zero speed at both ends."""
    w = np.clip(tau, 0.0, 1.0) ** SKEW
    return w - np.sin(2 * np.pi * w) / (2 * np.pi)


def peak_range_fraction() -> float:
    """Where the elbow is fastest, as a fraction of the rise's range (dense closed form)."""
    tau = np.linspace(1e-6, 1.0, 200_001)
    s = _shape(tau)
    return float(s[int(np.argmax(np.gradient(s, tau)))])


def elbow_curls(n_lifts: int, rate: float) -> tuple[F64, F64]:
    """(t [s], elbow flexion [deg]) of ``n_lifts`` curls with rest and a hold at the top."""
    cycle = RISE_S + HOLD_S + LOWER_S + REST_S
    t = np.arange(round((REST_S + n_lifts * cycle) * rate)) / rate
    y = np.full_like(t, REST_DEG)
    for k in range(n_lifts):
        t0 = REST_S + k * cycle
        up = _shape((t - t0) / RISE_S)
        down = _shape((t - t0 - RISE_S - HOLD_S) / LOWER_S)
        y += (TOP_DEG - REST_DEG) * (up - down)
    return t, y


def arm_pixels(elbow_deg: F64, *, shoulder: tuple[float, float] = (900.0, 300.0)) -> F64:
    """(T, 3, 2) shoulder, elbow, wrist pixel positions of a side view (y down), upper arm
    hanging, forearm rising forward (+x) with flexion."""
    n = len(elbow_deg)
    sx, sy = shoulder
    out = np.zeros((n, 3, 2))
    out[:, 0] = (sx, sy)
    out[:, 1] = (sx, sy + UPPER_ARM_PX)
    a = np.deg2rad(elbow_deg)
    out[:, 2, 0] = sx + FOREARM_PX * np.sin(a)
    out[:, 2, 1] = sy + UPPER_ARM_PX + FOREARM_PX * np.cos(a)
    return out


def write_mediapipe_csv(
    path: Path,
    elbow_deg: F64,
    *,
    left_elbow_deg: F64 | None = None,
    t: F64 | None = None,
    image: tuple[int, int] = IMAGE,
) -> Path:
    """MediaPipe landmark CSV (normalised x, y; visibility) of one or both arms; a ``time``
    column only when ``t`` is given."""
    w, h = image
    cols: dict[str, F64] = {}
    for side, ang, shoulder in (
        ("right", elbow_deg, (900.0, 300.0)),
        ("left", left_elbow_deg, (960.0, 300.0)),
    ):
        if ang is None:
            continue
        px = arm_pixels(ang, shoulder=shoulder)
        vis = 0.95 if side == "right" else 0.9
        for j, joint in enumerate(("shoulder", "elbow", "wrist")):
            cols[f"{side}_{joint}_x"] = px[:, j, 0] / w
            cols[f"{side}_{joint}_y"] = px[:, j, 1] / h
            cols[f"{side}_{joint}_z"] = np.zeros(len(ang))
            cols[f"{side}_{joint}_v"] = np.full(len(ang), vis)
    if t is not None:
        cols = {"time": t, **cols}
    names = list(cols)
    block = np.column_stack([cols[c] for c in names])
    lines = [",".join(names)] + [",".join(f"{v:.6f}" for v in row) for row in block]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def write_emg_csv(
    path: Path,
    bursts_s: list[float],
    *,
    rate: float = 1000.0,
    seconds: float,
    seed: int = 0,
) -> Path:
    """EMG CSV (time [s], biceps and deltoid [V], an all-zero 'spare') with a burst of
    activity starting at each time in ``bursts_s`` (deltoid 0.1 s before the biceps)."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(seconds * rate)) / rate
    gain_b = np.full_like(t, 0.05)
    gain_d = np.full_like(t, 0.05)
    for b in bursts_s:
        gain_b += np.exp(-(((t - b - 0.6) / 0.4) ** 2))
        gain_d += np.exp(-(((t - b - 0.5) / 0.4) ** 2))
    biceps = 1e-4 * gain_b * rng.standard_normal(len(t))
    deltoid = 1e-4 * gain_d * rng.standard_normal(len(t))
    lines = ["time,biceps,deltoid,spare"] + [
        f"{t[i]:.4f},{biceps[i]:.4e},{deltoid[i]:.4e},0" for i in range(len(t))
    ]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
