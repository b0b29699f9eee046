"""MAT 7.3 (HDF5) uploads never make the reader open anything outside the uploaded bytes.

Each attack is a real HDF5 feature aimed at a secret file beside the upload: external storage
(a dataset's raw data in another file), an external link, a virtual dataset, a soft link into
an external link, and a MATLAB cell array whose object reference leads to external storage.
Each one is first shown to work when h5py opens the file (so the attack is real), then refused
by the reader with a one-line message naming the file and the object's path.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.recordings import RecordingError, read_bytes, read_recording
from tests.utils.mat73 import (
    SECRET,
    SECRET_SAMPLES,
    contains_secret,
    external_storage,
    write_mat73,
    write_secret,
    write_secret_hdf5,
)

h5py = pytest.importorskip("h5py")


def _cls(obj: Any, name: str) -> Any:
    obj.attrs["MATLAB_class"] = np.bytes_(name)
    return obj


def _refused(path: Path, match: str) -> RecordingError:
    """The read of ``path`` (as an upload's bytes) is refused with ``match``; the message
    never quotes the secret."""
    with pytest.raises(RecordingError, match=match) as err:
        read_bytes(path.read_bytes(), path.name)
    text = str(err.value)
    assert "\n" not in text
    assert "s3cr3t" not in text and SECRET.decode() not in text
    return err.value


def _followed_by_h5py(path: Path, name: str) -> np.ndarray:
    """What plain h5py reads at ``name`` (the attack works when it is the secret)."""
    with h5py.File(path, "r") as f:
        return np.asarray(f[name][()])


def test_external_storage_is_refused_naming_the_dataset(tmp_path: Path) -> None:
    secret = write_secret(tmp_path)
    path = write_mat73(tmp_path / "attack.mat", external_storage(secret))
    assert contains_secret(_followed_by_h5py(path, "EMG"))
    _refused(path, r"^attack\.mat: dataset '/EMG' keeps its data in an external file")
    # Read from a path (CLI, analysis of a stored file) the same way.
    with pytest.raises(RecordingError, match=r"dataset '/EMG' keeps its data in an external"):
        read_recording(path)


def test_external_storage_deep_in_a_struct(tmp_path: Path) -> None:
    secret = write_secret(tmp_path)

    def build(f: Any) -> None:
        rec = _cls(f.create_group("rec"), "struct")
        data = _cls(rec.create_group("data"), "struct")
        external_storage(secret)(data)

    path = write_mat73(tmp_path / "nested.mat", build)
    assert contains_secret(_followed_by_h5py(path, "rec/data/EMG"))
    _refused(path, r"^nested\.mat: dataset '/rec/data/EMG' keeps its data in an external file")


def test_external_link_is_refused_before_it_is_followed(tmp_path: Path) -> None:
    other = write_secret_hdf5(tmp_path)

    def build(f: Any) -> None:
        f["EMG"] = h5py.ExternalLink(str(other), "/secret")

    path = write_mat73(tmp_path / "link.mat", build)
    assert contains_secret(_followed_by_h5py(path, "EMG"))
    _refused(path, r"^link\.mat: '/EMG' is an external link to another file")


def test_an_external_link_to_a_missing_file_is_bad_input_not_a_crash(tmp_path: Path) -> None:
    def build(f: Any) -> None:
        f["EMG"] = h5py.ExternalLink(str(tmp_path / "nowhere.h5"), "/x")

    path = write_mat73(tmp_path / "dangling.mat", build)
    _refused(path, r"^dangling\.mat: '/EMG' is an external link to another file")


def test_virtual_dataset_is_refused(tmp_path: Path) -> None:
    other = write_secret_hdf5(tmp_path)

    def build(f: Any) -> None:
        layout = h5py.VirtualLayout(shape=(1, SECRET_SAMPLES.size), dtype="<f8")
        layout[:] = h5py.VirtualSource(str(other), "secret", shape=(1, SECRET_SAMPLES.size))
        _cls(f.create_virtual_dataset("EMG", layout, fillvalue=0.0), "double")

    path = write_mat73(tmp_path / "virtual.mat", build)
    assert contains_secret(_followed_by_h5py(path, "EMG"))
    _refused(path, r"^virtual\.mat: dataset '/EMG' is a virtual dataset")


def test_soft_link_into_an_external_link_is_refused(tmp_path: Path) -> None:
    """The external link hides in ``#refs#`` (never walked itself); a soft link leads there."""
    other = write_secret_hdf5(tmp_path)

    def build(f: Any) -> None:
        f.create_group("#refs#")["x"] = h5py.ExternalLink(str(other), "/secret")
        f["EMG"] = h5py.SoftLink("/#refs#/x")

    path = write_mat73(tmp_path / "soft.mat", build)
    assert contains_secret(_followed_by_h5py(path, "EMG"))
    _refused(path, r"^soft\.mat: soft link '/EMG' leads to an external link to another file")


@pytest.mark.parametrize("kind", ["object", "region"])
def test_cell_reference_to_external_storage_is_refused(tmp_path: Path, kind: str) -> None:
    """MATLAB cell arrays hold object references into ``#refs#``: legitimate, and followed,
    but what they reach is checked like everything else."""
    secret = write_secret(tmp_path)

    def build(f: Any) -> None:
        refs = f.create_group("#refs#")
        external_storage(secret)(refs)
        target = refs["EMG"]
        if kind == "object":
            cell = f.create_dataset("trials", data=np.array([[target.ref]], dtype=h5py.ref_dtype))
        else:
            region = target.regionref[:, :]
            cell = f.create_dataset("trials", data=np.array([[region]], dtype=h5py.regionref_dtype))
        _cls(cell, "cell")

    path = write_mat73(tmp_path / "cell.mat", build)
    with h5py.File(path, "r") as f:
        assert contains_secret(f[f["trials"][0, 0]][()])
    err = _refused(path, r"^cell\.mat: dataset '/trials/0' \(stored at '/#refs#/EMG'\) keeps")
    assert "external file" in str(err)


def test_soft_link_loop_is_refused(tmp_path: Path) -> None:
    def build(f: Any) -> None:
        f["a"] = h5py.SoftLink("/b")
        f["b"] = h5py.SoftLink("/a")

    path = write_mat73(tmp_path / "loop.mat", build)
    _refused(path, r"^loop\.mat: soft link '/a' leads through more than 16 soft links")


def test_dangling_soft_link_is_refused(tmp_path: Path) -> None:
    def build(f: Any) -> None:
        f["EMG"] = h5py.SoftLink("/nothing/here")

    path = write_mat73(tmp_path / "dangling.mat", build)
    _refused(path, r"^dangling\.mat: soft link '/EMG' points at '/nothing/here', which is not")


def test_hard_link_loop_is_refused(tmp_path: Path) -> None:
    def build(f: Any) -> None:
        rec = _cls(f.create_group("rec"), "struct")
        rec["again"] = rec

    path = write_mat73(tmp_path / "cycle.mat", build)
    _refused(path, r"^cycle\.mat: '/rec/again' links back to a group that encloses it")


def test_links_that_fan_out_are_capped(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Ten groups, each linking twice to the next: 2**10 visits from a few KB of file."""
    from app.recordings import _hdf5

    def build(f: Any) -> None:
        groups = [f.create_group(f"g{i}") for i in range(10)]
        for a, b in itertools.pairwise(groups):
            a["left"] = b
            a["right"] = b

    path = write_mat73(tmp_path / "fan.mat", build)
    monkeypatch.setattr(_hdf5, "MAX_OBJECTS", 500)  # the same rule, a smaller test
    _refused(path, r"^fan\.mat: more than 500 objects reached")


def test_in_file_references_and_links_still_read(tmp_path: Path) -> None:
    """What MATLAB writes (cell arrays of char via ``#refs#``) and in-file soft and hard
    links read as before."""
    emg = np.vstack([np.sin(np.arange(300) / 7.0), np.cos(np.arange(300) / 5.0)])  # (2, 300)

    def build(f: Any) -> None:
        refs = f.create_group("#refs#")
        names = []
        for i, label in enumerate(["Biceps_L", "Triceps_L"]):
            chars = np.array([[ord(c)] for c in label], dtype=np.uint16)
            names.append(_cls(refs.create_dataset(f"n{i}", data=chars), "char").ref)
        rec = _cls(f.create_group("rec"), "struct")
        # MATLAB's (300, 2) matrix, stored with reversed dimensions
        _cls(rec.create_dataset("emg", data=emg), "double")
        _cls(rec.create_dataset("labels", data=np.array([names], dtype=h5py.ref_dtype).T), "cell")
        rec["fs"] = f["fs"]  # a hard link to the root's rate
        f["alias"] = h5py.SoftLink("/Biceps")

    path = write_mat73(tmp_path / "ok.mat", build)
    rec = read_bytes(path.read_bytes(), "ok.mat")
    assert {"Biceps_L", "Triceps_L", "Biceps", "alias"} <= set(rec.channels)
    assert rec.channels["Biceps_L"].rate == rec.channels["Triceps_L"].rate == 1000.0
    # The reader may convert units by channel name: compare shapes up to one scale.
    _assert_proportional(rec.channels["alias"].data, np.linspace(0.0, 1.0, 200))
    _assert_proportional(rec.channels["Biceps_L"].data, emg[0])
    _assert_proportional(rec.channels["Triceps_L"].data, emg[1])


def _assert_proportional(actual: np.ndarray, expected: np.ndarray) -> None:
    assert actual.shape == expected.shape
    k = float(np.dot(actual, expected) / np.dot(expected, expected))
    assert k > 0
    np.testing.assert_allclose(actual, k * expected, rtol=1e-12, atol=1e-12 * abs(k))
