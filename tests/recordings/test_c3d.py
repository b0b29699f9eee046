"""C3D reader: against ezc3d on the real files, against the Vicon CSV export, and edge cases."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from app.recordings import RecordingError, read_bytes, read_recording
from app.recordings._c3d import dec_to_ieee
from tests.conftest import shared_file
from tests.recordings._writers import emg_like, write_c3d

PYOMECA = "pyomeca_upperlimb_c3d_emg/markers_analogs.c3d"
BTS = "c3d_bts_gait_emg/BTS.c3d"
_TO_VOLT = {"V": 1.0, "mV": 1e-3, "uV": 1e-6}


@pytest.mark.parametrize("relative", [PYOMECA, BTS])
def test_c3d_matches_ezc3d(shared_data: Path, relative: str) -> None:
    ezc3d = pytest.importorskip("ezc3d")
    path = shared_file(relative)
    ref = ezc3d.c3d(str(path))
    rec = read_recording(path)

    labels = ref["parameters"]["ANALOG"]["LABELS"]["value"]
    units = ref["parameters"]["ANALOG"]["UNITS"]["value"]
    analogs = ref["data"]["analogs"][0]
    for i, label in enumerate(labels):
        ch = rec.channels[label]
        factor = _TO_VOLT[units[i]] if ch.kind == "emg" else 1.0
        np.testing.assert_allclose(ch.data, analogs[i] * factor, rtol=0, atol=1e-12)
        assert ch.rate == ref["header"]["analogs"]["frame_rate"]
    points = ref["data"]["points"]
    for i, label in enumerate(ref["parameters"]["POINT"]["LABELS"]["value"]):
        ch = rec.channels[label]
        assert ch.kind == "marker" and ch.unit == "m"
        np.testing.assert_allclose(ch.data, points[:3, i, :].T / 1000.0, rtol=0, atol=1e-12)
        assert ch.confidence is not None
        np.testing.assert_array_equal(ch.confidence == 0, np.isnan(points[0, i, :]))


def test_pyomeca_c3d_content(shared_data: Path) -> None:
    rec = read_recording(shared_file(PYOMECA))
    markers = rec.of_kind("marker")
    # README: 51 markers @ 100 Hz, 580 frames, 305 of 29580 samples invalid; 38 analogs @ 2 kHz
    assert len(markers) == 51 and {m.data.shape for m in markers} == {(580, 3)}
    assert {m.rate for m in markers} == {100.0}
    assert sum(int((m.confidence == 0).sum()) for m in markers if m.confidence is not None) == 305
    analogs = [c for c in rec.channels.values() if c.kind != "marker"]
    assert len(analogs) == 38 and {c.n_samples for c in analogs} == {11600}
    sites = {s: c.name for s, c in rec.emg_by_site().items()}
    assert sites == {"deltoid": "Delt_ant.EMG1", "biceps": "Biceps.EMG4", "triceps": "Triceps.EMG5"}
    # README: the elbow included angle ACRO_tip - mid(EPICl, EPICm) - mid(STYLr, STYLu)
    # spans 42..155 deg over the trial
    ch = {n.split(":")[-1]: c.data for n, c in rec.channels.items() if c.kind == "marker"}
    elbow = (ch["EPICl"] + ch["EPICm"]) / 2
    wrist = (ch["STYLr"] + ch["STYLu"]) / 2
    u, v = ch["ACRO_tip"] - elbow, wrist - elbow
    cos = np.sum(u * v, axis=1) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)
    angle = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    assert np.nanmin(angle) == pytest.approx(42, abs=1) and np.nanmax(angle) == pytest.approx(
        155, abs=1
    )


def test_muscle_map_moves_a_site_to_another_channel(shared_data: Path) -> None:
    path = shared_file(PYOMECA)
    rec = read_recording(path, muscle_map={"Delt_med.EMG2": "deltoid", "Infra.EMG10": "forearm"})
    sites = {s: c.name for s, c in rec.emg_by_site().items()}
    assert sites["deltoid"] == "Delt_med.EMG2" and sites["forearm"] == "Infra.EMG10"
    assert rec.channels["Delt_ant.EMG1"].site is None
    assert rec.channels["Delt_post.EMG3"].site is None


def test_c3d_and_its_csv_export_give_the_same_emg(shared_data: Path) -> None:
    c3d = read_recording(shared_file(PYOMECA))
    csv = read_recording(shared_file("pyomeca_upperlimb_c3d_emg/analogs.csv"))
    compared = 0
    for name, ch in csv.channels.items():
        # CSV "EMG4" is C3D "Biceps.EMG4"; "Voltage.1" is named alike in both
        match = [c for n, c in c3d.channels.items() if n == name or n.split(".", 1)[-1] == name]
        assert len(match) == 1, name
        other = match[0]
        assert other.kind == ch.kind and other.unit == ch.unit == "V"
        np.testing.assert_allclose(ch.data, other.data, rtol=0, atol=1e-6)
        compared += 1
    assert compared == 38
    assert np.max(np.abs(csv.channels["EMG4"].data - c3d.channels["Biceps.EMG4"].data)) < 1e-7


def test_bts_leg_emg_in_millivolts(shared_data: Path) -> None:
    rec = read_recording(shared_file(BTS))
    emg = rec.of_kind("emg")
    # README: channels 37-44 are leg EMG in mV, range -0.70..0.66 mV; force plates are N / Nmm
    assert [c.name for c in emg] == [
        "Left Rectus femoris",
        "Right Rectus femoris",
        "Left Semimembranosus",
        "Right Semimembranosus",
        "Left Tibialis anterior",
        "Right Tibialis anterior",
        "Left Gastrocnemius medialis",
        "Right Gastrocnemius medialis",
    ]
    assert {c.rate for c in emg} == {1000.0} and {c.n_samples for c in emg} == {6750}
    lo = min(float(c.data.min()) for c in emg)
    hi = max(float(c.data.max()) for c in emg)
    assert lo == pytest.approx(-0.70e-3, abs=0.01e-3) and hi == pytest.approx(0.66e-3, abs=0.01e-3)
    assert all(c.site is None for c in emg)  # leg muscles are none of the four arm sites
    assert rec.channels["Fz1"].unit == "N" and rec.channels["Mx1"].unit == "Nmm"
    assert len(rec.of_kind("marker")) == 22


def test_c3d_written_by_ezc3d(tmp_path: Path) -> None:
    pytest.importorskip("ezc3d")
    n_frames = 120
    points = np.stack(
        [
            np.full((2, n_frames), 100.0),
            np.linspace(0, 500, n_frames)[None].repeat(2, 0),
            np.full((2, n_frames), 900.0),
        ]
    )
    residuals = np.zeros((2, n_frames))
    residuals[1, 30:35] = -1.0
    emg = np.stack([emg_like(n_frames * 10, 1000.0, seed=s) * 1e3 for s in (1, 2)])  # mV
    path = tmp_path / "curl.c3d"
    write_c3d(
        path,
        points=points,
        point_labels=["RELB", "RWRA"],
        analogs=emg,
        analog_labels=["BIC", "TRI"],
        analog_units=["mV", "mV"],
        residuals=residuals,
    )

    rec = read_recording(path)

    np.testing.assert_allclose(rec.channels["BIC"].data, emg[0] * 1e-3, rtol=1e-6, atol=1e-12)
    assert rec.channels["BIC"].site == "biceps" and rec.channels["TRI"].site == "triceps"
    wrist = rec.channels["RWRA"]
    assert np.isnan(wrist.data[30:35]).all() and np.isfinite(wrist.data[:30]).all()
    np.testing.assert_allclose(wrist.data[:30, 1], np.linspace(0, 0.5, n_frames)[:30], atol=1e-6)
    assert wrist.confidence is not None and wrist.confidence[30:35].sum() == 0


def test_c3d_model_output_angles_are_angles(tmp_path: Path) -> None:
    ezc3d = pytest.importorskip("ezc3d")
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100]
    c["parameters"]["POINT"]["LABELS"]["value"] = ("RELB", "RElbowAngles")
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    c.add_parameter("POINT", "ANGLES", ["RElbowAngles"])
    c.add_parameter("POINT", "ANGLE_UNITS", ["deg"])
    points = np.ones((4, 2, 20))
    points[0, 1] = np.linspace(0.0, 90.0, 20)
    c["data"]["points"] = points
    c["parameters"]["ANALOG"]["RATE"]["value"] = [1000]
    c["parameters"]["ANALOG"]["LABELS"]["value"] = ("BIC",)
    c["parameters"]["ANALOG"]["UNITS"]["value"] = ["V"]
    c["data"]["analogs"] = emg_like(200, 1000.0)[None, None, :]
    path = tmp_path / "angles.c3d"
    c.write(str(path))
    rec = read_recording(path)
    elbow = rec.channels["RElbowAngles.X"]
    assert elbow.kind == "angle" and elbow.unit == "rad" and "RElbowAngles" not in rec.channels
    np.testing.assert_allclose(elbow.data, np.deg2rad(np.linspace(0.0, 90.0, 20)), atol=1e-6)
    assert rec.channels["RELB"].kind == "marker"


def test_c3d_without_analog_data_is_rejected(tmp_path: Path) -> None:
    pytest.importorskip("ezc3d")
    path = tmp_path / "markers_only.c3d"
    write_c3d(path, points=np.ones((3, 1, 20)), point_labels=["A"])
    with pytest.raises(RecordingError, match=r"markers_only\.c3d: has no analog data"):
        read_recording(path)


def test_truncated_c3d(shared_data: Path) -> None:
    data = shared_file(PYOMECA).read_bytes()
    with pytest.raises(RecordingError, match=r"cut\.c3d: truncated in the data section"):
        read_bytes(data[: len(data) // 2], "cut.c3d")
    with pytest.raises(RecordingError, match=r"head\.c3d: .*(512|truncated)"):
        read_bytes(data[:300], "head.c3d", format="c3d")


def test_dec_float_conversion() -> None:
    # VAX F floating point: 1.0 is stored as the bytes 80 40 00 00, -2.5 as 20 C1 00 00
    raw = bytes([0x80, 0x40, 0, 0, 0x20, 0xC1, 0, 0])
    np.testing.assert_array_equal(dec_to_ieee(raw, 2), [1.0, -2.5])
    # and an IEEE value read through the DEC path comes out 1/4 with its words swapped back
    ieee = struct.pack("<f", 8.0)
    swapped = ieee[2:] + ieee[:2]
    assert dec_to_ieee(swapped, 1)[0] == 2.0


def _fuzzed(data: bytes, rng: np.random.Generator) -> bytes:
    """Up to 30 random bytes changed in the header and parameter section."""
    out = bytearray(data)
    for _ in range(int(rng.integers(1, 30))):
        out[int(rng.integers(0, min(len(out), 8192)))] = int(rng.integers(0, 256))
    return bytes(out)


def test_fuzzed_c3d_errors_are_one_printable_line(shared_data: Path, tmp_path: Path) -> None:
    """Issue 14: fuzzed C3D files gave multi-line errors, the bytes of the next parameters
    quoted as a "name". Every refusal of 200 fuzzed files is one short printable line, in the
    library and on the CLI's stderr."""
    import subprocess
    import sys

    data = shared_file(PYOMECA).read_bytes()
    rng = np.random.default_rng(1)
    worst = ""
    for _ in range(200):
        fuzzed = _fuzzed(data, rng)
        try:
            read_bytes(fuzzed, "x.c3d")
        except RecordingError as exc:
            text = str(exc)
            assert text.isprintable() and len(text) < 1000, repr(text)
            if len(text) > len(worst):
                worst, worst_bytes = text, fuzzed
    assert worst, "no fuzzed file was refused"
    (tmp_path / "fuzzed.c3d").write_bytes(worst_bytes)
    proc = subprocess.run(
        [sys.executable, "-m", "app.cli", "analyze", str(tmp_path / "fuzzed.c3d")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 2
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("bioplan analyze: error: "), proc.stderr
    assert lines[0].isprintable()
