"""MATLAB v5 MAT-file parser (numpy and zlib only), bounds-checked.

scipy.io.loadmat (1.17) dies with a segmentation fault on some single-byte corruptions (an
invalid data type in a variable's real part), which would take a server process down with an
upload. This parser checks every size and type against the file and raises ValueError
instead; it returns what ``loadmat(..., simplify_cells=True)`` returns for the variable kinds
recordings use (numeric arrays, char arrays, cells, structs), and the tests compare the two.
"""

from __future__ import annotations

import zlib
from typing import Any

import numpy as np

from app.errors import BioPlanError

_MI_TYPES = {
    1: "i1",
    2: "u1",
    3: "i2",
    4: "u2",
    5: "i4",
    6: "u4",
    7: "f4",
    9: "f8",
    12: "i8",
    13: "u8",
    16: "u1",  # miUTF8
    17: "u2",  # miUTF16
    18: "u4",  # miUTF32
}
_MI_MATRIX = 14
_MI_COMPRESSED = 15
_NUMERIC_CLASSES = {6, 7, 8, 9, 10, 11, 12, 13, 14, 15}
_CHAR, _CELL, _STRUCT, _OBJECT = 4, 1, 2, 3
_MAX_DEPTH = 32
_MAX_INFLATED = 1 << 29  # refuse zlib bombs: no recording variable is near 512 MB


