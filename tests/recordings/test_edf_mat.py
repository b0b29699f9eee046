"""EDF/BDF (pyedflib) and MATLAB .mat (scipy v5, h5py v7.3) readers."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from app.recordings import RecordingError, read_bytes, read_recording
from tests.conftest import shared_file
from tests.recordings._writers import emg_like, write_edf

CUSTOM = "edf_emg_bids_examples/emg_CustomBipolar/sub-01_task-holdWeight_emg.edf"
MULTIMODAL = "edf_emg_bids_examples/emg_Multimodal/sub-01_task-pullstand_emg.edf"
NT01 = "noraxon_curls_biceps_brachioradialis/NT-01.mat"
SP01 = "noraxon_curls_biceps_brachioradialis/SP-01.mat"


# ---------------------------------------------------------------------------------------------
# EDF


def test_edf_custom_bipolar_with_bids_sidecar(shared_data: Path) -> None:
    pyedflib = pytest.importorskip("pyedflib")
    path = shared_file(CUSTOM)
    with pyedflib.EdfReader(str(path)) as ref:
        expected_uv = ref.readSignal(0)
    rec = read_recording(path)
    ch = rec.channels["EMG1"]
    # README: 1 channel EMG1, 2000 Hz, 2000 samples; EDF says uV, channels.tsv says V
    assert ch.kind == "emg" and ch.rate == 2000.0 and ch.n_samples == 2000
    np.testing.assert_allclose(ch.data, expected_uv * 1e-6, rtol=0, atol=1e-18)
    assert (
        ch.site == "forearm"
    )  # target_muscle: flexor carpi radialis, pronator teres, brachioradialis
    assert any("channels.tsv says 'V'" in w for w in rec.metadata["warnings"])
    assert rec.metadata["device"] == "Custom Raspberry Pi"


def test_edf_without_sidecar_from_bytes(shared_data: Path) -> None:
    data = shared_file(CUSTOM).read_bytes()
    rec = read_bytes(data, "upload.edf")
    assert rec.source == "upload.edf"
    assert rec.channels["EMG1"].site is None  # no sidecar: the label alone names no muscle


def _hand_parsed_multimodal(data: bytes) -> np.ndarray:
    """The Multimodal EDF's samples [uV] parsed by hand as its README describes them: data
    from byte 255 + 10 x 256, one record of 10 signals x 256 int16 samples, physical
    -500..500 uV over digital -32768..32767."""
    digital = np.frombuffer(data[255 + 10 * 256 :], dtype="<i2").reshape(10, 256)
    return (digital.astype(float) + 32768.0) * (1000.0 / 65535.0) - 500.0


def test_edf_255_byte_header_is_repaired_and_read(shared_data: Path) -> None:
    """Issue 29: the BIDS example's 255-byte fixed header (a writer dropped one byte of the
    patient field) is read with a stated repair; every sample equals the hand parse."""
    path = shared_file(MULTIMODAL)
    rec = read_recording(path)
    expected_uv = _hand_parsed_multimodal(path.read_bytes())
    tsv = path.with_name("sub-01_task-pullstand_channels.tsv").read_text()
    names = [line.split("\t")[0] for line in tsv.splitlines()[1:]]
    assert list(rec.channels) == names  # the sidecar's names, joined after the repair
    for i, ch in enumerate(rec.channels.values()):
        assert ch.rate == 256.0 and ch.kind == "emg" and ch.unit == "V"
        np.testing.assert_allclose(ch.data * 1e6, expected_uv[i], rtol=0, atol=1e-9)
    assert rec.metadata["start_date"].startswith("2025-09-23 12:00:00")  # field read unshifted
    notes = [w for w in rec.metadata["warnings"] if "255 bytes instead of 256" in w]
    assert len(notes) == 1 and "one space inserted after the patient field" in notes[0]


def test_edf_255_byte_header_refused_when_ambiguous(shared_data: Path) -> None:
    """The same header on a truncated file: the shifted reading no longer matches the file
    size, so it is not guessed at; the message names the 255-byte header."""
    data = shared_file(MULTIMODAL).read_bytes()
    with pytest.raises(RecordingError) as err:
        read_bytes(data[:-100], "sub-01_task-pullstand_emg.edf")
    text = str(err.value)
    assert text.startswith("sub-01_task-pullstand_emg.edf: EDF header is not standard-compliant")
    assert "255 bytes instead of 256" in text


@pytest.mark.parametrize("bdf", [False, True])
def test_edf_written_by_pyedflib(tmp_path: Path, bdf: bool) -> None:
    pytest.importorskip("pyedflib")
    biceps_uv = emg_like(4000, 2000.0, seed=1) * 1e6
    triceps_mv = emg_like(4000, 2000.0, seed=2) * 1e3
    elbow_deg = np.linspace(0.0, 140.0, 200)
    path = tmp_path / ("rec.bdf" if bdf else "rec.edf")
    write_edf(
        path,
        [biceps_uv, triceps_mv, elbow_deg],
        ["EMG Biceps", "EMG Triceps", "Elbow angle"],
        ["uV", "mV", "deg"],
        [2000.0, 2000.0, 100.0],
        bdf=bdf,
    )
    # reading the file under a misleading name: content decides
    odd = tmp_path / "recording.dat"
    shutil.copy(path, odd)

    rec = read_recording(odd)

    assert rec.format == "edf"
    # EDF stores 16-bit (BDF 24-bit) integers over the physical range: check to that resolution
    lsb = 1.2 * np.max(np.abs(biceps_uv)) * 2 / (2**24 if bdf else 2**16)
    np.testing.assert_allclose(rec.channels["EMG Biceps"].data, biceps_uv * 1e-6, atol=lsb * 1e-6)
    assert rec.channels["EMG Biceps"].site == "biceps"
    assert rec.channels["EMG Triceps"].site == "triceps"
    assert rec.channels["EMG Triceps"].unit == "V"
    elbow = rec.channels["Elbow angle"]
    assert elbow.kind == "angle" and elbow.rate == 100.0 and elbow.unit == "rad"
    np.testing.assert_allclose(elbow.data, np.deg2rad(elbow_deg), atol=1e-3)


def test_truncated_edf(tmp_path: Path) -> None:
    pytest.importorskip("pyedflib")
    path = tmp_path / "rec.edf"
    write_edf(path, [emg_like(4000, 2000.0) * 1e6], ["EMG1"], ["uV"], [2000.0])
    data = path.read_bytes()
    with pytest.raises(RecordingError, match=r"short\.edf: is truncated"):
        read_bytes(data[: len(data) - 1000], "short.edf")
    with pytest.raises(RecordingError, match=r"tiny\.edf: EDF header is not standard-compliant"):
        read_bytes(data[:200], "tiny.edf")


# ---------------------------------------------------------------------------------------------
# MAT


def test_nt01_stored_rate_is_flagged_and_overridable(shared_data: Path) -> None:
    path = shared_file(NT01)
    rec = read_recording(path)
    biceps = rec.emg_by_site()["biceps"]
    # README: BicepsBrachi (102400,) uV, stored sampling_frequency 20000 (really 2000)
    assert biceps.name == "BicepsBrachi" and biceps.n_samples == 102400
    assert biceps.rate == 20000.0 and rec.metadata["stored_rate"] == 20000.0
    assert rec.emg_by_site()["forearm"].name == "Brachioradialis"
    assert rec.metadata["suggested_emg_rate"] == 2000.0
    assert any("emg_rate=2000" in w for w in rec.metadata["warnings"])

    fixed = read_recording(path, emg_rate=2000)
    b = fixed.channels["BicepsBrachi"]
    assert b.rate == 2000.0 and b.duration == pytest.approx(51.2)  # README: 51.2 s at 2 kHz
    assert "suggested_emg_rate" not in fixed.metadata
    assert fixed.metadata["stored_emg_rate"] == 20000.0
    assert not any("implausible" in w for w in fixed.metadata["warnings"])
    np.testing.assert_array_equal(b.data, rec.channels["BicepsBrachi"].data)


def test_sp01_reads_against_h5py(shared_data: Path) -> None:
    h5py = pytest.importorskip("h5py")
    path = shared_file(SP01)
    with h5py.File(path, "r") as f:
        raw = f["EMG_recording_SP01/data/BicepsBrachi"][()].ravel()
    rec = read_recording(path)
    ch = rec.channels["BicepsBrachi"]
    assert ch.rate == 2000.0 and ch.n_samples == 113920  # README
    np.testing.assert_array_equal(ch.data, raw * 1e-6)  # amplitude_units "uV"
    assert rec.metadata["fields"]["EMG_recording_SP01.posture"] == "SP"
    assert not any("implausible" in w for w in rec.metadata["warnings"])


def test_mat_v5_labelled_matrix_and_struct(tmp_path: Path) -> None:
    sio = pytest.importorskip("scipy.io")
    emg = np.column_stack([emg_like(3000, 1000.0, seed=s) for s in range(4)])  # (N, 4) V
    path = tmp_path / "session.mat"
    sio.savemat(
        path,
        {
            "emg": emg,
            "labels": np.array(["Delt_ant", "Triceps", "Biceps", "ECRB"], dtype=object),
            "fs": 1000.0,
            "units": "V",
            "gonio": {"elbow": np.linspace(0, 150, 500), "fs": 100, "units": "deg"},
        },
    )
    rec = read_recording(path)
    assert rec.format == "mat" and rec.metadata["mat_version"] == "5"
    assert {s: c.name for s, c in rec.emg_by_site().items()} == {
        "deltoid": "Delt_ant",
        "triceps": "Triceps",
        "biceps": "Biceps",
        "forearm": "ECRB",
    }
    np.testing.assert_array_equal(rec.channels["ECRB"].data, emg[:, 3])
    assert rec.channels["Biceps"].rate == 1000.0
    elbow = rec.channels["elbow"]
    assert elbow.kind == "angle" and elbow.rate == 100.0
    np.testing.assert_allclose(elbow.data, np.deg2rad(np.linspace(0, 150, 500)))


def _same(mine: object, ref: object) -> None:
    if isinstance(ref, dict):
        assert isinstance(mine, dict) and set(mine) == set(ref)
        for k in ref:
            _same(mine[k], ref[k])
    elif isinstance(ref, list | tuple) or (isinstance(ref, np.ndarray) and ref.dtype.kind in "OU"):
        ref_list = (
            list(np.asarray(ref, dtype=object).ravel()) if isinstance(ref, np.ndarray) else ref
        )
        assert isinstance(mine, list) and len(mine) == len(ref_list)
        for a, b in zip(mine, ref_list, strict=True):
            _same(a, b)
    elif isinstance(ref, str):
        assert mine == ref
    else:
        np.testing.assert_array_equal(
            np.asarray(mine, dtype=np.float64), np.asarray(ref, dtype=np.float64)
        )


@pytest.mark.parametrize("compress", [False, True])
def test_mat5_parser_matches_scipy(tmp_path: Path, compress: bool) -> None:
    sio = pytest.importorskip("scipy.io")
    from app.recordings._mat5 import loadmat5

    rng = np.random.default_rng(3)
    variables = {
        "fs": 2000,
        "emg": rng.standard_normal((50, 3)),
        "i16": np.arange(6, dtype=np.int16).reshape(2, 3),
        "labels": np.array(["Biceps", "Triceps", "Delt"], dtype=object),
        "chars": np.array(["ab", "cd"]),
        "rec": {"data": {"Biceps": np.arange(5.0)}, "sampling_frequency": 1000.0, "unit": "mV"},
        "trials": np.array([{"a": 1.0}, {"a": 2.0}]),
        "cells": np.array([np.arange(3.0), "text"], dtype=object),
    }
    path = tmp_path / "ref.mat"
    sio.savemat(path, variables, do_compression=compress)
    data = path.read_bytes()
    reference = sio.loadmat(path, simplify_cells=True)
    mine = loadmat5(data)
    assert set(mine) == {k for k in reference if not k.startswith("__")}
    for key in mine:
        _same(mine[key], reference[key])


def test_mat5_invalid_data_type_is_an_error_not_a_crash(tmp_path: Path) -> None:
    # scipy.io.loadmat 1.17 segfaults on this single-byte corruption; the reader must not
    sio = pytest.importorskip("scipy.io")
    path = tmp_path / "emg.mat"
    sio.savemat(path, {"emg": np.arange(100.0), "fs": 1000.0})
    data = bytearray(path.read_bytes())
    at = data.index(b"\x09\x00\x00\x00", data.index(b"emg"))  # miDOUBLE tag of the values
    data[at] = 0x42
    with pytest.raises(
        RecordingError, match=r"emg\.mat: MAT v5 content cannot be read: data type 66"
    ):
        read_bytes(bytes(data), "emg.mat")


def test_mat_v5_without_rate_needs_one(tmp_path: Path) -> None:
    sio = pytest.importorskip("scipy.io")
    path = tmp_path / "norate.mat"
    sio.savemat(path, {"biceps": emg_like(2000, 1000.0)})
    with pytest.raises(
        RecordingError, match=r"norate\.mat, channel 'biceps': has no sampling rate"
    ):
        read_recording(path)
    assert read_recording(path, rate=1000).channels["biceps"].rate == 1000.0


def test_mat_v73_written_with_h5py(tmp_path: Path) -> None:
    h5py = pytest.importorskip("h5py")
    biceps = emg_like(3000, 2000.0, seed=7) * 1e6
    path = tmp_path / "v73.mat"
    # MATLAB v7.3 layout: 512-byte text header as HDF5 user block, struct groups, char as uint16,
    # arrays stored with reversed dimensions
    with h5py.File(path, "w", userblock_size=512) as f:
        g = f.create_group("rec")
        g.attrs["MATLAB_class"] = np.bytes_("struct")
        d = g.create_group("data")
        d.attrs["MATLAB_class"] = np.bytes_("struct")
        ds = d.create_dataset("Biceps", data=biceps[None, :])
        ds.attrs["MATLAB_class"] = np.bytes_("double")
        fs = g.create_dataset("sampling_frequency", data=np.array([[2000.0]]))
        fs.attrs["MATLAB_class"] = np.bytes_("double")
        unit = g.create_dataset(
            "amplitude_units", data=np.array([[ord("u")], [ord("V")]], dtype=np.uint16)
        )
        unit.attrs["MATLAB_class"] = np.bytes_("char")
    with path.open("r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: test".ljust(116, b" "))
    rec = read_recording(path)
    ch = rec.channels["Biceps"]
    assert rec.metadata["mat_version"] == "7.3"
    assert ch.site == "biceps" and ch.rate == 2000.0 and ch.unit == "V"
    np.testing.assert_allclose(ch.data, biceps * 1e-6, rtol=1e-15)


def test_edf_255_byte_header_mutated_raises_only_recording_error(shared_data: Path) -> None:
    """The repair reads numbers from a shifted header: any byte of it changed gives a read or
    a RecordingError naming the file, never another exception."""
    data = shared_file(MULTIMODAL).read_bytes()
    rng = np.random.default_rng(29)
    for _ in range(150):
        b = bytearray(data)
        for at in rng.integers(0, 255 + 10 * 256, size=int(rng.integers(1, 4))):
            b[int(at)] = int(rng.integers(0, 256))
        try:
            read_bytes(bytes(b), "sub-01_task-pullstand_emg.edf")
        except RecordingError as exc:
            assert str(exc).startswith("sub-01_task-pullstand_emg.edf"), exc
