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


def test_delsys_trigger_rows_are_not_sensor_labels(tmp_path: Path) -> None:
    # Trigno Discover 1.x writes its trigger settings as "Key: value" cells above the columns;
    # they once became every channel's name prefix.
    rate, acc_rate = 2148.1481, 148.1481
    emg = emg_like(3000, rate, seed=7) * 1e3
    acc = np.sin(np.arange(200) / 10.0)
    rows = [
        "Application:,Trigno Discover (v1.5.2)",
        "Date/Time:,01/02/2024 10:00:00",
        "Collection Length (seconds):,1.4",
        "Start Trigger Method: None,,Stop Trigger Method: None,",
        "",
        "X [s],EMG 1 (mV),X [s],ACC X 1 (G)",
    ]
    for i in range(3000):
        tail = f"{i / acc_rate:.6f},{acc[i]:.5f}" if i < 200 else ","
        rows.append(f"{i / rate:.6f},{emg[i]:.6f},{tail}")
    path = tmp_path / "trigno_trigger.csv"
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    rec = read_recording(path)
    assert set(rec.channels) == {"EMG 1", "ACC X 1"}
    accel = rec.channels["ACC X 1"]
    assert accel.kind == "accel" and accel.unit == "m/s^2"
    np.testing.assert_allclose(accel.data, np.round(acc, 5) * 9.80665, rtol=1e-9)
    assert rec.channels["EMG 1"].unit == "V"


def test_delsys_trigno_discover_2_layout(tmp_path: Path) -> None:
    """Trigno Discover 2.x: sensor row, ``sensor mode:`` row, ``... Time Series (s)`` time
    columns, a rate row and a period row, ``", "`` between cells, ACC in g."""
    rate, acc_rate = 1259.2593, 148.1481
    emg = np.column_stack([emg_like(2500, rate, seed=8), emg_like(2500, rate, seed=9)]) * 1e3
    acc = np.cos(np.arange(290) / 15.0)
    block = "EMG 1 Time Series (s), EMG 1 (mV), ACC X Time Series (s), ACC X (G)"
    head = [
        "Application:, Trigno Discover (2.1.0.7)",
        "Date/Time:, 01-01-2026 10:00:00",
        "Collection Length (seconds):, 1.985",
        "Biceps R (81728), , , , Triceps R (81730), , , ",
        "sensor mode: 65, , , , sensor mode: 65, , , ",
        f"{block}, {block}",
        f", {rate} Hz, , {acc_rate} Hz, , {rate} Hz, , {acc_rate} Hz",
        f", {1 / rate:.6f} s, , {1 / acc_rate:.6f} s, , {1 / rate:.6f} s, , {1 / acc_rate:.6f} s",
    ]
    rows = []
    for i in range(2500):
        a = f"{i / acc_rate:.6f}, {acc[i]:.5f}" if i < 290 else ", "
        rows.append(f"{i / rate:.6f}, {emg[i, 0]:.6f}, {a}, {i / rate:.6f}, {emg[i, 1]:.6f}, {a}")
    path = tmp_path / "trigno2.csv"
    path.write_text("\n".join(head + rows) + "\n", encoding="utf-8")
    assert sniff_format(path) == "delsys_csv"
    rec = read_recording(path)
    assert set(rec.channels) == {
        "Biceps R: EMG 1", "Biceps R: ACC X", "Triceps R: EMG 1", "Triceps R: ACC X",
    }  # fmt: skip
    biceps = rec.channels["Biceps R: EMG 1"]
    assert biceps.site == "biceps" and biceps.unit == "V" and biceps.rate == rate
    np.testing.assert_allclose(biceps.data, emg[:, 0] * 1e-3, atol=6e-10)
    assert rec.channels["Triceps R: EMG 1"].site == "triceps"
    accel = rec.channels["Triceps R: ACC X"]
    assert accel.kind == "accel" and accel.unit == "m/s^2" and accel.site is None
    assert accel.rate == acc_rate and accel.n_samples == 290
    np.testing.assert_allclose(accel.data, np.round(acc, 5) * 9.80665, rtol=1e-9)


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


def test_qtm_analog_tsv_export_is_sniffed_and_read(tmp_path: Path) -> None:
    """QTM's analog export (File > Export > TSV, analog data): TOT_NO_OF_CHAN and NO_OF_SAMPLES
    come first, then FREQUENCY, the board, NO_OF_CHANNELS, CHANNEL_NUMBERS, CHANNEL_NAMES; a
    SAMPLE/TIME column row; EMG in volts."""
    rate = 2000.0
    n = 3000
    emg = np.column_stack([emg_like(n, rate, seed=11), emg_like(n, rate, seed=12)])
    trigger = (np.arange(n) > 1500).astype(float) * 5.0
    head = [
        "TOT_NO_OF_CHAN\t3",
        f"NO_OF_SAMPLES\t{n}",
        f"FREQUENCY\t{rate:g}",
        "TIME_STAMP\t2024-01-02, 10:00:00.123\t1234.567",
        "DATA_INCLUDED\tAnalog",
        "BOARD_NAME\tDelsys Trigno",
        "NO_OF_CHANNELS\t3",
        "CHANNEL_NUMBERS\t1\t2\t3",
        "CHANNEL_NAMES\tBiceps R\tDeltoid anterior R\tTrigger",
        "SAMPLE\tTIME\tBiceps R\tDeltoid anterior R\tTrigger",
    ]
    rows = [
        f"{i + 1}\t{i / rate:.5f}\t{emg[i, 0]:.6e}\t{emg[i, 1]:.6e}\t{trigger[i]:.3f}"
        for i in range(n)
    ]
    path = tmp_path / "curl_a_1.tsv"
    path.write_text("\n".join(head + rows) + "\n", encoding="utf-8")
    assert sniff_format(path) == "qualisys_tsv"
    rec = read_recording(path)
    assert rec.format == "qualisys_tsv" and rec.metadata["board_name"] == "Delsys Trigno"
    assert list(rec.channels) == ["Biceps R", "Deltoid anterior R", "Trigger"]
    biceps = rec.channels["Biceps R"]
    assert biceps.kind == "emg" and biceps.site == "biceps" and biceps.unit == "V"
    assert biceps.rate == rate and biceps.n_samples == n
    np.testing.assert_allclose(biceps.data, emg[:, 0], rtol=1e-5)
    assert rec.channels["Deltoid anterior R"].site == "deltoid"
    assert rec.channels["Trigger"].kind == "other"
    assert not rec.metadata["warnings"]
    # the rate is FREQUENCY's; a TIME column that disagrees is reported
    other = path.read_text().replace(f"FREQUENCY\t{rate:g}", "FREQUENCY\t1000")
    rec = read_bytes(other.encode(), "curl_a_1.tsv")
    assert rec.channels["Biceps R"].rate == 1000.0
    assert any("disagrees with the TIME column (2000 Hz)" in w for w in rec.metadata["warnings"])


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
