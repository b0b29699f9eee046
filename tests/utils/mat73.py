"""MATLAB 7.3 files written with h5py, and HDF5 files that point outside themselves.

A MAT 7.3 file is an HDF5 file with a 512-byte user block that starts with the MATLAB header
text. The attacks below aim at a secret file written beside the upload: its bytes are chosen so
that, read as float64 samples, they can be recognised in any channel.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

#: The secret's content: 8-byte aligned text, so it reads as whole float64 samples.
SECRET = b"root:x:0:0:BIOPLAN_API_TOKEN=s3cr3t-t0ken-never-served!".ljust(64, b"#")
#: The secret read as float64 samples, as a reader following the reference would see them.
SECRET_SAMPLES = np.frombuffer(SECRET, dtype="<f8")


def _cls(obj: Any, name: str) -> Any:
    obj.attrs["MATLAB_class"] = np.bytes_(name)
    return obj


def write_mat73(path: Path, build: Callable[[Any], None]) -> Path:
    """Write ``path`` as MAT 7.3: ``build(h5py.File)`` fills it, a rate ``fs`` and one honest
    channel ``Biceps`` (1000 Hz, 200 samples) are added, then the MATLAB header is written."""
    import h5py

    with h5py.File(path, "w", userblock_size=512) as f:
        _cls(f.create_dataset("fs", data=np.array([[1000.0]])), "double")
        _cls(f.create_dataset("Biceps", data=np.linspace(0.0, 1.0, 200)[None, :]), "double")
        build(f)
    with path.open("r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: test".ljust(116, b" "))
    return path


def write_secret(folder: Path) -> Path:
    """The server file an attack wants to read."""
    secret = folder / "secret.bin"
    secret.write_bytes(SECRET)
    return secret


def write_secret_hdf5(folder: Path) -> Path:
    """An HDF5 file elsewhere on the server with the secret as dataset ``/secret``."""
    import h5py

    path = folder / "secret.h5"
    with h5py.File(path, "w") as f:
        _cls(f.create_dataset("secret", data=SECRET_SAMPLES[None, :]), "double")
    return path


def external_storage(secret: Path) -> Callable[[Any], None]:
    """A dataset ``EMG`` whose raw data is the secret file (HDF5 external storage)."""

    def build(f: Any) -> None:
        n = len(SECRET) // 8
        ds = f.create_dataset("EMG", (1, n), "<f8", external=[(str(secret), 0, len(SECRET))])
        _cls(ds, "double")

    return build


def contains_secret(values: Any) -> bool:
    """Whether samples hold the secret's samples in a row, at any scale (a reader may have
    converted units)."""
    arr = np.asarray(values, dtype=np.float64).ravel()
    n = SECRET_SAMPLES.size
    for i in range(arr.size - n + 1):
        ratio = arr[i : i + n] / SECRET_SAMPLES
        if ratio[0] != 0 and np.allclose(ratio, ratio[0], rtol=1e-9, atol=0.0):
            return True
    return False
