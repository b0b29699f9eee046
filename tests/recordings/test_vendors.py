"""Formats users asked for: Delsys EMGworks and Trigno CSV, Qualisys TSV, OpenSim coordinate
names, BIDS EDF sidecars given with an upload.

The Delsys and Qualisys files are written here in the layouts the vendors document (no such
file is in the shared data); values are checked against what was written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.analysis import angles_from_channels
from app.recordings import read_bytes, read_recording, sniff_format
from tests.conftest import shared_file
from tests.recordings._writers import emg_like

CUSTOM = "edf_emg_bids_examples/emg_CustomBipolar/sub-01_task-holdWeight"


def _emgworks(path: Path, emg: np.ndarray, rate: float, acc: np.ndarray, acc_rate: float) -> Path:
    """EMGworks export: preamble, then X[s],<label>: EMG n pairs; the accelerometer's shorter
    columns end early (empty cells)."""
    rows = [
        "Label:,curl trial 3",
        "Application:,EMGworks Acquisition",
        "",
        "X[s],R BICEPS BRACHII: EMG 1,X[s],R TRICEPS BRACHII: EMG 2,X[s],R BICEPS BRACHII: ACC X 1",
    ]
    for i in range(len(emg)):
        cells = [f"{i / rate:.6f}", f"{emg[i, 0]:.6e}", f"{i / rate:.6f}", f"{emg[i, 1]:.6e}"]
        cells += [f"{i / acc_rate:.6f}", f"{acc[i]:.5f}"] if i < len(acc) else ["", ""]
        rows.append(",".join(cells))
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def test_delsys_emgworks_keeps_muscle_names_and_rates(tmp_path: Path) -> None:
    rate, acc_rate = 1925.925, 148.148
    emg = np.column_stack([emg_like(4000, rate, seed=1), emg_like(4000, rate, seed=2)])
    acc = np.sin(np.arange(300) / 20.0)
    path = _emgworks(tmp_path / "trial3.csv", emg, rate, acc, acc_rate)
    assert sniff_format(path) == "delsys_csv"
    rec = read_recording(path)
    assert rec.format == "delsys_csv"
    biceps = rec.channels["R BICEPS BRACHII: EMG 1"]
    triceps = rec.channels["R TRICEPS BRACHII: EMG 2"]
    assert biceps.kind == "emg" and biceps.site == "biceps" and triceps.site == "triceps"
    assert biceps.rate == pytest.approx(rate, rel=1e-4) and biceps.n_samples == 4000
    np.testing.assert_allclose(biceps.data, emg[:, 0], rtol=1e-6)
    accel = rec.channels["R BICEPS BRACHII: ACC X 1"]
    assert accel.kind == "accel" and accel.n_samples == 300  # the empty tail is not data
    assert accel.rate == pytest.approx(acc_rate, rel=1e-3)


def test_delsys_trigno_discover_takes_labels_from_the_sensor_row(tmp_path: Path) -> None:
    rate = 2148.1481
    emg = np.column_stack([emg_like(3000, rate, seed=3), emg_like(3000, rate, seed=4)]) * 1e3
    rows = [
        "Application:,Trigno Discover (v1.5.2)",
        "Date/Time:,01/02/2024 10:00:00",
        "Collection Length (seconds):,1.4",
        "",
        "Biceps R (81728),,Deltoid anterior R (81730),",
        "X [s],EMG 1 (mV),X [s],EMG 1 (mV)",
    ] + [f"{i / rate:.6f},{emg[i, 0]:.6f},{i / rate:.6f},{emg[i, 1]:.6f}" for i in range(len(emg))]
    path = tmp_path / "trigno.csv"
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    rec = read_recording(path)
    assert set(rec.channels) == {"Biceps R: EMG 1", "Deltoid anterior R: EMG 1"}
    ch = rec.channels["Biceps R: EMG 1"]
    assert ch.site == "biceps" and ch.unit == "V"
    np.testing.assert_allclose(ch.data, emg[:, 0] * 1e-3, atol=6e-10)  # 6 decimals of mV
    assert rec.channels["Deltoid anterior R: EMG 1"].site == "deltoid"


def _qualisys_3d(path: Path, xyz_mm: np.ndarray, names: list[str], rate: float) -> Path:
    n = xyz_mm.shape[0]
    head = [
        f"NO_OF_FRAMES\t{n}",
        "NO_OF_CAMERAS\t8",
        f"NO_OF_MARKERS\t{len(names)}",
        f"FREQUENCY\t{rate:g}",
        "NO_OF_ANALOG\t0",
        "ANALOG_FREQUENCY\t0",
        "DESCRIPTION\t--",
        "TIME_STAMP\t2024-01-02, 10:00:00",
        "DATA_INCLUDED\t3D",
        "MARKER_NAMES\t" + "\t".join(names),
        "Frame\tTime\t" + "\t".join(f"{m} {a}" for m in names for a in "XYZ"),
    ]
    rows = [
        f"{i + 1}\t{i / rate:.3f}\t" + "\t".join(f"{v:.3f}" for v in xyz_mm[i].ravel())
        for i in range(n)
    ]
    path.write_text("\n".join(head + rows) + "\n", encoding="utf-8")
    return path


def test_qualisys_3d_markers_in_metres_with_zero_gaps(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    xyz = rng.uniform(100, 1500, size=(120, 3, 3))
    xyz[40:45, 1] = 0.0  # QTM writes zeros where the marker was lost
    path = _qualisys_3d(tmp_path / "curl.tsv", xyz, ["RSHO", "RELB", "RWRA"], 100.0)
    assert sniff_format(path) == "qualisys_tsv"
    rec = read_recording(path)
    elb = rec.channels["RELB"]
    assert elb.kind == "marker" and elb.rate == 100.0 and elb.unit == "m"
    np.testing.assert_allclose(rec.channels["RSHO"].data, xyz[:, 0] / 1000.0, atol=1e-6)
    assert np.isnan(elb.data[40:45]).all() and np.isfinite(elb.data[:40]).all()
    assert elb.confidence is not None and elb.confidence[42] == 0.0


def test_qualisys_analog_emg(tmp_path: Path) -> None:
    rate = 1500.0
    emg = np.column_stack([emg_like(1500, rate, seed=5), emg_like(1500, rate, seed=6)])
    head = [
        "NO_OF_CHANNELS\t2",
        "NO_OF_SAMPLES\t1500",
        f"FREQUENCY\t{rate:g}",
        "CHANNEL_NAMES\tBiceps EMG\tTriceps EMG",
        "SAMPLE\tTIME\tBiceps EMG\tTriceps EMG",
    ]
    rows = [f"{i + 1}\t{i / rate:.5f}\t{emg[i, 0]:.6e}\t{emg[i, 1]:.6e}" for i in range(1500)]
    path = tmp_path / "curl_a.tsv"
    path.write_text("\n".join(head + rows) + "\n", encoding="utf-8")
    rec = read_recording(path)
    assert rec.format == "qualisys_tsv"
    biceps = rec.channels["Biceps EMG"]
    assert biceps.kind == "emg" and biceps.site == "biceps" and biceps.rate == rate
    np.testing.assert_allclose(biceps.data, emg[:, 0], rtol=1e-5)


def test_opensim_coordinate_names_give_the_arm_of_the_moving_side(tmp_path: Path) -> None:
    rate = 100.0
    t = np.arange(300) / rate
    elbow_r = 20 + 110 * (1 - np.cos(2 * np.pi * t / 3.0)) / 2
    cols = {
        "time": t,
        "arm_flex_r": 10 + 0 * t,
        "elbow_flex_r": elbow_r,
        "arm_flex_l": 5 + 0 * t,
        "elbow_flex_l": 15 + 0 * t,
    }
    header = ["Coordinates", "version=1", f"nRows={len(t)}", f"nColumns={len(cols)}",
              "inDegrees=yes", "endheader", "\t".join(cols)]  # fmt: skip
    rows = ["\t".join(f"{cols[c][i]:.6f}" for c in cols) for i in range(len(t))]
    path = tmp_path / "ik.mot"
    path.write_text("\n".join(header + rows) + "\n", encoding="utf-8")
    rec = read_recording(path)
    auto = angles_from_channels(rec)
    assert auto is not None and auto.side == "right"
    assert np.nanmax(np.rad2deg(auto.elbow)) == pytest.approx(130.0, abs=1.0)
    assert np.nanmedian(np.rad2deg(auto.shoulder)) == pytest.approx(10.0, abs=0.5)
    left = angles_from_channels(rec, side="left")
    assert left is not None and left.side == "left"
    assert np.nanmedian(np.rad2deg(left.shoulder)) == pytest.approx(5.0, abs=0.5)


def test_bids_sidecars_given_with_an_uploaded_edf(shared_data: Path) -> None:
    edf = shared_file(CUSTOM + "_emg.edf").read_bytes()
    tsv = shared_file(CUSTOM + "_channels.tsv").read_bytes()
    meta = shared_file(CUSTOM + "_emg.json").read_bytes()
    name = "sub-01_task-holdWeight_emg.edf"
    bare = read_bytes(edf, name)
    assert bare.channels["EMG1"].site is None  # no sidecars: EMG1 names no muscle
    rec = read_bytes(
        edf,
        name,
        sidecars={
            "sub-01_task-holdWeight_channels.tsv": tsv,
            "sub-01_task-holdWeight_emg.json": meta,
        },
    )
    assert rec.channels["EMG1"].site == "forearm"  # target muscle from channels.tsv
    assert rec.metadata["device"] == "Custom Raspberry Pi"  # from _emg.json
