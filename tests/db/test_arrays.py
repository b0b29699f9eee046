"""Array storage round trips exactly and refuses anything it did not write."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from app.db.arrays import ArrayDecodeError, decode_array, decode_arrays, encode_array, encode_arrays


@settings(max_examples=50, deadline=None)
@given(
    hnp.arrays(
        dtype=st.sampled_from([np.float64, np.float32, np.int64, np.uint8, np.bool_]),
        shape=hnp.array_shapes(min_dims=0, max_dims=3, max_side=20),
    )
)
def test_round_trip_is_exact(a: np.ndarray) -> None:
    b = decode_array(encode_array(a))
    assert b.dtype == a.dtype and b.shape == a.shape
    np.testing.assert_array_equal(a, b)  # NaN == NaN here, bit for bit otherwise


def test_storage_is_compact_binary_not_json() -> None:
    # A ramp compresses well; raw float64 would be 8 bytes a sample and JSON about 20.
    a = np.linspace(0.0, 1.0, 100_000)
    blob = encode_array(a)
    assert len(blob) < a.nbytes
    noise = np.random.default_rng(0).standard_normal(100_000)
    assert len(encode_array(noise)) < 1.05 * noise.nbytes + 200


def test_named_arrays_round_trip() -> None:
    arrays = {"t": np.linspace(0, 1, 11), "q": np.arange(22.0).reshape(11, 2)}
    out = decode_arrays(encode_arrays(arrays))
    assert set(out) == {"t", "q"}
    for k, v in arrays.items():
        np.testing.assert_array_equal(out[k], v)


def test_rejects_foreign_bytes_and_object_arrays() -> None:
    with pytest.raises(ArrayDecodeError, match="unknown header"):
        decode_array(b"not an array")
    with pytest.raises(ArrayDecodeError, match="corrupt"):
        decode_array(b"BPA1" + b"\x00" * 10)
    with pytest.raises(ArrayDecodeError, match="corrupt"):
        decode_arrays(b"PK\x03\x04garbage")
    with pytest.raises(TypeError, match="numeric"):
        encode_array(np.array([{"a": 1}], dtype=object))
