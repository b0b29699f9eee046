"""MATLAB .mat reader: v5 (scipy.io) and v7.3 (HDF5, h5py), labelled matrices and structs.

Both versions are flattened to leaves ``path -> value`` (numbers as float arrays in MATLAB's
dimension order, text as str or list of str), then channels are found by convention:

- a rate leaf (``fs``, ``Fs``, ``rate``, ``srate``, ``sampling_frequency``, ``SampleRate``...)
  applies to the data beside it (the nearest one up the struct tree);
- a units leaf (``units``, ``amplitude_units``...) likewise, as one string or one per channel;
- a labels leaf (``labels``, ``channel_names``, ``names``...) names the columns (or rows) of a
  matrix with as many columns (rows);
- every other numeric vector is one channel named by its field (``data.BicepsBrachi`` ->
  ``"BicepsBrachi"``); a matrix without labels is split along its short side.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from app.errors import BioPlanError
from app.recordings import _hdf5
from app.recordings._common import (
    F64,
    Options,
    Source,
    check_rate,
    classify,
    rate_from_times,
    scalar_channel,
    unique_name,
)
from app.recordings._mat5 import loadmat5
from app.recordings.types import Channel, Recording

Leaves = dict[tuple[str, ...], Any]

_RATE_KEYS = {
    "fs",
    "sr",
    "srate",
    "rate",
    "samplerate",
    "samplingrate",
    "samplingfrequency",
    "samplefrequency",
    "samplingfreq",
    "sampfreq",
    "fsamp",
    "frequency",
    "freq",
    "samplingrateHz".lower(),
}
_UNIT_KEYS = {"units", "unit", "amplitudeunits", "dimension", "dimensions", "physicaldimension"}
_LABEL_KEYS = {
    "labels",
    "label",
    "channelnames",
    "channels",
    "names",
    "chanlabels",
    "channellabels",
}
_TIME_KEYS = {"time", "t", "times", "timestamps"}
_MAX_CHANNELS = 512


def _key(k: str) -> str:
    return re.sub(r"[^a-z0-9]", "", k.lower())


def _walk_v5(obj: Any, path: tuple[str, ...], out: Leaves, depth: int = 0) -> None:
    if depth > 20:
        return
    if isinstance(obj, dict):
        for k, v in obj.items():
            if not str(k).startswith("__"):
                _walk_v5(v, (*path, str(k)), out, depth + 1)
    elif isinstance(obj, str):
        out[path] = obj
    elif isinstance(obj, list | tuple):
        if obj and all(isinstance(v, str) for v in obj):
            out[path] = [str(v) for v in obj]
        else:
            for i, v in enumerate(obj):
                _walk_v5(v, (*path, str(i)), out, depth + 1)
    elif isinstance(obj, np.ndarray):
        if obj.dtype.kind in "US":
            out[path] = (
                [str(s).strip() for s in obj.ravel()]
                if obj.size != 1
                else str(obj.ravel()[0]).strip()
            )
        elif obj.dtype.kind == "O":
            _walk_v5(list(obj.ravel()), path, out, depth + 1)
        elif obj.dtype.kind in "iuf" and obj.size:
            out[path] = np.asarray(obj, dtype=np.float64)
    elif isinstance(obj, int | float | np.integer | np.floating) and not isinstance(obj, bool):
        out[path] = np.asarray([float(obj)])


#: Bytes one MAT 7.3 file may decode to, all datasets together: a recording is far smaller,
#: while gzip chunks that were never written inflate from a few KB to any size.
MAX_DECODED_BYTES = 512 << 20


class _H5Walk:
    """What one walk of an HDF5 file has used: decoded bytes left, objects visited, open groups."""

    def __init__(self) -> None:
        self.budget = MAX_DECODED_BYTES
        self.visits = _hdf5.Visits()


def _walk_h5(
    f: Any,
    node: Any,
    path: tuple[str, ...],
    out: Leaves,
    depth: int = 0,
    walk: _H5Walk | None = None,
) -> None:
    """Leaves of an HDF5 (MAT 7.3) file.

    Every link is checked before it is followed and every dataset's storage before it is read
    (``_hdf5``: nothing outside the uploaded bytes is ever opened); the decoded-size budget is
    checked against each dataset's declared size before it is read, so nothing over the limit
    is ever allocated.
    """
    import h5py

    walk = _H5Walk() if walk is None else walk
    if depth > 20:
        return
    if isinstance(node, h5py.Group):
        walk.visits.enter(node, path)
        for k, child in _hdf5.children(node, path):
            if not k.startswith("#"):
                _walk_h5(f, child, (*path, k), out, depth + 1, walk)
        walk.visits.leave()
        return
    if not isinstance(node, h5py.Dataset):
        return
    walk.visits.enter(node, path)
    _hdf5.check_dataset(node, path)
    cls = node.attrs.get("MATLAB_class", b"")
    cls = cls.decode("latin-1") if isinstance(cls, bytes) else str(cls)
    if node.attrs.get("MATLAB_empty", 0):
        return
    walk.budget -= int(node.size) * max(int(node.dtype.itemsize), 1)
    if walk.budget < 0:
        raise BioPlanError(
            f"its datasets decode to more than {MAX_DECODED_BYTES >> 20} MB in all (at "
            f"{'/'.join(path) or 'the root'}, shape {tuple(node.shape)}): a recording is far "
            "smaller (a damaged or hostile file)"
        )
    value = node[()]
    if cls == "char":
        arr = np.asarray(value)
        # MATLAB char arrays are stored transposed: rows of the MATLAB matrix are columns here.
        if arr.ndim == 2 and arr.shape[1] > 1 and arr.shape[0] > 1:
            out[path] = ["".join(chr(c) for c in col).strip() for col in arr.T]
        else:
            out[path] = "".join(chr(int(c)) for c in arr.ravel()).strip()
    elif cls == "cell" or (isinstance(value, np.ndarray) and value.dtype.kind == "O"):
        _walk_cell(f, value, path, out, depth, walk)
    else:
        arr = np.asarray(value)
        if arr.dtype.kind in "iuf" and arr.size:
            # HDF5 holds MATLAB arrays in reversed dimension order.
            out[path] = np.asarray(arr.T, dtype=np.float64)


def _walk_cell(
    f: Any, value: Any, path: tuple[str, ...], out: Leaves, depth: int, walk: _H5Walk
) -> None:
    """A cell array's items: object references into the same file, each target walked (and so
    checked) like any other object; a cell of strings becomes one list of str."""
    items = [
        item for ref in np.asarray(value).T.ravel() if (item := _hdf5.deref(f, ref)) is not None
    ]
    texts: list[str] = []
    for i, item in enumerate(items):
        sub: Leaves = {}
        _walk_h5(f, item, (*path, str(i)), sub, depth + 1, walk)
        if len(sub) == 1 and isinstance(next(iter(sub.values())), str):
            texts.append(next(iter(sub.values())))
        else:
            out.update(sub)
    if texts and len(texts) == len(items):
        out[path] = texts


def _leaves(src: Source, data: bytes) -> tuple[Leaves, str]:
    if (
        data[:19] == b"MATLAB 7.3 MAT-file"
        or data[:8] == b"\x89HDF\r\n\x1a\n"
        or (len(data) > 520 and data[512:520] == b"\x89HDF\r\n\x1a\n")
    ):
        out: Leaves = {}
        try:
            with _hdf5.open_bytes(data) as f:
                _walk_h5(f, f, (), out)
        except BioPlanError as exc:
            raise src.error(str(exc), expected="a MATLAB v7.3 recording") from None
        except OSError as exc:
            raise src.error(
                f"HDF5 (MATLAB v7.3) content cannot be read: {exc}",
                expected="a complete MATLAB v7.3 / HDF5 file",
            ) from None
        return out, "7.3"
    if not data.startswith(b"MATLAB 5.0 MAT-file"):
        raise src.error(
            "is not a MATLAB v5 or v7.3 file",
            expected="'MATLAB 5.0 MAT-file' or an HDF5 (v7.3) file",
        )
    try:
        loaded = loadmat5(data)
    except ValueError as exc:
        raise src.error(
            f"MAT v5 content cannot be read: {exc}", expected="a complete MATLAB v5 file"
        ) from None
    out = {}
    _walk_v5(loaded, (), out)
    return out, "5"


def _nearest(path: tuple[str, ...], found: dict[tuple[str, ...], Any]) -> Any:
    """The value whose parent path shares the longest prefix with ``path``."""
    best = None
    best_len = -1
    for p, v in found.items():
        parent = p[:-1]
        if path[: len(parent)] == parent and len(parent) > best_len:
            best, best_len = v, len(parent)
    return best


def read_mat(src: Source, opts: Options) -> Recording:
    """Channels from a MATLAB file (see the module docstring for the conventions)."""
    data = src.data()
    leaves, version = _leaves(src, data)
    rates: dict[tuple[str, ...], float] = {}
    units: dict[tuple[str, ...], Any] = {}
    labels: dict[tuple[str, ...], list[str]] = {}
    times: dict[tuple[str, ...], F64] = {}
    arrays: dict[tuple[str, ...], F64] = {}
    info: dict[str, Any] = {}
    for path, value in leaves.items():
        key = _key(path[-1]) if path else ""
        if isinstance(value, np.ndarray):
            if value.size == 1:
                if key in _RATE_KEYS:
                    rates[path] = float(value.ravel()[0])
                else:
                    info[".".join(path)] = float(value.ravel()[0])
            elif key in _TIME_KEYS and min(value.shape) == 1:
                times[path] = value.ravel()
            elif value.ndim <= 2:
                arrays[path] = value
        elif key in _UNIT_KEYS:
            units[path] = value
        elif key in _LABEL_KEYS:
            labels[path] = [value] if isinstance(value, str) else list(value)
        elif isinstance(value, str) and len(value) < 200:
            info[".".join(path)] = value
    if not arrays:
        raise src.error(
            "holds no numeric arrays with more than one sample",
            expected="channel vectors or a channel matrix",
        )
    channels: dict[str, Channel] = {}
    stored: set[float] = set()
    for path, arr in arrays.items():
        stored_rate = _nearest(path, rates)
        time = _nearest(path, times)
        unit = _nearest(path, units)
        label_list = _nearest(path, labels)
        columns = _split(arr, label_list, path)
        if len(channels) + len(columns) > _MAX_CHANNELS:
            raise src.error(
                f"more than {_MAX_CHANNELS} channels", expected="a labelled channel matrix"
            )
        for j, (name, values) in enumerate(columns):
            rate, start, t = _rate_for(src, opts, name, values, stored_rate, time)
            if stored_rate is not None:
                stored.add(stored_rate)
            u = unit[j] if isinstance(unit, list) and j < len(unit) else unit
            u = u if isinstance(u, str) else None
            name = unique_name(name, channels)
            kind = classify(name, u)
            channels[name] = scalar_channel(
                name, values, rate=rate, unit=u, kind=kind, src=src, start=start, time=t
            )
    metadata: dict[str, Any] = {"mat_version": version, "fields": info}
    if len(stored) == 1:
        metadata["stored_rate"] = stored.pop()
    for k in ("subject", "ID", "id", "sex", "posture", "age"):
        for field, v in info.items():
            if field.split(".")[-1] == k:
                metadata.setdefault("subject_" + k.lower() if k != "subject" else "subject", v)
    return Recording(channels=channels, source=src.name, format="mat", metadata=metadata)


def _split(arr: F64, label_list: list[str] | None, path: tuple[str, ...]) -> list[tuple[str, F64]]:
    base = path[-1] if path else "data"
    if arr.ndim == 1 or min(arr.shape) == 1:
        return [(base, np.ascontiguousarray(arr.ravel()))]
    rows, cols = arr.shape
    if label_list is not None and len(label_list) == cols:
        return [
            (label_list[j] or f"{base}_{j + 1}", np.ascontiguousarray(arr[:, j]))
            for j in range(cols)
        ]
    if label_list is not None and len(label_list) == rows:
        return [
            (label_list[j] or f"{base}_{j + 1}", np.ascontiguousarray(arr[j, :]))
            for j in range(rows)
        ]
    if cols <= rows:
        return [(f"{base}_{j + 1}", np.ascontiguousarray(arr[:, j])) for j in range(cols)]
    return [(f"{base}_{j + 1}", np.ascontiguousarray(arr[j, :])) for j in range(rows)]


def _rate_for(
    src: Source,
    opts: Options,
    name: str,
    values: F64,
    stored: float | None,
    time: F64 | None,
) -> tuple[float, float, F64 | None]:
    if opts.rate is not None:
        if stored is not None and abs(stored - opts.rate) > 0.01 * opts.rate:
            src.warn(
                f"channel {name!r}: rate option {opts.rate:g} Hz overrides the stored {stored:g} Hz"
            )
        return opts.rate, 0.0, None
    if stored is not None:
        return check_rate(stored, src=src, what="stored sampling rate", channel=name), 0.0, None
    if time is not None and time.size == values.size:
        rate, start, t = rate_from_times(time, src=src, channel=name)
        return check_rate(rate, src=src, what="rate from the time vector", channel=name), start, t
    raise src.error(
        "has no sampling rate",
        channel=name,
        expected="a rate field (fs, rate, sampling_frequency...), a time vector or the rate option",
    )
