"""XDF (Lab Streaming Layer) recordings: EMG and motion-capture streams with clock offsets.

pyxdf has no writer, so the file is written here chunk by chunk as the XDF 1.0 specification
lays it out (https://github.com/sccn/xdf/wiki/Specifications): the magic ``XDF:``, then chunks
of [length-size byte][length][tag uint16][content]: FileHeader (1), StreamHeader (2), Samples
(3), ClockOffset (4), StreamFooter (6). The file is read back by pyxdf itself (the reference)
and by BioPlan, and the two are compared.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from app.analysis.pose import arm_angles
from app.recordings import read_bytes, read_recording, sniff_format
from tests.recordings._writers import emg_like

pyxdf = pytest.importorskip("pyxdf", reason="pyxdf reads XDF files")


def _varlen(n: int) -> bytes:
    if n < 256:
        return struct.pack("<BB", 1, n)
    if n < 2**32:
        return struct.pack("<BI", 4, n)
    return struct.pack("<BQ", 8, n)


def _chunk(tag: int, content: bytes) -> bytes:
    return _varlen(len(content) + 2) + struct.pack("<H", tag) + content


def _header_xml(sid: int, name: str, stype: str, rate: float, channels: list[dict[str, str]]):
    desc = "".join(
        "<channel>" + "".join(f"<{k}>{v}</{k}>" for k, v in ch.items()) + "</channel>"
        for ch in channels
    )
    return (
        '<?xml version="1.0"?><info>'
        f"<name>{name}</name><type>{stype}</type><channel_count>{len(channels)}</channel_count>"
        f"<nominal_srate>{rate:g}</nominal_srate><channel_format>float32</channel_format>"
        f"<source_id>src{sid}</source_id><version>1.1</version><created_at>100.0</created_at>"
        f"<uid>uid-{sid}</uid><session_id>default</session_id><hostname>lab-pc{sid}</hostname>"
        f"<desc><channels>{desc}</channels></desc></info>"
    ).encode()


def _samples(sid: int, stamps: np.ndarray, values: np.ndarray) -> bytes:
    body = bytearray(struct.pack("<I", sid))
    body += _varlen(len(stamps))
    for t, row in zip(stamps, values, strict=True):
        body += struct.pack("<Bd", 8, float(t))
        body += np.asarray(row, dtype="<f4").tobytes()
    return _chunk(3, bytes(body))


def _clock_offsets(sid: int, offset: float, times: np.ndarray) -> bytes:
    return b"".join(_chunk(4, struct.pack("<Idd", sid, float(t), offset)) for t in times)


def _footer(sid: int, stamps: np.ndarray, count: int) -> bytes:
    xml = (
        '<?xml version="1.0"?><info>'
        f"<first_timestamp>{stamps[0]:.9f}</first_timestamp>"
        f"<last_timestamp>{stamps[-1]:.9f}</last_timestamp>"
        f"<sample_count>{count}</sample_count></info>"
    )
    return _chunk(6, struct.pack("<I", sid) + xml.encode())


EMG_RATE, MOCAP_RATE = 1000.0, 100.0
EMG_OFFSET, MOCAP_OFFSET = 0.5, -2.0  # remote clock + offset = recorder clock [s]


def _write_xdf(path: Path) -> dict[str, np.ndarray]:
    """Two streams from two computers: 2 EMG channels (uV) and 3 markers (mm)."""
    n_emg, n_mocap = 4000, 400
    emg = np.column_stack([emg_like(n_emg, EMG_RATE, seed=21), emg_like(n_emg, EMG_RATE, seed=22)])
    emg_uv = (emg * 1e6).astype(np.float32)
    emg_t = 1000.0 + np.arange(n_emg) / EMG_RATE  # EMG amplifier's LSL clock
    t = np.arange(n_mocap) / MOCAP_RATE
    q2 = np.deg2rad(10.0) + np.deg2rad(130.0) * (1 - np.cos(np.pi * t)) / 2
    shoulder = np.tile([200.0, 0.0, 1400.0], (n_mocap, 1))
    elbow = shoulder + np.array([0.0, 0.0, -300.0])
    wrist = elbow + 300.0 * np.column_stack([np.sin(q2), 0 * t, -np.cos(q2)])
    mocap = np.column_stack([shoulder, elbow, wrist]).astype(np.float32)
    mocap_t = 1003.0 + t  # the mocap computer's clock
    emg_ch = [
        {"label": "Biceps", "unit": "microvolts", "type": "EMG"},
        {"label": "Triceps", "unit": "microvolts", "type": "EMG"},
    ]
    mocap_ch = [
        {"label": f"{m}_{a}", "marker": m, "type": f"Position{a}", "unit": "millimeters"}
        for m in ("RSHO", "RELB", "RWRA")
        for a in "XYZ"
    ]
    out = bytearray(b"XDF:")
    out += _chunk(1, b'<?xml version="1.0"?><info><version>1.0</version></info>')
    out += _chunk(2, struct.pack("<I", 1) + _header_xml(1, "Trigno", "EMG", EMG_RATE, emg_ch))
    out += _chunk(2, struct.pack("<I", 2) + _header_xml(2, "Qualisys", "MoCap", 100, mocap_ch))
    for k in range(0, n_emg, 1000):  # interleaved chunks, as LabRecorder writes them
        out += _samples(1, emg_t[k : k + 1000], emg_uv[k : k + 1000])
        j = k // 10
        out += _samples(2, mocap_t[j : j + 100], mocap[j : j + 100])
    out += _clock_offsets(1, EMG_OFFSET, np.arange(1000.0, 1005.0, 1.0))
    out += _clock_offsets(2, MOCAP_OFFSET, np.arange(1003.0, 1008.0, 1.0))
    out += _footer(1, emg_t, n_emg) + _footer(2, mocap_t, n_mocap)
    path.write_bytes(bytes(out))
    return {"emg_uv": emg_uv, "emg_t": emg_t, "mocap": mocap, "mocap_t": mocap_t, "q2": q2}


def test_xdf_emg_and_mocap_on_the_recorders_clock(tmp_path: Path) -> None:
    path = tmp_path / "curl.xdf"
    written = _write_xdf(path)
    # the reference: pyxdf itself, clock offsets applied
    streams, _ = pyxdf.load_xdf(str(path), synchronize_clocks=True)
    by_name = {s["info"]["name"][0]: s for s in streams}
    ref_emg, ref_mocap = by_name["Trigno"], by_name["Qualisys"]
    np.testing.assert_allclose(ref_emg["time_stamps"][0], 1000.0 + EMG_OFFSET, atol=1e-6)
    np.testing.assert_allclose(ref_mocap["time_stamps"][0], 1003.0 + MOCAP_OFFSET, atol=1e-6)

    assert sniff_format(path) == "xdf"
    rec = read_recording(path)
    assert rec.format == "xdf"
    t0 = min(ref_emg["time_stamps"][0], ref_mocap["time_stamps"][0])  # 1000.5 (EMG)
    assert rec.metadata["lsl_time_zero"] == pytest.approx(t0)
    assert "ClockOffset" in rec.metadata["clock"]
    biceps = rec.channels["Biceps"]
    assert biceps.kind == "emg" and biceps.site == "biceps" and biceps.unit == "V"
    assert biceps.rate == EMG_RATE and biceps.start == pytest.approx(0.0)
    np.testing.assert_allclose(biceps.data, ref_emg["time_series"][:, 0] * 1e-6, rtol=1e-6)
    np.testing.assert_allclose(biceps.data, written["emg_uv"][:, 0] * 1e-6, rtol=1e-6)
    assert rec.channels["Triceps"].site == "triceps"
    wrist = rec.channels["RWRA"]
    assert wrist.kind == "marker" and wrist.unit == "m" and wrist.rate == MOCAP_RATE
    # mocap started at 1001.0 on the recorder's clock, 0.5 s after the EMG
    assert wrist.start == pytest.approx(ref_mocap["time_stamps"][0] - t0, abs=1e-6)
    assert wrist.start == pytest.approx(0.5, abs=1e-6)
    np.testing.assert_allclose(wrist.data * 1000.0, ref_mocap["time_series"][:, 6:9], rtol=1e-6)
    arm = arm_angles(rec, landmarks="plugin_gait_right", lowpass=None)
    ok = arm.valid
    np.testing.assert_allclose(arm.elbow[ok], written["q2"][ok], atol=1e-4)
    assert [s["name"] for s in rec.metadata["streams"]] == ["Trigno", "Qualisys"]
    # bytes (an upload) read the same
    same = read_bytes(path.read_bytes(), "curl.xdf")
    np.testing.assert_array_equal(same.channels["RELB"].data, rec.channels["RELB"].data)


def test_xdf_without_streams_is_a_clear_error(tmp_path: Path) -> None:
    from app.recordings import RecordingError

    path = tmp_path / "empty.xdf"
    path.write_bytes(
        b"XDF:" + _chunk(1, b'<?xml version="1.0"?><info><version>1.0</version></info>')
    )
    with pytest.raises(RecordingError, match=r"empty\.xdf: .*(no stream|cannot be read)"):
        read_recording(path)
