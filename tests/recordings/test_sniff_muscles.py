"""Format sniffing (real and synthetic files, misleading extensions) and muscle mapping."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from app.recordings import FORMATS, RecordingError, map_muscle, read_recording, sniff_format
from app.recordings._read import READERS
from tests.conftest import shared_file
from tests.recordings._writers import (
    emg_like,
    mediapipe_frames,
    write_datalog,
    write_edf,
    write_vicon_csv,
)

REAL = {
    "biosppy_emg_examples/emg.txt": "csv",
    "biosppy_emg_examples/emg_1.txt": "csv",
    "c3d_bts_gait_emg/BTS.c3d": "c3d",
    "edf_emg_bids_examples/emg_CustomBipolar/sub-01_task-holdWeight_emg.edf": "edf",
    "edf_emg_bids_examples/emg_Multimodal/sub-01_task-pullstand_emg.edf": "edf",
    "mediapipe_bicep_curl_frames/test.csv": "mediapipe_csv",
    "noraxon_curls_biceps_brachioradialis/2023-04-20-15-06_BR_posredni.csv": "noraxon_csv",
    "noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv": "noraxon_csv",
    "noraxon_curls_biceps_brachioradialis/NT-01.mat": "mat",
    "noraxon_curls_biceps_brachioradialis/SP-01.mat": "mat",
    "pyomeca_upperlimb_c3d_emg/analogs.csv": "vicon_csv",
    "pyomeca_upperlimb_c3d_emg/inverse_dyn.sto": "sto",
    "pyomeca_upperlimb_c3d_emg/inverse_kin.mot": "mot",
    "pyomeca_upperlimb_c3d_emg/markers.trc": "trc",
    "pyomeca_upperlimb_c3d_emg/markers_analogs.c3d": "c3d",
}


def test_every_format_has_a_reader() -> None:
    assert set(FORMATS) == set(READERS) and len(FORMATS) == 15  # xdf is the 15th


@pytest.mark.parametrize(("relative", "fmt"), sorted(REAL.items()))
def test_sniff_real_files(shared_data: Path, relative: str, fmt: str) -> None:
    assert sniff_format(shared_file(relative)) == fmt


@pytest.mark.parametrize(("relative", "fmt"), sorted(REAL.items()))
def test_real_files_read_with_json_metadata(shared_data: Path, relative: str, fmt: str) -> None:
    options = {"frame_rate": 30.0} if fmt == "mediapipe_csv" else {}
    try:
        rec = read_recording(shared_file(relative), **options)  # type: ignore[arg-type]
    except RecordingError as err:
        assert "pullstand" in relative and "255 bytes" in str(err)  # the one malformed file
        return
    assert rec.format == fmt and rec.source == Path(relative).name
    # the service stores metadata as JSON: plain types only
    assert json.loads(json.dumps(rec.metadata)) == rec.metadata
    assert all(isinstance(w, str) for w in rec.metadata["warnings"])


@pytest.mark.parametrize(
    ("relative", "misleading"),
    [
        ("noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv", "export.txt"),
        ("pyomeca_upperlimb_c3d_emg/markers_analogs.c3d", "trial.csv"),
        ("noraxon_curls_biceps_brachioradialis/SP-01.mat", "emg.dat"),
        ("mediapipe_bicep_curl_frames/test.csv", "pose.json"),
        ("pyomeca_upperlimb_c3d_emg/analogs.csv", "devices.c3d"),
        ("pyomeca_upperlimb_c3d_emg/inverse_kin.mot", "ik.csv"),
        ("pyomeca_upperlimb_c3d_emg/markers.trc", "markers.mot"),
        ("edf_emg_bids_examples/emg_CustomBipolar/sub-01_task-holdWeight_emg.edf", "emg.mat"),
    ],
)
def test_sniff_ignores_a_misleading_extension(
    shared_data: Path, tmp_path: Path, relative: str, misleading: str
) -> None:
    target = tmp_path / misleading
    shutil.copy(shared_file(relative), target)
    assert sniff_format(target) == REAL[relative]


def _synthetic(tmp_path: Path) -> dict[str, Path]:
    import h5py
    import scipy.io as sio

    out: dict[str, Path] = {}
    out["vicon_csv"] = tmp_path / "vicon.dat"
    write_vicon_csv(out["vicon_csv"])
    out["datalog_txt"] = tmp_path / "datalog.csv"
    write_datalog(out["datalog_txt"], [list(range(100)), list(range(10))])
    lm = mediapipe_frames(3)
    frames = [
        {"timestamp_ms": 33 * i, "pose_landmarks": [[{"x": p[0], "y": p[1]} for p in f]]}
        for i, f in enumerate(lm.tolist())
    ]
    out["mediapipe_json"] = tmp_path / "landmarks.txt"
    out["mediapipe_json"].write_text(json.dumps(frames))
    header = ",".join(f"{a}{k}" for k in range(33) for a in "xyzv")
    out["mediapipe_csv"] = tmp_path / "ids.txt"
    out["mediapipe_csv"].write_text(header + "\n" + ",".join(["0.5"] * 132) + "\n")
    out["edf"] = tmp_path / "rec.bin"
    write_edf(out["edf"], [emg_like(400, 200.0) * 1e6], ["EMG1"], ["uV"], [200.0])
    out["mat"] = tmp_path / "v5.bin"
    sio.savemat(out["mat"], {"x": np.arange(5.0)})
    out["csv"] = tmp_path / "generic.mat"
    out["csv"].write_text("time;biceps\n0;1,5\n0,001;2,5\n")
    h5 = tmp_path / "plain.h5"
    with h5py.File(h5, "w") as f:
        f["x"] = np.arange(4.0)
    out["mat#h5"] = h5
    return out


def test_sniff_synthetic_files(tmp_path: Path) -> None:
    for fmt, path in _synthetic(tmp_path).items():
        assert sniff_format(path) == fmt.split("#")[0], path.name


def test_sniff_rejects_empty_and_unknown_binary(tmp_path: Path) -> None:
    empty = tmp_path / "empty.csv"
    empty.write_bytes(b"")
    with pytest.raises(RecordingError, match=r"^empty\.csv: file is empty"):
        sniff_format(empty)
    blob = tmp_path / "video.mp4"
    blob.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(range(256)) * 4)
    with pytest.raises(RecordingError, match=r"video\.mp4: is a video, not a recording"):
        sniff_format(blob)
    other = tmp_path / "scan.bin"
    other.write_bytes(b"\x00\x01BLOB" + bytes(range(256)) * 4)
    with pytest.raises(RecordingError, match=r"scan\.bin: is a binary file of unknown") as err:
        sniff_format(other)
    # The message names the formats that are supported.
    for name in ("C3D", "EDF", "Delsys", "Qualisys", "OpenSim", "MediaPipe", "mp4"):
        assert name in str(err.value)
    with pytest.raises(RecordingError, match=r"missing\.csv: cannot be read"):
        sniff_format(tmp_path / "missing.csv")


# ---------------------------------------------------------------------------------------------
# muscles


@pytest.mark.parametrize(
    ("label", "site"),
    [
        ("Biceps.EMG4", "biceps"),
        ("BIC", "biceps"),
        ("biceps brachii", "biceps"),
        ("BicepsBrachi", "biceps"),
        ("R_BICEPS (uV)", "biceps"),
        ("Delt_ant", "deltoid"),
        ("Delt_ant.EMG1", "deltoid"),
        ("DELT", "deltoid"),
        ("anterior deltoid", "deltoid"),
        ("TRI", "triceps"),
        ("Triceps", "triceps"),
        ("Triceps.EMG5", "triceps"),
        ("brachioradialis", "forearm"),
        ("BRACHIORAD. LT (uV)", "forearm"),
        ("BR", "forearm"),
        ("forearm", "forearm"),
        ("ECRB", "forearm"),
        ("FCR", "forearm"),
        ("Flexor carpi radialis, Pronator teres, Brachioradialis", "forearm"),
        ("extensor carpi radialis brevis", "forearm"),
        ("Left Rectus femoris", None),
        ("biceps femoris", None),
        ("Right Gastrocnemius medialis", None),
        ("L_leg_emg_tibialis_anterior", None),
        ("L_neck_emg", None),
        ("Trap_sup.EMG6", None),
        ("Supra.EMG9", None),
        ("Pec.IM EMG12", None),
        ("Sensor 12.EMG12", None),
        ("EMG1", None),
        ("Voltage.1", None),
        ("", None),
    ],
)
def test_map_muscle(label: str, site: str | None) -> None:
    assert map_muscle(label) == site


def test_muscle_map_errors_name_the_problem(tmp_path: Path) -> None:
    path = tmp_path / "rec.csv"
    path.write_text(
        "time,ch1,ch2\n" + "".join(f"{i / 1000},{np.sin(i)},{np.cos(i)}\n" for i in range(50))
    )
    with pytest.raises(
        RecordingError,
        match=r"rec\.csv: muscle_map names channel 'ch9'.*expected one of 'ch1', 'ch2'",
    ):
        read_recording(path, muscle_map={"ch9": "biceps"})
    with pytest.raises(RecordingError, match=r"unknown site 'calf'"):
        read_recording(path, muscle_map={"ch1": "calf"})
    rec = read_recording(path, muscle_map={"ch1": "biceps"})
    assert rec.channels["ch1"].kind == "emg" and rec.emg_by_site()["biceps"].name == "ch1"


def test_a_text_file_named_like_a_binary_format_is_said_to_be_misnamed(tmp_path: Path) -> None:
    """Issue 29: a text file renamed .mat got only the CSV parser's complaint; the message now
    says first that the file is not what its name says."""
    misnamed = tmp_path / "trial.mat"
    misnamed.write_text("these are my notes about the session\nnothing to plot here\n")
    with pytest.raises(RecordingError) as err:
        read_recording(misnamed)
    assert re.match(
        r"trial\.mat(, line 1)?: is named \.mat but is not a mat file; read as csv", str(err.value)
    )
    # A file that reads as what its bytes hold is still read (the extension is only a hint).
    good = tmp_path / "generic.mat"
    good.write_text("time;biceps\n0;1,5\n0,001;2,5\n0,002;2,0\n")
    assert read_recording(good, rate=None).channels
