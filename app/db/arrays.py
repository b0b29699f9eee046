"""Compact array storage: NumPy ``.npy`` / ``.npz`` bytes for ``LargeBinary`` columns.

Arrays are never stored as JSON lists of floats. One array is ``.npy`` bytes compressed with zlib
(level 1: float data compresses little, so speed matters more than ratio); a group of arrays is an
``.npz`` archive. Loading never unpickles (``allow_pickle=False``).
"""

from __future__ import annotations

import io
import zipfile
import zlib
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

_MAGIC = b"BPA1"


class ArrayDecodeError(ValueError):
    """Stored bytes are not an array written by this module."""


def encode_array(array: NDArray[np.generic]) -> bytes:
    """Encode one array (any shape, numeric dtype) as zlib-compressed ``.npy`` bytes."""
    arr = np.asarray(array)
    if arr.dtype == object:
        raise TypeError("object arrays cannot be stored (expected a numeric dtype)")
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=False)
    return _MAGIC + zlib.compress(buf.getbuffer(), 1)


def decode_array(data: bytes) -> NDArray[np.generic]:
    """Inverse of :func:`encode_array`."""
    if not data.startswith(_MAGIC):
        raise ArrayDecodeError("stored array has an unknown header (expected BPA1 npy bytes)")
    try:
        raw = zlib.decompress(memoryview(data)[len(_MAGIC) :])
    except zlib.error as exc:
        raise ArrayDecodeError(f"stored array is corrupt: {exc}") from exc
    result: NDArray[np.generic] = np.load(io.BytesIO(raw), allow_pickle=False)
    return result


def encode_arrays(arrays: Mapping[str, NDArray[np.generic]]) -> bytes:
    """Encode named arrays as a compressed ``.npz`` archive."""
    buf = io.BytesIO()
    np.savez_compressed(buf, allow_pickle=False, **{k: np.asarray(v) for k, v in arrays.items()})
    return buf.getvalue()


def decode_arrays(data: bytes) -> dict[str, NDArray[np.generic]]:
    """Inverse of :func:`encode_arrays`."""
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            return {name: npz[name] for name in npz.files}
    except (ValueError, OSError, zipfile.BadZipFile) as exc:
        raise ArrayDecodeError(f"stored arrays are corrupt: {exc}") from exc
