"""Generic CSV/TSV, Noraxon MR3 CSV and Vicon Nexus CSV readers."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np
import pytest

from app.recordings import RecordingError, read_bytes, read_recording
from tests.conftest import shared_file
from tests.recordings._writers import emg_like, write_vicon_csv

NORAXON = "noraxon_curls_biceps_brachioradialis/2023-04-20-15-06_BR_posredni.csv"
NORAXON_2 = "noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv"


def _write(tmp_path: Path, name: str, text: str, *, bom: bool = False, crlf: bool = False) -> Path:
    if crlf:
        text = text.replace("\n", "\r\n")
    data = text.encode("utf-8")
    path = tmp_path / name
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + data)
    return path


def _table(rate: float, n: int = 400) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(n) / rate
    return t, emg_like(n, rate, seed=3) * 1e6, np.linspace(0.0, 120.0, n)


@pytest.mark.parametrize(
    ("delimiter", "decimal", "bom", "crlf"),
    [
        (",", ".", False, False),
        (";", ",", True, True),
        ("\t", ".", True, False),
        ("|", ".", False, True),
        ("\t", ",", False, False),
    ],
)
def test_generic_csv_dialects(
    tmp_path: Path, delimiter: str, decimal: str, bom: bool, crlf: bool
) -> None:
    t, biceps_uv, elbow_deg = _table(1000.0)
    lines = ["# exported by a test", f"time (s){delimiter}biceps (uV){delimiter}elbow angle (deg)"]
    for row in zip(t, biceps_uv, elbow_deg, strict=True):
        lines.append(delimiter.join(f"{v:.6f}".replace(".", decimal) for v in row))
    path = _write(tmp_path, "rec.csv", "\n".join(lines) + "\n", bom=bom, crlf=crlf)

    rec = read_recording(path)

    assert rec.format == "csv"
    assert rec.metadata["delimiter"] == delimiter and rec.metadata["decimal"] == decimal
    biceps, elbow = rec.channels["biceps"], rec.channels["elbow angle"]
    assert biceps.kind == "emg" and biceps.site == "biceps" and biceps.unit == "V"
    assert biceps.rate == pytest.approx(1000.0) and biceps.time is None
    np.testing.assert_allclose(biceps.data, np.round(biceps_uv, 6) * 1e-6, atol=1e-12)
    assert elbow.kind == "angle" and elbow.unit == "rad"
    np.testing.assert_allclose(elbow.data, np.deg2rad(np.round(elbow_deg, 6)), atol=1e-9)


def test_generic_csv_with_units_row_and_metadata_rows(tmp_path: Path) -> None:
    _, biceps_uv, elbow_deg = _table(2000.0, n=1000)
    lines = ["Subject,S01,,", "Task,curl 12 kg,,", "", "Time,Biceps,Elbow,Marker", "ms,uV,deg,"]
    for i, (b, e) in enumerate(zip(biceps_uv, elbow_deg, strict=True)):
        lines.append(f"{i * 0.5:.1f},{b:.4f},{e:.4f},{'x' if i == 10 else ''}")
    rec = read_recording(_write(tmp_path, "units.csv", "\n".join(lines) + "\n"))
    biceps = rec.channels["Biceps"]
    assert biceps.rate == 2000.0 and biceps.site == "biceps" and biceps.unit == "V"
    np.testing.assert_allclose(biceps.data, np.round(biceps_uv, 4) * 1e-6, atol=1e-12)
    np.testing.assert_allclose(rec.channels["Elbow"].data, np.deg2rad(np.round(elbow_deg, 4)))
    assert rec.metadata["ignored_columns"] == ["Marker"]


def test_generic_csv_without_time_needs_rate(tmp_path: Path) -> None:
    _, biceps_uv, _ = _table(500.0)
    text = "biceps_uV,triceps_uV\n" + "".join(f"{b:.4f},{-b:.4f}\n" for b in biceps_uv)
    path = _write(tmp_path, "norate.csv", text)
    with pytest.raises(RecordingError, match=r"norate\.csv.*no time column and no sampling rate"):
        read_recording(path)
    rec = read_recording(path, rate=500.0)
    assert rec.channels["biceps_uV"].rate == 500.0
    assert rec.channels["triceps_uV"].site == "triceps"
    np.testing.assert_allclose(
        rec.channels["biceps_uV"].data, np.round(biceps_uv, 4) * 1e-6, atol=1e-12
    )


def test_generic_csv_irregular_time_keeps_times(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.005, 0.015, 300))
    text = "timestamp_ms,shoulder_flexion_deg\n" + "".join(
        f"{1000 * a:.3f},{30 + 10 * math.sin(a):.5f}\n" for a in t
    )
    rec = read_recording(_write(tmp_path, "irregular.csv", text))
    ch = rec.channels["shoulder_flexion_deg"]
    assert ch.time is not None
    np.testing.assert_allclose(ch.time, np.round(t * 1000, 3) / 1000, atol=1e-9)
    assert ch.kind == "angle"
    np.testing.assert_allclose(ch.data, np.deg2rad(30 + 10 * np.sin(t)), atol=1e-6)


def test_emg_without_unit_is_guessed_and_warned(tmp_path: Path) -> None:
    _, biceps_uv, _ = _table(1000.0, n=2000)
    text = "time,biceps\n" + "".join(
        f"{i / 1000:.3f},{b / 1000:.6f}\n" for i, b in enumerate(biceps_uv)
    )
    rec = read_recording(_write(tmp_path, "mv.csv", text))
    np.testing.assert_allclose(
        rec.channels["biceps"].data, np.round(biceps_uv / 1000, 6) * 1e-3, atol=1e-12
    )
    assert any("assumed mV" in w for w in rec.metadata["warnings"])


def test_biosppy_text_format(shared_data: Path) -> None:
    path = shared_file("biosppy_emg_examples/emg_1.txt")
    reference = np.loadtxt(path, comments="#")
    rec = read_recording(path)
    ch = rec.channels["EMG"]
    assert rec.format == "csv" and ch.kind == "emg" and ch.unit == "counts"
    assert ch.rate == 1000.0 and ch.n_samples == 63880 == reference.size
    # README: 12-bit counts; the reader removes the 2048 mid-scale offset
    np.testing.assert_array_equal(ch.data, reference - 2048)
    assert rec.metadata["adc_resolution_bits"] == 12


# ---------------------------------------------------------------------------------------------
# Noraxon


def _noraxon_reference(path: Path) -> tuple[list[float], list[float], dict[str, str]]:
    text = path.read_text(encoding="utf-8-sig")
    rows = list(csv.reader(io.StringIO(text), delimiter=";"))
    meta = dict(zip(rows[0], rows[1], strict=True))
    data = [r for r in rows[4:] if r]
    t = [float(r[0].replace(",", ".")) for r in data]
    emg = [float(r[3].replace(",", ".")) for r in data]
    return t, emg, meta


@pytest.mark.parametrize(("relative", "rows"), [(NORAXON, 33280), (NORAXON_2, 24600)])
def test_noraxon_real_files(shared_data: Path, relative: str, rows: int) -> None:
    path = shared_file(relative)
    t, emg_uv, meta = _noraxon_reference(path)

    rec = read_recording(path)

    assert rec.format == "noraxon_csv"
    assert list(rec.channels) == ["BRACHIORAD. LT"]
    ch = rec.channels["BRACHIORAD. LT"]
    assert ch.kind == "emg" and ch.site == "forearm" and ch.unit == "V"
    assert ch.n_samples == rows == len(t) == int(meta["count"])
    assert ch.rate == 2000.0 == float(meta["frequency"])  # README: dt 0.5 ms
    assert ch.duration == pytest.approx(rows / 2000.0)
    np.testing.assert_allclose(ch.data, np.array(emg_uv) * 1e-6, rtol=0, atol=1e-15)
    assert rec.metadata["stored_rate"] == 2000.0
    assert rec.metadata["declared_rows"] == rec.metadata["actual_rows"] == rows
    assert rec.metadata["device"].startswith("Noraxon MR3")
    assert rec.metadata["annotation_columns"] == ["Activity", "Marker"]


def test_noraxon_muscle_map_override(shared_data: Path) -> None:
    path = shared_file(NORAXON)
    rec = read_recording(path, muscle_map={"BRACHIORAD. LT (uV)": "none"})
    assert rec.channels["BRACHIORAD. LT"].site is None
    rec = read_recording(path, muscle_map={"brachiorad. lt": "biceps"})
    assert rec.emg_by_site()["biceps"].name == "BRACHIORAD. LT"


def test_noraxon_synthetic_two_channels(tmp_path: Path) -> None:
    rate = 1500.0
    n = 3000
    biceps = emg_like(n, rate, seed=4) * 1e6
    triceps = emg_like(n, rate, seed=5) * 1e6
    head = '"type";"frequency";"count"\n"record";"1500";"3000"\n\n'
    head += '"time";"Activity";"BICEPS BR. RT (uV)";"TRICEPS RT (uV)"\n'
    body = "".join(
        f'{i / rate:.5f};"";{b:.6f};{c:.6f}\n'.replace(".", ",")
        for i, (b, c) in enumerate(zip(biceps, triceps, strict=True))
    )
    rec = read_bytes((b"\xef\xbb\xbf" + (head + body).encode()), "upload.csv")
    assert rec.format == "noraxon_csv"
    assert {c.site for c in rec.channels.values()} == {"biceps", "triceps"}
    assert rec.channels["BICEPS BR. RT"].rate == pytest.approx(1500.0, rel=1e-6)
    np.testing.assert_allclose(
        rec.channels["TRICEPS RT"].data, np.round(triceps, 6) * 1e-6, atol=1e-13
    )


# ---------------------------------------------------------------------------------------------
# Vicon


def test_vicon_synthetic_sections(tmp_path: Path) -> None:
    path = tmp_path / "trial.csv"
    expected = write_vicon_csv(path)

    rec = read_recording(path)

    assert rec.format == "vicon_csv"
    assert set(rec.channels) == set(expected)
    for name in ("Biceps", "Triceps"):
        ch = rec.channels[name]
        assert ch.kind == "emg" and ch.unit == "V" and ch.rate == 1000.0
        np.testing.assert_allclose(ch.data, expected[name], rtol=1e-8, atol=1e-15)
    assert rec.channels["Biceps"].site == "biceps"
    np.testing.assert_allclose(rec.channels["Plate 2.Fz"].data, expected["Plate 2.Fz"], atol=1e-6)
    relb, rwra = rec.channels["Subj:RELB"], rec.channels["Subj:RWRA"]
    assert relb.kind == "marker" and relb.unit == "m" and relb.data.shape == (50, 3)
    assert relb.rate == 100.0
    np.testing.assert_allclose(rwra.data, expected["Subj:RWRA"], atol=1e-9)
    assert rwra.confidence is not None
    np.testing.assert_array_equal(rwra.confidence[9:14], [1, 0, 0, 0, 1])
    elbow = rec.channels["Subj:RElbowAngles.X"]
    assert elbow.kind == "angle" and elbow.unit == "rad" and elbow.rate == 100.0
    np.testing.assert_allclose(elbow.data, expected["Subj:RElbowAngles.X"], atol=1e-7)
    assert set(rec.metadata["sections"]) == {"Devices", "Trajectories", "Model Outputs"}
    # Devices (1 kHz) and Trajectories (100 Hz) share one clock and one duration
    assert rec.channels["Biceps"].duration == pytest.approx(relb.duration)


def test_vicon_real_devices_csv(shared_data: Path) -> None:
    path = shared_file("pyomeca_upperlimb_c3d_emg/analogs.csv")
    rec = read_recording(path)
    assert rec.format == "vicon_csv"
    # README: 5 header rows, data (11600, 40) = Frame, Sub Frame + 38 channels at 2000 Hz in V
    assert len(rec.channels) == 38
    assert {c.rate for c in rec.channels.values()} == {2000.0}
    assert {c.n_samples for c in rec.channels.values()} == {11600}
    emg = [c for c in rec.channels.values() if c.kind == "emg"]
    assert len(emg) == 32 and {c.unit for c in emg} == {"V"}
    # muscle names are absent from the CSV, so nothing is mapped without a muscle_map
    assert rec.emg_by_site() == {}
    rec = read_recording(path, muscle_map={"EMG4": "biceps", "EMG5": "triceps", "EMG1": "deltoid"})
    assert {s: c.name for s, c in rec.emg_by_site().items()} == {
        "biceps": "EMG4",
        "triceps": "EMG5",
        "deltoid": "EMG1",
    }
    # unused channels are exact zeros: reported, not fatal
    assert any("constant channel" in w and "'EMG12'" in w for w in rec.metadata["warnings"])
