"""A curling right arm as 3-D motion-capture markers under any marker names, and its TRC file
(for the landmark presets and mappings: tests/analysis/test_pose.py, tests/api)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from app.recordings.types import Channel, Recording

UPPER_ARM, FOREARM = 0.30, 0.35  # [m]
RATE = 100.0  # [Hz]


def curl_markers(
    names: dict[str, str], seconds: float = 8.0
) -> tuple[Recording, NDArray[np.float64]]:
    """(markers in m, z up, of 0.5 Hz curls named by role -> marker name plus a C7; the true
    elbow flexion [rad]). Shoulder flexion 10-25 deg, elbow 10-140 deg."""
    t = np.arange(int(seconds * RATE)) / RATE
    wave = (1 - np.cos(2 * np.pi * 0.5 * t)) / 2
    q1 = np.deg2rad(10.0) + np.deg2rad(15.0) * wave
    q2 = np.deg2rad(10.0) + np.deg2rad(130.0) * wave
    fwd, up = np.array([np.cos(0.3), np.sin(0.3), 0.0]), np.array([0.0, 0.0, 1.0])

    def lab(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        out: NDArray[np.float64] = x[:, None] * fwd + y[:, None] * up + [0.2, -0.1, 1.3]
        return out

    zero = np.zeros_like(t)
    ex, ey = UPPER_ARM * np.sin(q1), -UPPER_ARM * np.cos(q1)
    pts = {
        "shoulder": lab(zero, zero),
        "elbow": lab(ex, ey),
        "wrist": lab(ex + FOREARM * np.sin(q1 + q2), ey - FOREARM * np.cos(q1 + q2)),
        "hip": lab(zero, zero - 0.5),
    }
    channels = {name: Channel(name, pts[role], RATE, "m", "marker") for role, name in names.items()}
    channels["C7"] = Channel("C7", pts["shoulder"] + [0.0, 0.1, 0.1], RATE, "m", "marker")
    return Recording(channels, "markers.c3d", "c3d"), q2


def write_trc(path: Path, rec: Recording) -> Path:
    """An OpenSim/Vicon TRC (mm) of the recording's markers, as Nexus and Pose2Sim write it."""
    names = list(rec.channels)
    n = rec.channels[names[0]].n_samples
    head = [
        f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame"
        "\tOrigNumFrames",
        f"{RATE:g}\t{RATE:g}\t{n}\t{len(names)}\tmm\t{RATE:g}\t1\t{n}",
        "Frame#\tTime\t" + "\t\t\t".join(names) + "\t\t",
        "\t\t" + "\t".join(f"X{k}\tY{k}\tZ{k}" for k in range(1, len(names) + 1)),
    ]
    rows = [
        f"{i + 1}\t{i / RATE:.2f}\t"
        + "\t".join(f"{v:.4f}" for nm in names for v in rec.channels[nm].data[i] * 1000.0)
        for i in range(n)
    ]
    path.write_text("\n".join([*head, "", *rows]) + "\n", encoding="utf-8")
    return path
