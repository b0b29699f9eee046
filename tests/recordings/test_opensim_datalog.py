"""OpenSim TRC/MOT/STO and Biometrics DataLOG readers."""

from __future__ import annotations

import csv
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.recordings import DatalogSensor, RecordingError, read_bytes, read_recording
from tests.conftest import shared_file
from tests.recordings._writers import emg_like, write_datalog

FOLDER = "pyomeca_upperlimb_c3d_emg/"


def _rows(path: Path, skip: int) -> list[list[str]]:
    with path.open(newline="") as fh:
        return [r for r in list(csv.reader(fh))[skip:] if any(x.strip() for x in r)]


def test_real_trc_does_not_trust_numframes(shared_data: Path) -> None:
    path = shared_file(FOLDER + "markers.trc")
    rows = _rows(path, 5)
    rec = read_recording(path)
    assert rec.format == "trc"
    # README: header says NumFrames=652, 51 markers, 100 Hz, mm; 93 data rows x 155 columns
    assert rec.metadata["declared_rows"] == 652 and rec.metadata["actual_rows"] == 93 == len(rows)
    assert any("NumFrames=652" in w for w in rec.metadata["warnings"])
    markers = rec.of_kind("marker")
    assert len(markers) == 51 and {m.data.shape for m in markers} == {(93, 3)}
    acro = rec.channels["ACRO_tip"]
    assert acro.rate == 100.0 and acro.unit == "m"
    k = 2 + 3 * list(rec.channels).index("ACRO_tip")
    np.testing.assert_allclose(acro.data[:, 0], [float(r[k]) / 1000 for r in rows])


def test_real_mot_and_sto(shared_data: Path) -> None:
    mot = read_recording(shared_file(FOLDER + "inverse_kin.mot"))
    rows = _rows(shared_file(FOLDER + "inverse_kin.mot"), 11)
    # README: nRows=250 declared, 88 rows x 26 columns, t = 1.56..2.43 s, inDegrees=yes
    assert mot.format == "mot" and mot.metadata["declared_rows"] == 250
    assert mot.metadata["actual_rows"] == 88 and len(mot.channels) == 25
    elbow = mot.channels["elbow_flexion"]
    assert elbow.kind == "angle" and elbow.unit == "rad"
    assert elbow.start == pytest.approx(1.56) and elbow.rate == 100.0
    assert elbow.start + (elbow.n_samples - 1) / elbow.rate == pytest.approx(2.43)
    column = rows[0].index("elbow_flexion") if "elbow_flexion" in rows[0] else 16
    np.testing.assert_allclose(elbow.data, np.deg2rad([float(r[column]) for r in rows]))
    assert mot.channels["thorax_tx"].unit == "m"

    sto = read_recording(shared_file(FOLDER + "inverse_dyn.sto"))
    assert sto.format == "sto" and sto.metadata["actual_rows"] == 92
    assert sto.metadata["declared_rows"] == 250 and len(sto.channels) == 25
    assert sto.channels["thorax_ty_force"].unit == "N"
    assert sto.channels["thorax_tilt_moment"].unit == "N*m"


def test_standard_tab_trc_with_gap(tmp_path: Path) -> None:
    n = 20
    t = np.arange(n) / 60.0
    lines = [
        "PathFileType\t4\t(X/Y/Z)\tcurl.trc",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
        f"60\t60\t{n}\t2\tmm\t60\t1\t{n}",
        "Frame#\tTime\tRELB\t\t\tRWRA\t\t",
        "\t\tX1\tY1\tZ1\tX2\tY2\tZ2",
        "",
    ]
    for i in range(n):
        wrist = "\t\t" if i == 7 else f"{300 + i:.3f}\t{100.0:.3f}\t{1000.0:.3f}"
        lines.append(f"{i + 1}\t{t[i]:.5f}\t{10.0 * i:.3f}\t{200.0:.3f}\t{1000.0:.3f}\t{wrist}")
    path = tmp_path / "curl.trc"
    path.write_text("\n".join(lines) + "\n")
    rec = read_recording(path)
    assert rec.channels["RELB"].rate == 60.0
    np.testing.assert_allclose(rec.channels["RELB"].data[:, 0], 0.01 * np.arange(n))
    wrist = rec.channels["RWRA"]
    assert np.isnan(wrist.data[7]).all() and wrist.confidence is not None
    assert wrist.confidence[7] == 0 and wrist.confidence[6] == 1
    assert rec.metadata["declared_rows"] == n and rec.metadata["warnings"] == []


