"""EDF/EDF+/BDF reader (pyedflib), with BIDS sidecars joined when they sit beside the file."""

from __future__ import annotations

import csv
import io
import json
import re
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.recordings._common import Options, Source, classify, norm_unit, scalar_channel, unique_name
from app.recordings.muscles import map_muscle
from app.recordings.types import Channel, Recording


def _field(data: bytes, start: int, size: int) -> str:
    return data[start : start + size].decode("latin-1").strip()


def _int(text: str) -> int | None:
    try:
        return int(text)
    except ValueError:
        return None


def header_problem(data: bytes) -> str | None:
    """What is wrong with an EDF/BDF fixed header, in words; None if it looks compliant.

    The fixed header is 256 bytes; field offsets follow the EDF specification (number of
    header bytes at 184, number of signals at 252). A header shifted by one byte (255 bytes,
    as in a known BIDS example) is recognised and named; :func:`repair_short_header` reads it.
    """
    if len(data) < 256:
        return f"the file is {len(data)} bytes, shorter than the 256-byte fixed header"
    ns = _int(_field(data, 252, 4))
    hbytes = _int(_field(data, 184, 8))
    if ns is not None and hbytes == 256 * (ns + 1):
        date = _field(data, 168, 8)
        if not re.fullmatch(r"\d\d\.\d\d\.\d\d", date):
            return f"start date {date!r} is not dd.mm.yy"
        return None
    ns1 = _int(_field(data, 251, 4))
    hb1 = _int(_field(data, 183, 8))
    if ns1 is not None and hb1 is not None and hb1 in (256 * (ns1 + 1), 256 * (ns1 + 1) - 1):
        return "the fixed header is 255 bytes instead of 256 (every field is shifted by one byte)"
    return (
        f"header size field {_field(data, 184, 8)!r} and signal count {_field(data, 252, 4)!r}"
        " do not agree"
    )


#: Where the 256-byte fixed header's fields start after the 8-byte version: local patient
#: (80 bytes), local recording (80), start date (8), start time (8), header bytes (8).
_PATIENT, _RECORDING, _DATE = 8, 88, 168


def repair_short_header(data: bytes) -> tuple[bytes, str] | None:
    """The file with a 255-byte fixed header made standard, and what was done; None when
    the shifted reading is not unambiguous.

    One writer dropped a byte from a free-text field (the BIDS-EMG "Multimodal" example: the
    patient field is 79 bytes, so the recording field starts at byte 87, the start date at
    167, and the 256-byte signal headers at 255). The repair inserts one space: after the
    patient field when the recording field starts there (EDF+ ``Startdate``) or the patient
    field ends in padding, else at the end of the recording field; both are free text, so no
    number moves. It is applied only when every shifted numeric field parses (start date
    ``dd.mm.yy``, start time ``hh.mm.ss``, header bytes = 256 x (signals + 1), records,
    samples per record) and the file size is exactly header + data, so the reading is not a
    guess.
    """
    if len(data) < 255:
        return None
    ns = _int(_field(data, 251, 4))
    hbytes = _int(_field(data, 183, 8))
    nrec = _int(_field(data, 235, 8))
    if ns is None or ns <= 0 or hbytes is None or nrec is None or nrec <= 0:
        return None
    if hbytes not in (256 * (ns + 1), 256 * (ns + 1) - 1):
        return None
    if not re.fullmatch(r"\d\d\.\d\d\.\d\d", _field(data, _DATE - 1, 8)):
        return None
    if not re.fullmatch(r"\d\d\.\d\d\.\d\d", _field(data, _DATE + 7, 8)):
        return None
    spr_start = 255 + ns * (16 + 80 + 8 + 8 + 8 + 8 + 8 + 80)
    if len(data) < spr_start + 8 * ns:
        return None
    samples = [_int(_field(data, spr_start + 8 * i, 8)) for i in range(ns)]
    if any(s is None or s <= 0 for s in samples):
        return None
    width = 3 if data[:1] == b"\xff" else 2
    total = sum(s for s in samples if s is not None)
    if len(data) != 255 + 256 * ns + nrec * width * total:
        return None
    after_patient = _RECORDING - 1
    if data[after_patient : after_patient + 9] == b"Startdate" or data[after_patient - 1] == 32:
        at, where = after_patient, "after the patient field"
    else:
        at, where = _DATE - 1, "at the end of the recording field"
    fixed = bytearray(data[:at] + b" " + data[at:])
    fixed[_DATE + 16 : _DATE + 24] = f"{256 * (ns + 1):<8d}".encode("ascii")
    note = (
        "EDF fixed header is 255 bytes instead of 256 (a writer's quirk); read with one"
        f" space inserted {where}: the numeric fields, signal headers and"
        f" {nrec} x {total} samples per record then agree with the file size"
    )
    return bytes(fixed), note


