"""Bad input: every case gives a RecordingError naming the file and the line or channel."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from app.recordings import RecordingError, read_bytes, read_recording
from app.recordings._common import emg_median_frequency, suggest_emg_rate
from tests.recordings._writers import emg_like, write_edf


def _emg_csv(n: int = 200, *, rate: float = 1000.0, delimiter: str = ",") -> list[str]:
    x = emg_like(max(n, 64), rate, seed=5)[:n] * 1e6
    y = emg_like(max(n, 64), rate, seed=6)[:n] * 1e6
    head = delimiter.join(["time", "biceps (uV)", "triceps (uV)"])
    return [head] + [
        delimiter.join([f"{i / rate:.4f}", f"{a:.3f}", f"{b:.3f}"])
        for i, (a, b) in enumerate(zip(x, y, strict=True))
    ]


def _replace(lines: list[str], line: int, column: int, value: str) -> list[str]:
    out = list(lines)
    fields = out[line - 1].split(",")
    fields[column] = value
    out[line - 1] = ",".join(fields)
    return out


CASES: dict[str, tuple[Callable[[], bytes], dict[str, object], str, int | None, str | None]] = {
    # name: (content, options, message pattern, line, channel)
    "empty file": (lambda: b"", {}, "file is empty", None, None),
    "only whitespace": (lambda: b" \r\n\r\n ", {}, "file is empty", None, None),
    "wrong delimiter": (
        lambda: "\n".join([_emg_csv()[0]] + [r.replace(",", ";") for r in _emg_csv()[1:]]).encode(),
        {},
        "header has 1 field",
        1,
        None,
    ),
    "text early in a numeric column": (
        lambda: "\n".join(_replace(_emg_csv(), 3, 1, "oops")).encode(),
        {},
        "text 'oops' in a numeric column",
        3,
        "biceps (uV)",
    ),
    "text late in a numeric column": (
        lambda: "\n".join(_replace(_emg_csv(20000), 15000, 2, "n/a?")).encode(),
        {},
        "text 'n/a\\?' in a numeric column",
        15000,
        "triceps (uV)",
    ),
    "NaN in an EMG column": (
        lambda: "\n".join(_replace(_emg_csv(), 120, 1, "NaN")).encode(),
        {},
        "missing or not a number",
        120,
        "biceps",
    ),
    "empty cell in an EMG column": (
        lambda: "\n".join(_replace(_emg_csv(), 57, 2, "")).encode(),
        {},
        "missing or not a number",
        57,
        "triceps",
    ),
    "ragged row": (
        lambda: "\n".join([*_emg_csv()[:40], "0.5,1.0", *_emg_csv()[41:]]).encode(),
        {},
        "row has 2 field",
        41,
        None,
    ),
    "a single sample": (lambda: "\n".join(_emg_csv(1)).encode(), {}, "1 data row", 2, None),
    "time going backwards": (
        lambda: "\n".join(_replace(_emg_csv(), 80, 0, "0.0010")).encode(),
        {},
        "expected strictly increasing time",
        80,
        "time",
    ),
    "constant channel the user maps to a site": (
        lambda: "\n".join(
            [r if i == 0 else ",".join([*r.split(",")[:2], "0"]) for i, r in enumerate(_emg_csv())]
        ).encode(),
        {"muscle_map": {"triceps": "triceps"}},
        "is constant .* mapped to the triceps site",
        None,
        "triceps",
    ),
    "every channel constant": (
        lambda: ("time,a,b\n" + "".join(f"{i / 100},1,2\n" for i in range(50))).encode(),
        {},
        "as is every channel",
        None,
        "a",
    ),
    "sampling rate missing": (
        lambda: (
            "biceps,triceps\n" + "".join(f"{np.sin(i)},{np.cos(i)}\n" for i in range(50))
        ).encode(),
        {},
        "no time column and no sampling rate",
        None,
        None,
    ),
    "sampling rate zero in header": (
        lambda: (
            "# Sampling Rate: 0\nbiceps\n" + "".join(f"{np.sin(i)}\n" for i in range(50))
        ).encode(),
        {},
        "stated sampling rate is 0",
        None,
        None,
    ),
    "absurd rate from the time column": (
        lambda: (
            "time,biceps\n" + "".join(f"{i * 1e-7:.7f},{np.sin(i)}\n" for i in range(50))
        ).encode(),
        {},
        "1e\\+07 Hz is absurd",
        None,
        "time",
    ),
    "zero rate option": (
        lambda: "\n".join(_emg_csv()).encode(),
        {"rate": 0},
        "rate option is 0",
        None,
        None,
    ),
    "absurd emg_rate option": (
        lambda: "\n".join(_emg_csv()).encode(),
        {"emg_rate": 1e7},
        "emg_rate option 1e\\+07 Hz is absurd",
        None,
        None,
    ),
    "NaN rate option": (
        lambda: "\n".join(_emg_csv()).encode(),
        {"frame_rate": float("nan")},
        "frame_rate option is nan",
        None,
        None,
    ),
    "pose JSON without arm landmarks": (
        lambda: json.dumps(
            [{"timestamp_ms": i * 33, "pose_landmarks": [[{"x": 0.5, "y": 0.5}]]} for i in range(5)]
        ).encode(),
        {},
        "has no arm landmarks",
        None,
        None,
    ),
    "broken JSON": (
        lambda: b'[{"timestamp_ms": 1, "pose_landmarks": [',
        {},
        "is not valid JSON",
        1,
        None,
    ),
    "unknown format option": (
        lambda: b"time,a\n0,1\n1,2\n",
        {"format": "xls"},
        "unknown format 'xls'",
        None,
        None,
    ),
    "bad image size": (lambda: b"x", {"image_size": (0, 720)}, "image_size", None, None),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_names_file_and_place(case: str) -> None:
    make, options, pattern, line, channel = CASES[case]
    with pytest.raises(RecordingError, match=pattern) as err:
        read_bytes(make(), "user-upload.csv", name="my recording.csv", **options)  # type: ignore[arg-type]
    e = err.value
    assert e.file == "my recording.csv" and str(e).startswith("my recording.csv")
    assert e.line == line
    if channel is not None:
        assert e.channel is not None and e.channel.startswith(channel)
    assert "/" not in str(e).split(":")[0]  # never a server path


def test_a_constant_channel_mapped_by_its_name_is_left_out_with_a_note() -> None:
    """The same all-zero triceps column, mapped automatically from its name: not an error
    (an unused input of the amplifier), unmapped and named in a warning."""
    data = "\n".join(
        [r if i == 0 else ",".join([*r.split(",")[:2], "0"]) for i, r in enumerate(_emg_csv())]
    ).encode()
    rec = read_bytes(data, "flat.csv")
    assert rec.channels["triceps"].site is None
    assert rec.metadata["flat_channels"] == ["triceps"]
    assert any("'triceps' is constant" in w for w in rec.metadata["warnings"])


def test_errors_name_the_user_file_not_the_storage_path(tmp_path: Path) -> None:
    stored = tmp_path / "3f9a0c2e"  # the API stores uploads by hash
    stored.write_bytes(b"time,biceps\n0,1\n")
    with pytest.raises(RecordingError) as err:
        read_recording(stored, name="curl_01.csv")
    assert str(err.value).startswith("curl_01.csv, line 2: has 1 data row(s)")
    assert str(tmp_path) not in str(err.value)


def test_edf_from_bytes_uses_no_visible_temp_name(tmp_path: Path) -> None:
    pytest.importorskip("pyedflib")
    path = tmp_path / "x.edf"
    write_edf(path, [emg_like(400, 200.0) * 1e6], ["EMG1"], ["uV"], [200.0])
    data = bytearray(path.read_bytes())
    data[168:176] = b"31.02.2x"  # an impossible start date
    with pytest.raises(RecordingError) as err:
        read_bytes(bytes(data), "session.edf")
    assert str(err.value).startswith("session.edf: EDF header is not standard-compliant")
    assert "bioplan-upload" not in str(err.value)


def test_truncated_mat_files(tmp_path: Path) -> None:
    import h5py
    import scipy.io as sio

    v5 = tmp_path / "a.mat"
    sio.savemat(v5, {"biceps": emg_like(5000, 1000.0), "fs": 1000.0})
    data = v5.read_bytes()
    with pytest.raises(RecordingError, match=r"^a\.mat: "):
        read_bytes(data[: len(data) // 2], "a.mat")
    v73 = tmp_path / "b.mat"
    with h5py.File(v73, "w") as f:
        f["biceps"] = emg_like(5000, 1000.0)
        f["fs"] = 1000.0
    data = v73.read_bytes()
    with pytest.raises(
        RecordingError, match=r"^b\.mat: HDF5 \(MATLAB v7\.3\) content cannot be read"
    ):
        read_bytes(data[: len(data) // 2], "b.mat")


# ---------------------------------------------------------------------------------------------
# rate checks


@pytest.mark.parametrize("rate", [500.0, 2000.0, 4096.0])
def test_emg_median_frequency_matches_scipy_welch(rate: float) -> None:
    signal = pytest.importorskip("scipy.signal")
    x = emg_like(int(20 * rate), rate, seed=11)
    f, p = signal.welch(x, fs=rate, nperseg=256)
    cum = np.cumsum(p[1:])
    reference = f[1:][np.searchsorted(cum, cum[-1] / 2)]
    assert emg_median_frequency(x, rate) == pytest.approx(reference, abs=rate / 256)


def test_rate_suggestions() -> None:
    # NT-01: 474 Hz at the stored 20 kHz -> 2 kHz (a decimal slip)
    assert suggest_emg_rate(474.0, 20000.0) == 2000.0
    assert suggest_emg_rate(8.0, 100.0) == 1000.0
    # whatever the stored rate and measured median, the suggestion lands in the plausible band
    for median in (3.0, 15.0, 260.0, 700.0, 4000.0):
        for rate in (100.0, 1000.0, 1111.0, 2048.0, 30000.0):
            fixed = median * suggest_emg_rate(median, rate) / rate
            assert 20.0 <= fixed <= 250.0, (median, rate)


def test_wrong_stored_rate_warns_and_emg_rate_fixes(tmp_path: Path) -> None:
    true_rate = 2000.0
    x = emg_like(20000, true_rate, seed=2) * 1e6
    # exported with a time column that claims 200 Hz
    lines = ["time,biceps (uV)"] + [f"{i / 200:.3f},{v:.3f}" for i, v in enumerate(x)]
    path = tmp_path / "slow.csv"
    path.write_text("\n".join(lines) + "\n")
    rec = read_recording(path)
    assert rec.channels["biceps"].rate == 200.0
    assert rec.metadata["suggested_emg_rate"] == 2000.0
    fixed = read_recording(path, emg_rate=2000.0)
    ch = fixed.channels["biceps"]
    assert ch.rate == 2000.0 and ch.time is None and ch.duration == pytest.approx(10.0)
    assert "suggested_emg_rate" not in fixed.metadata


def test_a_misspelt_reader_keyword_is_refused(tmp_path: Path) -> None:
    """``read_recording``/``read_bytes`` take their keywords as one TypedDict: a misspelt one
    is a TypeError naming it (not silently ignored), the right one changes the result."""
    data = "\n".join(_emg_csv()).encode()
    path = tmp_path / "emg.csv"
    path.write_bytes(data)
    with pytest.raises(TypeError, match="emg_rat"):
        read_bytes(data, "emg.csv", emg_rat=2000.0)  # type: ignore[call-arg]
    with pytest.raises(TypeError, match="emg_rat"):
        read_recording(path, emg_rat=2000.0)  # type: ignore[call-arg]
    assert {ch.rate for ch in read_recording(path).channels.values()} == {1000.0}
    fixed = read_bytes(data, "emg.csv", emg_rate=2000.0)
    assert {ch.rate for ch in fixed.channels.values() if ch.kind == "emg"} == {2000.0}