def test_tab_mot_in_degrees(tmp_path: Path) -> None:
    t = np.arange(50) / 100.0
    elbow = 75 - 70 * np.cos(np.pi * t / t[-1])
    lines = [
        "Coordinates",
        "version=1",
        "nRows=50",
        "nColumns=3",
        "inDegrees=yes",
        "endheader",
        "time\telbow_flexion\tshoulder_elv",
    ]
    lines += [f"{a:.4f}\t{b:.6f}\t{10.0 + a:.6f}" for a, b in zip(t, elbow, strict=True)]
    rec = read_bytes("\n".join(lines).encode(), "ik.txt")
    assert rec.format == "mot"
    np.testing.assert_allclose(rec.channels["elbow_flexion"].data, np.deg2rad(np.round(elbow, 6)))


#: Writes an STO with OpenSim's own STOFileAdapter (argv: path, inDegrees, then a JSON table).
_WRITE_STO = """
import json, sys
import opensim as osim
path, deg, data = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
table = osim.TimeSeriesTable()
table.setColumnLabels(data["labels"])
for ti, values in zip(data["t"], data["rows"]):
    row = osim.RowVector(len(values), 0.0)
    for j, v in enumerate(values):
        row[j] = float(v)
    table.appendRow(float(ti), row)
table.addTableMetaDataString("inDegrees", deg)
osim.STOFileAdapter.write(table, path)
"""