class _Reader:
    def __init__(self, data: bytes, endian: str) -> None:
        self.data = data
        self.endian = endian

    def need(self, pos: int, size: int, what: str) -> bytes:
        if pos < 0 or size < 0 or pos + size > len(self.data):
            raise BioPlanError(
                f"truncated in {what} (needs bytes {pos}..{pos + size} of {len(self.data)})"
            )
        return self.data[pos : pos + size]

    def u32(self, pos: int, what: str) -> int:
        return int(np.frombuffer(self.need(pos, 4, what), dtype=self.endian + "u4")[0])

    def tag(self, pos: int, what: str) -> tuple[int, int, int, int]:
        """(type, nbytes, data offset, offset of the next element)."""
        first = self.u32(pos, what)
        if first >> 16:
            # small data element: type and size in one word, data in the next 4 bytes
            mtype, nbytes = first & 0xFFFF, first >> 16
            if nbytes > 4:
                raise BioPlanError(f"small data element of {nbytes} bytes in {what}")
            return mtype, nbytes, pos + 4, pos + 8
        nbytes = self.u32(pos + 4, what)
        end = pos + 8 + nbytes
        if end > len(self.data):
            raise BioPlanError(f"{what} claims {nbytes} bytes, beyond the end of the file")
        padded = end if first == _MI_COMPRESSED else pos + 8 + ((nbytes + 7) // 8) * 8
        return first, nbytes, pos + 8, padded

    def numbers(self, pos: int, what: str) -> tuple[np.ndarray, int]:
        mtype, nbytes, start, nxt = self.tag(pos, what)
        dtype = _MI_TYPES.get(mtype)
        if dtype is None:
            raise BioPlanError(f"data type {mtype} in {what}")
        size = np.dtype(dtype).itemsize
        if nbytes % size:
            raise BioPlanError(f"{what}: {nbytes} bytes is not a whole number of {dtype}")
        raw = self.need(start, nbytes, what)
        return np.frombuffer(raw, dtype=self.endian + dtype), nxt


def loadmat5(data: bytes) -> dict[str, Any]:
    """Variables of a v5 MAT-file: arrays, str / list of str, lists (cells), dicts (structs)."""
    if len(data) < 128:
        raise BioPlanError(f"file is {len(data)} bytes, shorter than the 128-byte MAT header")
    indicator = data[126:128]
    if indicator == b"IM":
        endian = "<"
    elif indicator == b"MI":
        endian = ">"
    else:
        raise BioPlanError(f"endian indicator {indicator!r} (expected 'IM' or 'MI')")
    out: dict[str, Any] = {}
    _elements(_Reader(data, endian), 128, len(data), out, depth=0, budget=[_MAX_INFLATED])
    return out


def _elements(
    r: _Reader, pos: int, end: int, out: dict[str, Any], *, depth: int, budget: list[int]
) -> None:
    """Variables between ``pos`` and ``end``; ``budget`` holds the bytes every compressed
    variable of the file may still inflate to, together (a bomb of many variables, each under
    the limit, is refused as surely as one large one)."""
    while pos + 8 <= end:
        mtype, nbytes, start, nxt = r.tag(pos, "a variable")
        if mtype == _MI_COMPRESSED:
            inflater = zlib.decompressobj()
            try:
                inner = inflater.decompress(
                    r.need(start, nbytes, "compressed variable"), max(budget[0], 1)
                )
            except zlib.error as exc:
                raise BioPlanError(f"compressed variable cannot be inflated: {exc}") from None
            budget[0] -= len(inner)
            if inflater.unconsumed_tail or budget[0] < 0:
                raise BioPlanError(
                    f"its compressed variables inflate beyond {_MAX_INFLATED >> 20} MB in all "
                    "(a recording is far smaller: a damaged or hostile file)"
                )
            _elements(_Reader(inner, r.endian), 0, len(inner), out, depth=depth + 1, budget=budget)
        elif mtype == _MI_MATRIX:
            name, value = _matrix(r, start, start + nbytes, depth=depth)
            if name and value is not None:
                out[name] = value
        pos = max(nxt, pos + 8)


def _matrix(r: _Reader, pos: int, end: int, *, depth: int) -> tuple[str, Any]:
    if depth > _MAX_DEPTH:
        raise BioPlanError("variables nested too deeply")
    if pos >= end:
        return "", None  # empty miMATRIX: MATLAB writes these for empty cells
    flags, pos = r.numbers(pos, "array flags")
    if flags.size < 2:
        raise BioPlanError("array flags are too short")
    cls = int(flags[0]) & 0xFF
    complex_ = bool(int(flags[0]) & 0x0800)
    dims_arr, pos = r.numbers(pos, "dimensions")
    dims = [int(d) for d in dims_arr]
    if not dims or any(d < 0 for d in dims):
        raise BioPlanError(f"dimensions {dims}")
    count = int(np.prod(dims, dtype=np.int64)) if dims else 0
    name_arr, pos = r.numbers(pos, "array name")
    name = bytes(name_arr.astype(np.uint8)).decode("latin-1") if name_arr.size else ""
    if cls in _NUMERIC_CLASSES:
        real, pos = r.numbers(pos, f"values of {name!r}")
        if real.size != count:
            raise BioPlanError(f"{name!r} holds {real.size} values for dimensions {dims}")
        values = real.astype(np.float64)
        if complex_:
            _, pos = r.numbers(pos, f"imaginary part of {name!r}")  # recordings are real
        return name, _shape(values, dims)
    if cls == _CHAR:
        chars, pos = r.numbers(pos, f"text of {name!r}")
        if chars.size != count:
            # UTF-8 char data is stored by byte, not by character
            return name, bytes(chars.astype(np.uint8)).decode("utf-8", "replace")
        codes = chars.astype(np.int64).reshape(dims, order="F") if count else chars
        if codes.ndim == 2 and codes.shape[0] > 1:
            return name, ["".join(map(chr, row)).rstrip() for row in codes.clip(0, 0x10FFFF)]
        return name, "".join(map(chr, codes.ravel().clip(0, 0x10FFFF)))
    if cls == _CELL:
        items = []
        for _ in range(count):
            _, nbytes, start, nxt = r.tag(pos, f"cell of {name!r}")
            items.append(_matrix(r, start, start + nbytes, depth=depth + 1)[1])
            pos = nxt
        return name, items[0] if count == 1 else items
    if cls in (_STRUCT, _OBJECT):
        if cls == _OBJECT:
            _, pos = r.numbers(pos, f"class name of {name!r}")
        length_arr, pos = r.numbers(pos, f"field name length of {name!r}")
        names_arr, pos = r.numbers(pos, f"field names of {name!r}")
        width = int(length_arr[0]) if length_arr.size else 0
        raw = bytes(names_arr.astype(np.uint8))
        fields = (
            [
                raw[i : i + width].split(b"\0")[0].decode("latin-1")
                for i in range(0, len(raw), width)
            ]
            if width > 0
            else []
        )
        structs = []
        for _ in range(count):
            entry: dict[str, Any] = {}
            for field in fields:
                _, nbytes, start, nxt = r.tag(pos, f"field {field!r} of {name!r}")
                entry[field] = _matrix(r, start, start + nbytes, depth=depth + 1)[1]
                pos = nxt
            structs.append(entry)
        return name, structs[0] if count == 1 else structs
    return name, None  # sparse, function handles, opaque objects: not recording data


def _shape(values: np.ndarray, dims: list[int]) -> Any:
    array = values.reshape(dims, order="F")
    squeezed = array.squeeze()
    if squeezed.ndim == 0:
        return float(squeezed)
    return np.ascontiguousarray(squeezed)
