"""Small loaders for the shared real-data files, written for these tests only.

They read the files with the format libraries directly (h5py, numpy, ezc3d), so the analysis
tests do not depend on the readers in ``app.recordings`` and check them independently.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from app.recordings.types import Channel, Recording
from tests.conftest import shared_file

NORAXON = "noraxon_curls_biceps_brachioradialis"


def noraxon_mat(name: str) -> tuple[NDArray[np.float64], float]:
    """(N, 2) biceps and brachioradialis EMG [uV] of NT-01/SP-01, at the true rate 2000 Hz."""
    import h5py

    path = shared_file(f"{NORAXON}/{name}.mat")
    with h5py.File(path, "r") as h5:
        group = next(h5[k] for k in h5 if k.startswith("EMG_recording"))
        data = group["data"]
        biceps = np.asarray(data["BicepsBrachi"], dtype=np.float64).ravel()
        brachio = np.asarray(data["Brachioradialis"], dtype=np.float64).ravel()
    # NT-01 stores 20000 Hz by mistake (see the folder README): both are 2000 Hz.
    return np.stack([biceps, brachio], axis=1), 2000.0


def noraxon_recording(name: str) -> Recording:
    x, rate = noraxon_mat(name)
    channels = {
        "BicepsBrachi": Channel("BicepsBrachi", x[:, 0] * 1e-6, rate, "V", "emg", site="biceps"),
        "Brachioradialis": Channel(
            "Brachioradialis", x[:, 1] * 1e-6, rate, "V", "emg", site="forearm"
        ),
    }
    return Recording(channels, source=f"{name}.mat", format="noraxon_mat")


def biosppy_emg(name: str = "emg_1.txt") -> tuple[NDArray[np.float64], float]:
    """BioSPPy example EMG in ADC counts with the mid-scale offset removed, 1000 Hz."""
    path = shared_file(f"biosppy_emg_examples/{name}")
    x = np.loadtxt(path, comments="#")
    return x - 2048.0, 1000.0


def pyomeca_c3d() -> Recording:
    """Markers [m] (with residual-based confidence) and EMG [V] of the pyomeca upper-limb trial."""
    import ezc3d

    path = shared_file("pyomeca_upperlimb_c3d_emg/markers_analogs.c3d")
    c3d = ezc3d.c3d(str(path))
    params = c3d["parameters"]
    point_rate = float(params["POINT"]["RATE"]["value"][0])
    analog_rate = float(params["ANALOG"]["RATE"]["value"][0])
    labels = params["POINT"]["LABELS"]["value"]
    points = c3d["data"]["points"][:3] / 1000.0  # mm -> m
    residuals = c3d["data"]["meta_points"]["residuals"][0]
    channels: dict[str, Channel] = {}
    for i, label in enumerate(labels):
        name = label.split(":")[-1]
        conf = (residuals[i] >= 0).astype(np.float64)
        channels[name] = Channel(
            name, points[:, i, :].T.copy(), point_rate, "m", "marker", confidence=conf
        )
    analogs = c3d["data"]["analogs"][0]
    sites = {"Delt_ant": "deltoid", "Biceps": "biceps", "Triceps": "triceps"}
    for i, label in enumerate(params["ANALOG"]["LABELS"]["value"]):
        muscle = label.split(".")[0]
        if muscle in sites:
            channels[label] = Channel(
                label, analogs[i].astype(np.float64), analog_rate, "V", "emg", site=sites[muscle]
            )
    return Recording(channels, source=Path(path).name, format="c3d")


def mediapipe_csv(frame_rate: float = 30.0) -> Recording:
    """The MediaPipe bicep-curl landmarks: (N, 3) normalised x, y, z with visibility."""
    path = shared_file("mediapipe_bicep_curl_frames/test.csv")
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    values = np.array([[float(v) for v in row[1:]] for row in body])
    channels: dict[str, Channel] = {}
    for j in range(0, values.shape[1], 4):
        name = header[1 + j][: -len("_x")]
        xyz = values[:, j : j + 3].copy()
        channels[name] = Channel(
            name, xyz, frame_rate, "norm", "landmark", confidence=values[:, j + 3].copy()
        )
    return Recording(channels, source=Path(path).name, format="mediapipe_csv")