def _expected_size(data: bytes) -> int | None:
    ns = _int(_field(data, 252, 4))
    hbytes = _int(_field(data, 184, 8))
    nrec = _int(_field(data, 236, 8))
    if ns is None or hbytes is None or nrec is None or ns <= 0 or nrec < 0:
        return None
    if len(data) < 256 + ns * 256:
        return None
    spr_start = 256 + ns * (16 + 80 + 8 + 8 + 8 + 8 + 8 + 80)
    samples = [_int(_field(data, spr_start + 8 * i, 8)) for i in range(ns)]
    if any(s is None or s < 0 for s in samples):
        return None
    width = 3 if data[:1] == b"\xff" else 2
    return hbytes + nrec * width * sum(s for s in samples if s is not None)


def _bids_sidecars(src: Source) -> tuple[list[dict[str, str]] | None, dict[str, Any] | None]:
    """BIDS ``_channels.tsv`` rows and ``_emg.json`` of the EDF: given with the upload, or
    beside the file (named after the user's file name, else the stored file's)."""
    stems = [_bids_stem(src.name)] + ([_bids_stem(src.path.name)] if src.path else [])
    rows = None
    side = src.sidecar(*(st + "_channels.tsv" for st in stems))
    if side is not None:
        try:
            text = side[1].decode("utf-8-sig")
            rows = list(csv.DictReader(io.StringIO(text), delimiter="\t"))
        except (UnicodeDecodeError, csv.Error):
            src.warn(f"BIDS sidecar {side[0]} cannot be read; ignored")
    info = None
    side_json = src.sidecar(*(st + "_emg.json" for st in stems))
    if side_json is not None:
        try:
            loaded = json.loads(side_json[1].decode("utf-8"))
            info = loaded if isinstance(loaded, dict) else None
        except (UnicodeDecodeError, ValueError):
            src.warn(f"BIDS sidecar {side_json[0]} cannot be read; ignored")
    return rows, info


