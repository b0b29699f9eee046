"""Fuzzing: mutated real and synthetic files raise nothing but RecordingError (or read)."""

from __future__ import annotations

import functools
import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app.recordings import DatalogSensor, Recording, RecordingError, read_bytes
from tests.conftest import SHARED_DATA
from tests.recordings._writers import (
    emg_like,
    mediapipe_frames,
    write_c3d,
    write_datalog,
    write_edf,
    write_vicon_csv,
)

FUZZ = settings(
    max_examples=int(os.environ.get("BIOPLAN_FUZZ_EXAMPLES", "40")),
    deadline=None,
    derandomize=True,  # the same examples on every run (set BIOPLAN_FUZZ_EXAMPLES to explore more)
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


def _lines(relative: str, n: int) -> bytes | None:
    path = SHARED_DATA / relative
    if not path.is_file():
        return None
    return b"\n".join(path.read_bytes().split(b"\n")[:n]) + b"\n"


def _real(relative: str) -> bytes | None:
    path = SHARED_DATA / relative
    return path.read_bytes() if path.is_file() else None


def _synthetic_file(writer: Callable[[Path], Any], suffix: str) -> bytes:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"seed{suffix}"
        writer(path)
        return path.read_bytes()


def _csv() -> bytes:
    x = emg_like(600, 1000.0, seed=1) * 1e6
    rows = ["time;biceps;elbow (deg)"] + [
        f"{i / 1000:.3f};{v:.3f};{i / 10:.2f}".replace(".", ",") for i, v in enumerate(x)
    ]
    return ("\ufeff" + "\r\n".join(rows) + "\r\n").encode()


def _datalog(path: Path) -> None:
    emg = np.round(emg_like(400, 1000.0) / 3e-3 * 4000).astype(int)
    write_datalog(path, [emg.tolist(), list(range(0, 4000, 100))])


def _c3d(path: Path) -> None:
    points = np.random.default_rng(0).uniform(0, 1000, (3, 3, 30))
    analogs = np.stack([emg_like(300, 1000.0, seed=s) for s in (1, 2)])
    write_c3d(
        path,
        points=points,
        point_labels=["A", "B", "C"],
        analogs=analogs,
        analog_labels=["Biceps.EMG1", "Triceps.EMG2"],
        analog_units=["V", "V"],
    )


def _edf(path: Path) -> None:
    write_edf(
        path,
        [emg_like(800, 400.0) * 1e6, np.linspace(0, 90, 200)],
        ["EMG Biceps", "Elbow"],
        ["uV", "deg"],
        [400.0, 100.0],
    )


def _mat5(path: Path) -> None:
    import scipy.io as sio

    sio.savemat(
        path,
        {
            "emg": np.column_stack([emg_like(500, 1000.0, seed=s) for s in (1, 2)]),
            "labels": np.array(["BIC", "TRI"], dtype=object),
            "fs": 1000.0,
            "info": {"subject": "S01", "units": "V"},
        },
    )


def _mat73(path: Path) -> None:
    import h5py

    with h5py.File(path, "w", userblock_size=512) as f:
        g = f.create_group("rec")
        g.attrs["MATLAB_class"] = np.bytes_("struct")
        g["Biceps"] = emg_like(500, 1000.0)[None, :]
        g["fs"] = np.array([[1000.0]])
    with path.open("r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file".ljust(116, b" "))


def _mp_json() -> bytes:
    lm = mediapipe_frames(8)
    frames = [
        {
            "timestamp_ms": 33 * i,
            "pose_landmarks": [[{"x": p[0], "y": p[1], "z": p[2], "visibility": p[3]} for p in f]],
        }
        for i, f in enumerate(lm.tolist())
    ]
    return json.dumps({"image_width": 640, "image_height": 480, "frames": frames}).encode()


def _trc() -> bytes:
    rows = [
        "PathFileType\t4\t(X/Y/Z)\tx.trc",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits",
        "100\t100\t10\t1\tmm",
        "Frame#\tTime\tM1\t\t",
        "\t\tX1\tY1\tZ1",
        "",
    ]
    rows += [f"{i + 1}\t{i / 100:.2f}\t{i}.0\t1.0\t2.0" for i in range(10)]
    return "\n".join(rows).encode()


SENSORS = [
    DatalogSensor(0, "biceps", "emg", 1000.0, 3.0, "mV"),
    DatalogSensor(1, "elbow", "angle", 100.0, 180.0, "deg"),
]

# (id, file name, seed bytes factory, format, options)
SEEDS: list[tuple[str, str, Callable[[], bytes | None], str, dict[str, Any]]] = [
    ("csv", "a.csv", _csv, "csv", {}),
    (
        "noraxon",
        "n.csv",
        lambda: _lines(
            "noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv", 400
        ),
        "noraxon_csv",
        {},
    ),
    ("vicon", "v.csv", lambda: _synthetic_file(write_vicon_csv, ".csv"), "vicon_csv", {}),
    (
        "vicon_real",
        "v2.csv",
        lambda: _lines("pyomeca_upperlimb_c3d_emg/analogs.csv", 300),
        "vicon_csv",
        {},
    ),
    (
        "datalog",
        "d.txt",
        lambda: _synthetic_file(_datalog, ".txt"),
        "datalog_txt",
        {"datalog_sensors": SENSORS},
    ),
    ("c3d", "c.c3d", lambda: _synthetic_file(_c3d, ".c3d"), "c3d", {}),
    ("c3d_real", "r.c3d", lambda: _real("c3d_bts_gait_emg/BTS.c3d"), "c3d", {}),
    ("edf", "e.edf", lambda: _synthetic_file(_edf, ".edf"), "edf", {}),
    ("mat5", "m.mat", lambda: _synthetic_file(_mat5, ".mat"), "mat", {}),
    ("mat73", "h.mat", lambda: _synthetic_file(_mat73, ".mat"), "mat", {}),
    (
        "mat73_real",
        "nt.mat",
        lambda: _real("noraxon_curls_biceps_brachioradialis/SP-01.mat"),
        "mat",
        {},
    ),
    (
        "mediapipe_csv",
        "p.csv",
        lambda: _lines("mediapipe_bicep_curl_frames/test.csv", 40),
        "mediapipe_csv",
        {"frame_rate": 30.0},
    ),
    ("mediapipe_json", "p.json", _mp_json, "mediapipe_json", {}),
    ("trc", "t.trc", _trc, "trc", {}),
    ("mot", "k.mot", lambda: _real("pyomeca_upperlimb_c3d_emg/inverse_kin.mot"), "mot", {}),
    ("sto", "s.sto", lambda: _real("pyomeca_upperlimb_c3d_emg/inverse_dyn.sto"), "sto", {}),
]


@functools.cache
def _seed(key: str) -> bytes | None:
    factory = next(s[2] for s in SEEDS if s[0] == key)
    return factory()


@st.composite
def mutated(draw: st.DrawFn, data: bytes) -> bytes:
    kind = draw(st.sampled_from(["truncate", "flip", "flip_head", "insert", "text", "binary"]))
    b = bytearray(data)
    if kind == "truncate":
        return bytes(b[: draw(st.integers(0, len(b)))])
    if kind in ("flip", "flip_head"):
        # headers decide how the rest is read: hit them more often
        limit = len(b) if kind == "flip" else min(len(b), 2048)
        for _ in range(draw(st.integers(1, 8))):
            b[draw(st.integers(0, limit - 1))] = draw(st.integers(0, 255))
        return bytes(b)
    if kind == "insert":
        newlines = [i for i, c in enumerate(b[:20000]) if c == 10] or [0]
        at = draw(st.sampled_from(newlines)) + 1
        junk = draw(st.text(max_size=40)).encode("utf-8", "replace") + b"\n"
        return bytes(b[:at] + junk + b[at:])
    if kind == "text":
        return draw(st.text(max_size=300)).encode("utf-8", "replace")
    return draw(st.binary(max_size=600))


def _check(data: bytes, name: str, fmt: str | None, options: dict[str, Any]) -> None:
    try:
        rec = read_bytes(data, name, format=fmt, **options)
    except RecordingError as err:
        assert str(err).startswith(name)
        return
    assert isinstance(rec, Recording) and rec.channels
    assert isinstance(rec.metadata["warnings"], list)


@pytest.mark.parametrize(
    ("key", "name", "fmt", "options"),
    [(s[0], s[1], s[3], s[4]) for s in SEEDS],
    ids=[s[0] for s in SEEDS],
)
@FUZZ
@given(data=st.data())
def test_mutated_files_raise_only_recording_error(
    key: str, name: str, fmt: str, options: dict[str, Any], data: st.DataObject
) -> None:
    seed = _seed(key)
    if seed is None:
        pytest.skip(f"real test data for {key} not found")
    # the unmutated seed reads
    _check(seed, name, None, options)
    content = data.draw(mutated(seed))
    forced = data.draw(st.booleans())
    _check(content, name, fmt if forced else None, options)


def test_seeds_read_cleanly() -> None:
    for key, name, _, fmt, options in SEEDS:
        seed = _seed(key)
        if seed is None:
            continue
        rec = read_bytes(seed, name, **options)
        assert rec.format == fmt, key
