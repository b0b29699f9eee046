"""Small recording files the tests write themselves, with known content.

Binary formats are written with their own libraries (ezc3d, pyedflib, scipy.io, h5py), so the
readers are checked against an independent writer, not against themselves.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def emg_like(n: int, rate: float, *, seed: int = 0, amplitude: float = 1e-4) -> F64:
    """Band-limited noise (about 20-300 Hz) bursting twice, like raw surface EMG [V]."""
    from scipy.signal import butter, sosfiltfilt

    rng = np.random.default_rng(seed)
    sos = butter(4, [20.0, min(300.0, 0.45 * rate)], btype="bandpass", fs=rate, output="sos")
    x = sosfiltfilt(sos, rng.standard_normal(n))
    t = np.arange(n) / rate
    envelope = 0.2 + np.sin(np.pi * t / t[-1] * 2) ** 2
    return np.asarray(amplitude * x / x.std() * envelope, dtype=np.float64)


def write_vicon_csv(path: Path, *, n_frames: int = 50, sub: int = 10) -> dict[str, F64]:
    """Vicon Nexus CSV with a Devices section (EMG in mV + two force plates with the same
    column names) and a Trajectories section (two markers in mm, one with a gap).

    Returns the values written, keyed by the channel names the reader should give, in SI.
    """
    rate = 100.0 * sub
    n = n_frames * sub
    biceps_mv = emg_like(n, rate, seed=1) * 1e3
    triceps_mv = emg_like(n, rate, seed=2) * 1e3
    fz1 = np.linspace(0.0, 700.0, n)
    fz2 = np.linspace(700.0, 0.0, n)
    rows = [
        "Devices",
        f"{rate:g}",
        ",,Delsys - Biceps,Delsys - Triceps,Plate 1,Plate 2",
        "Frame,Sub Frame,Biceps,Triceps,Fz,Fz",
        ",,mV,mV,N,N",
    ]
    for i in range(n):
        rows.append(
            f"{i // sub + 1},{i % sub},{biceps_mv[i]:.9g},{triceps_mv[i]:.9g},"
            f"{fz1[i]:.6f},{fz2[i]:.6f}"
        )
    rows += ["", "Trajectories", "100", ",,Subj:RELB,,,Subj:RWRA,,", "Frame,Sub Frame,X,Y,Z,X,Y,Z"]
    rows.append(",,mm,mm,mm,mm,mm,mm")
    relb = np.column_stack(
        [np.arange(n_frames) * 1.0, np.full(n_frames, 200.0), np.full(n_frames, 1000.0)]
    )
    rwra = relb + 300.0
    for i in range(n_frames):
        a = ",".join(f"{v:.4f}" for v in relb[i])
        b = ",," if 10 <= i < 13 else ",".join(f"{v:.4f}" for v in rwra[i])
        rows.append(f"{i + 1},0,{a},{b}")
    rows += [
        "",
        "Model Outputs",
        "100",
        ",,Subj:RElbowAngles,,",
        "Frame,Sub Frame,X,Y,Z",
        ",,deg,deg,deg",
    ]
    elbow_deg = np.linspace(10.0, 140.0, n_frames)
    for i in range(n_frames):
        rows.append(f"{i + 1},0,{elbow_deg[i]:.5f},0,0")
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    rwra_m = rwra / 1000.0
    rwra_m[10:13] = np.nan
    return {
        "Biceps": biceps_mv * 1e-3,
        "Triceps": triceps_mv * 1e-3,
        "Fz": fz1,
        "Plate 2.Fz": fz2,
        "Subj:RELB": relb / 1000.0,
        "Subj:RWRA": rwra_m,
        "Subj:RElbowAngles.X": np.deg2rad(elbow_deg),
        "Subj:RElbowAngles.Y": np.zeros(n_frames),
        "Subj:RElbowAngles.Z": np.zeros(n_frames),
    }


def write_datalog(path: Path, columns: Sequence[Sequence[int]]) -> None:
    """Tab-separated, CRLF, no header; shorter columns end in empty fields."""
    n = max(len(c) for c in columns)
    lines = []
    for i in range(n):
        lines.append("\t".join(str(c[i]) if i < len(c) else "" for c in columns))
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode("ascii"))


def write_edf(
    path: Path,
    signals: Sequence[F64],
    labels: Sequence[str],
    dims: Sequence[str],
    rates: Sequence[float],
    *,
    bdf: bool = False,
) -> None:
    import pyedflib

    filetype = pyedflib.FILETYPE_BDFPLUS if bdf else pyedflib.FILETYPE_EDFPLUS
    with pyedflib.EdfWriter(str(path), len(signals), file_type=filetype) as w:
        headers = []
        for x, label, dim, rate in zip(signals, labels, dims, rates, strict=True):
            # EDF stores the physical range as 8 characters: 3 significant digits fit
            lim = float(f"{float(np.max(np.abs(x))) * 1.1:.3g}")
            headers.append(
                {
                    "label": label,
                    "dimension": dim,
                    "sample_frequency": rate,
                    "physical_max": lim,
                    "physical_min": -lim,
                    "digital_max": 8388607 if bdf else 32767,
                    "digital_min": -8388608 if bdf else -32768,
                    "transducer": "",
                    "prefilter": "",
                }
            )
        w.setSignalHeaders(headers)
        w.writeSamples([np.asarray(x, dtype=np.float64) for x in signals])


def write_c3d(
    path: Path,
    *,
    points: F64 | None,
    point_labels: Sequence[str] = (),
    analogs: F64 | None = None,
    analog_labels: Sequence[str] = (),
    analog_units: Sequence[str] = (),
    point_rate: float = 100.0,
    analog_rate: float = 1000.0,
    residuals: F64 | None = None,
) -> None:
    """C3D written by ezc3d: points (3, n_points, n_frames) [mm], analogs (n, n_samples)."""
    import ezc3d

    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [point_rate]
    if points is not None:
        c["parameters"]["POINT"]["LABELS"]["value"] = tuple(point_labels)
        c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
        full = np.ones((4, points.shape[1], points.shape[2]))
        full[:3] = points
        c["data"]["points"] = full
        if residuals is not None:
            c["data"]["meta_points"]["residuals"] = residuals[None, :, :]
            c["data"]["meta_points"]["camera_masks"] = np.zeros(
                (7, points.shape[1], points.shape[2]), dtype=bool
            )
    if analogs is not None:
        c["parameters"]["ANALOG"]["RATE"]["value"] = [analog_rate]
        c["parameters"]["ANALOG"]["LABELS"]["value"] = tuple(analog_labels)
        c["parameters"]["ANALOG"]["UNITS"]["value"] = list(analog_units)
        c["data"]["analogs"] = analogs[None, :, :]
    c.write(str(path))


def mediapipe_frames(n: int, *, seed: int = 0) -> F64:
    """(n, 33, 4) landmarks x, y, z, visibility: an arm curling, the rest standing still."""
    rng = np.random.default_rng(seed)
    lm = np.zeros((n, 33, 4))
    lm[:, :, 0] = 0.5 + 0.01 * rng.standard_normal((1, 33))
    lm[:, :, 1] = np.linspace(0.1, 0.9, 33)[None, :]
    lm[:, :, 3] = 0.9
    angle = np.linspace(0.0, 2.5, n)  # elbow flexion [rad]
    for sh, el, wr in ((11, 13, 15), (12, 14, 16)):
        lm[:, sh, :2] = (0.5, 0.3)
        lm[:, el, :2] = (0.5, 0.5)
        lm[:, wr, 0] = 0.5 + 0.2 * np.sin(angle)
        lm[:, wr, 1] = 0.5 + 0.2 * np.cos(angle)
    return lm