def _bids_stem(name: str) -> str:
    for suffix in ("_emg.edf", "_emg.bdf", ".edf", ".bdf"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return name


def read_edf(src: Source, opts: Options) -> Recording:
    """EDF, EDF+ and BDF via pyedflib: physical values, per-signal rates and units.

    A BIDS ``*_channels.tsv`` (beside the file, or given with an upload) renames generic labels
    (``EMG1``) to its names and maps sites from ``target_muscle``; when its units disagree with
    the EDF header, the EDF header wins (it defines the digital-to-physical scaling) and a
    warning says so.
    """
    repaired = _check_header(src)
    edf = _read_signals(src if repaired is None else Source(src.name, content=repaired))
    rows, info = _bids_sidecars(src)
    n = len(edf.headers)
    if rows is not None and len(rows) != n:
        src.warn(f"BIDS channels.tsv lists {len(rows)} channels, the EDF has {n}; not joined")
        rows = None
    if opts.rate is not None:
        src.warn("rate option ignored: EDF states a rate per signal (use emg_rate for EMG)")
    channels: dict[str, Channel] = {}
    labels = []
    for i, (h, x) in enumerate(zip(edf.headers, edf.signals, strict=True)):
        label = str(h.get("label", "")).strip() or f"signal{i + 1}"
        labels.append(label)
        ch = _channel(src, h, x, label, rows[i] if rows is not None else None, channels)
        channels[ch.name] = ch
    metadata = _metadata(edf, labels, channels)
    if info is not None:
        _join_bids_info(src, info, metadata)
    return Recording(channels=channels, source=src.name, format="edf", metadata=metadata)


def _check_header(src: Source) -> bytes | None:
    """Refuse a malformed header by name. A 255-byte one that :func:`repair_short_header`
    reads unambiguously is repaired with a warning: the repaired bytes are returned."""
    data = src.data()
    problem = header_problem(data)
    repaired = None
    if problem is not None and "255 bytes" in problem:
        fixed = repair_short_header(data)
        if fixed is not None:
            repaired, note = fixed
            src.warn(note)
            data, problem = repaired, None
    if problem is not None:
        raise src.error(
            f"EDF header is not standard-compliant: {problem}",
            expected="an EDF/EDF+/BDF file with a 256-byte fixed header",
        )
    size = _expected_size(data)
    if size is not None and len(data) < size:
        raise src.error(
            f"is truncated: the header announces {size} bytes, the file has {len(data)}",
            expected="a complete EDF file",
        )
    return repaired


@dataclass
class _Edf:
    headers: list[dict[str, Any]]
    signals: list[NDArray[np.float64]]
    file_header: dict[str, Any]
    duration: float
    filetype: int


def _read_signals(src: Source) -> _Edf:
    import pyedflib

    suffix = ".bdf" if src.data()[:1] == b"\xff" else ".edf"
    with src.as_path(suffix) as path:
        try:
            reader = pyedflib.EdfReader(str(path))
        except OSError as exc:
            reason = str(exc).replace(str(path), "").lstrip(": ")
            raise src.error(
                f"EDF header is not standard-compliant: {reason}",
                expected="an EDF/EDF+/BDF file readable by pyedflib",
            ) from None
        try:
            n = reader.signals_in_file
            edf = _Edf(
                headers=[reader.getSignalHeader(i) for i in range(n)],
                signals=[np.asarray(reader.readSignal(i), dtype=np.float64) for i in range(n)],
                file_header=reader.getHeader(),
                duration=float(reader.getFileDuration()),
                filetype=reader.filetype,
            )
        finally:
            reader.close()
    if n == 0:
        raise src.error("has no signals", expected="at least one signal")
    return edf


def _channel(
    src: Source,
    h: dict[str, Any],
    x: NDArray[np.float64],
    label: str,
    row: dict[str, str] | None,
    channels: dict[str, Channel],
) -> Channel:
    """One signal as a channel, named and typed by its channels.tsv row when there is one."""
    unit = str(h.get("dimension", "")).strip() or None
    rate = float(h.get("sample_frequency", 0.0) or h.get("sample_rate", 0.0))
    name, target = label, ""
    kind = classify(label, unit, context=str(h.get("transducer", "")))
    if row is not None:
        name = (row.get("name") or label).strip()
        target = (row.get("target_muscle") or "").strip()
        if (row.get("type") or "").strip().upper() == "EMG":
            kind = "emg"
        side_unit = (row.get("units") or "").strip()
        if side_unit and unit and _unit_key(side_unit) != _unit_key(unit):
            src.warn(
                f"channel {name!r}: EDF header says {unit!r}, channels.tsv says"
                f" {side_unit!r}; the EDF header is used"
            )
    name = unique_name(name, channels)
    ch = scalar_channel(name, x, rate=rate, unit=unit, kind=kind, src=src)
    if kind == "emg":
        ch.site = map_muscle(target) if target else ch.site
        if ch.site is None:
            ch.site = map_muscle(name) or map_muscle(label)
    return ch


def _metadata(edf: _Edf, labels: list[str], channels: dict[str, Channel]) -> dict[str, Any]:
    file_header = edf.file_header
    metadata: dict[str, Any] = {
        "edf_labels": labels,
        "duration": edf.duration,
        "filetype": {0: "EDF", 1: "EDF+", 2: "BDF", 3: "BDF+"}.get(edf.filetype, str(edf.filetype)),
    }
    start = file_header.get("startdate")
    if start is not None:
        metadata["start_date"] = str(start)
    for key in ("patientcode", "equipment", "technician"):
        if file_header.get(key):
            metadata[key] = file_header[key]
    if file_header.get("equipment"):
        metadata["device"] = file_header["equipment"]
    rates = {ch.rate for ch in channels.values()}
    if len(rates) == 1:
        metadata["stored_rate"] = rates.pop()
    return metadata


def _join_bids_info(src: Source, info: dict[str, Any], metadata: dict[str, Any]) -> None:
    """The BIDS ``_emg.json``: device names, and a warning when its rate disagrees."""
    metadata["bids"] = info
    if info.get("ManufacturersModelName") or info.get("Manufacturer"):
        metadata["device"] = " ".join(
            str(info[k]) for k in ("Manufacturer", "ManufacturersModelName") if info.get(k)
        )
    fs = info.get("SamplingFrequency")
    stored = metadata.get("stored_rate")
    if isinstance(fs, int | float) and stored and abs(float(fs) - stored) > 1e-6 * fs:
        src.warn(
            f"BIDS SamplingFrequency {fs} Hz disagrees with the EDF's {stored:g} Hz;"
            " the EDF is used"
        )


def _unit_key(unit: str) -> str:
    u = norm_unit(unit)
    return {"microv": "uv", "microvolt": "uv", "microvolts": "uv", "millivolt": "mv"}.get(u, u)