def _opensim_sto(path: Path, labels: list[str], t: np.ndarray, cols: np.ndarray, deg: str) -> Path:
    """An STO written by OpenSim itself (STOFileAdapter, as IK and the Manager write them).

    OpenSim is run in a child process: importing it puts its own libraries (a CasADi 3.7
    among them) first on this process's LD_LIBRARY_PATH, which every later subprocess of the
    test run would inherit, breaking CasADi 3.8 in them."""
    if importlib.util.find_spec("opensim") is None:
        pytest.skip("opensim (pip install opensim) writes the STO")
    data = {"labels": labels, "t": t.tolist(), "rows": np.asarray(cols).tolist()}
    done = subprocess.run(
        [sys.executable, "-c", _WRITE_STO, str(path), deg, json.dumps(data)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    return path


def test_opensim4_states_sto_in_radians(tmp_path: Path) -> None:
    from app.analysis import angles_from_channels

    t = np.arange(200) / 100.0
    elbow = 0.2 + 1.1 * (1 - np.cos(np.pi * t))
    shoulder = 0.1 + 0.05 * np.sin(np.pi * t)
    labels = [
        "/jointset/r_shoulder/r_shoulder_elev/value",
        "/jointset/r_elbow/r_elbow_flex/value",
        "/jointset/r_elbow/r_elbow_flex/speed",
        "/forceset/BIClong/activation",
    ]
    cols = np.column_stack([shoulder, elbow, 1.1 * np.pi * np.sin(np.pi * t), 0.3 + 0 * t])
    path = _opensim_sto(tmp_path / "arm26_states.sto", labels, t, cols, "no")
    assert "inDegrees=no" in path.read_text() and "OpenSimVersion=" in path.read_text()
    rec = read_recording(path)
    assert rec.format == "sto"
    flex = rec.channels["/jointset/r_elbow/r_elbow_flex/value"]
    assert flex.kind == "angle" and flex.unit == "rad" and flex.rate == pytest.approx(100.0)
    np.testing.assert_allclose(flex.data, elbow, rtol=1e-12)  # radians kept, not scaled
    speed = rec.channels["/jointset/r_elbow/r_elbow_flex/speed"]
    assert speed.kind == "other" and speed.unit == "rad/s"
    act = rec.channels["/forceset/BIClong/activation"]
    assert act.kind == "other" and act.unit == ""
    assert not any("assumed" in w for w in rec.metadata["warnings"])
    arm = angles_from_channels(rec)
    assert arm is not None and arm.side == "right"
    assert np.nanmax(arm.elbow) == pytest.approx(2.4, abs=0.02)
    assert np.nanmax(arm.shoulder) == pytest.approx(0.15, abs=0.01)


def test_opensim_ik_sto_in_radians_and_degrees(tmp_path: Path) -> None:
    t = np.arange(100) / 50.0
    elbow = 1.2 - 1.0 * np.cos(np.pi * t)
    labels = ["elbow_flexion", "shoulder_elv", "pelvis_tx", "BIClong"]
    cols = np.column_stack([elbow, 0.2 + 0 * t, 0.5 + 0.01 * t, 0.4 + 0.1 * t])
    rad = read_recording(_opensim_sto(tmp_path / "ik_rad.sto", labels, t, cols, "no"))
    assert rad.channels["elbow_flexion"].kind == "angle"
    assert rad.channels["elbow_flexion"].unit == "rad"
    np.testing.assert_allclose(rad.channels["elbow_flexion"].data, elbow, rtol=1e-12)
    assert rad.channels["pelvis_tx"].unit == "m"
    assert rad.channels["BIClong"].kind == "other"  # an activation, not a coordinate
    deg = read_recording(_opensim_sto(tmp_path / "ik_deg.sto", labels, t, np.rad2deg(cols), "yes"))
    np.testing.assert_allclose(deg.channels["elbow_flexion"].data, elbow, rtol=1e-12)


# ---------------------------------------------------------------------------------------------
# DataLOG

SENSORS = [
    DatalogSensor(0, "biceps", "emg", 1000.0, 3.0, "mV"),
    DatalogSensor(1, "elbow", "angle", 100.0, 180.0, "deg"),
    DatalogSensor(2, "wrist acc", "accel", 100.0, 2.0, "g", counts_range=2000.0),
]


def _datalog(tmp_path: Path) -> tuple[Path, list[np.ndarray]]:
    emg = np.round(emg_like(2000, 1000.0, seed=9) / 3e-3 * 4000).astype(int)  # 2 s at 1 kHz
    gonio = np.round(np.linspace(0, 150, 200) / 180 * 4000).astype(int)  # 2 s at 100 Hz
    acc = np.round(np.sin(np.arange(200) / 10) * 1000).astype(int)
    path = tmp_path / "S01.txt"
    write_datalog(path, [emg, gonio, acc])
    return path, [emg, gonio, acc]


def test_datalog_ragged_columns_and_scaling(tmp_path: Path) -> None:
    path, (emg, gonio, acc) = _datalog(tmp_path)
    assert path.read_bytes().count(b"\r\n") == 2000  # CRLF, one line per fastest sample

    rec = read_recording(path, datalog_sensors=SENSORS)

    assert rec.format == "datalog_txt"
    biceps, elbow, wrist = rec.channels["biceps"], rec.channels["elbow"], rec.channels["wrist acc"]
    assert biceps.n_samples == 2000 and elbow.n_samples == 200 and wrist.n_samples == 200
    np.testing.assert_allclose(biceps.data, emg * 3e-3 / 4000)  # ±4000 counts = ±3 mV
    assert biceps.site == "biceps" and biceps.unit == "V"
    np.testing.assert_allclose(elbow.data, np.deg2rad(gonio * 180 / 4000))  # ±4000 = ±180 deg
    np.testing.assert_allclose(wrist.data, acc * 2 / 2000 * 9.80665)
    assert biceps.duration == elbow.duration == 2.0
    assert rec.metadata["warnings"] == []


def test_datalog_sidecar_and_wrong_rate_warning(tmp_path: Path) -> None:
    path, _ = _datalog(tmp_path)
    sensors = [
        {
            "column": 0,
            "name": "biceps",
            "kind": "emg",
            "rate": 1000,
            "physical_range": 3,
            "unit": "mV",
        },
        {
            "column": 1,
            "name": "elbow",
            "kind": "angle",
            "rate": 50,
            "physical_range": 180,
            "unit": "deg",
        },
    ]
    (tmp_path / "S01.txt.json").write_text(json.dumps({"sensors": sensors}))
    rec = read_recording(path)
    assert rec.channels["elbow"].rate == 50.0
    # 200 samples at 50 Hz last 4 s while the EMG lasts 2 s: the warning names the rate that fits
    assert any(
        "'elbow' lasts 4 s" in w and "100 Hz would match" in w for w in rec.metadata["warnings"]
    )
    assert rec.metadata["ignored_columns"] == [2]


def test_datalog_needs_rates(tmp_path: Path) -> None:
    path, _ = _datalog(tmp_path)
    with pytest.raises(RecordingError, match=r"S01\.txt: DataLOG export states no sensor rates"):
        read_recording(path)
    rec = read_recording(path, rate=1000.0)
    assert rec.channels["column1"].unit == "counts"
    with pytest.raises(RecordingError, match=r"channel 'knee': sensor column 7 does not exist"):
        read_recording(
            path, datalog_sensors=[DatalogSensor(7, "knee", "angle", 100.0, 180.0, "deg")]
        )


def test_writing_with_opensim_leaves_this_process_alone(tmp_path: Path) -> None:
    """Importing OpenSim here put its CasADi 3.7 on LD_LIBRARY_PATH, and every later `bioplan`
    subprocess of the run failed to import CasADi 3.8 (found by a clean CI run)."""
    t = np.linspace(0.0, 1.0, 5)
    _opensim_sto(tmp_path / "x.sto", ["elbow_flexion"], t, t[:, None], "no")
    assert "opensim" not in sys.modules
    assert "opensim" not in os.environ.get("LD_LIBRARY_PATH", "")
