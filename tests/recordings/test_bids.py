"""A BIDS dataset folder (EMG-BIDS): subjects and sessions become labelled recordings.

The dataset is assembled here in the layout the BIDS specification gives
(``sub-<label>/[ses-<label>/]emg/sub-<label>[_ses-<label>]_task-<label>_emg.edf`` with its
``_channels.tsv`` and ``_emg.json``) from the real EMG-BIDS example files of
bids-standard/bids-examples in the shared data (mne-bids is not installed: it would pull in all
of MNE for one test). Values are compared with pyedflib's reading of the same EDF.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from app.recordings import RecordingError, bids_entities, read_bids, read_recording
from tests.conftest import shared_file

CUSTOM = "edf_emg_bids_examples/emg_CustomBipolar/"
MULTI = "edf_emg_bids_examples/emg_Multimodal/"


def _copy(src_dir: Path, stem: str, dest: Path, new_stem: str) -> None:
    dest.mkdir(parents=True, exist_ok=True)
    for suffix in ("_emg.edf", "_channels.tsv", "_emg.json"):
        shutil.copy(src_dir / f"{stem}{suffix}", dest / f"{new_stem}{suffix}")


def _dataset(root: Path, *, with_bad: bool = False) -> Path:
    custom = shared_file(CUSTOM + "sub-01_task-holdWeight_emg.edf").parent
    shutil.copy(custom / "dataset_description.json", root / "dataset_description.json")
    (root / "participants.tsv").write_text(
        "participant_id\tage\tsex\nsub-01\t34\tF\nsub-02\t51\tM\n", encoding="utf-8"
    )
    stem = "sub-01_task-holdWeight"
    _copy(custom, stem, root / "sub-01/ses-pre/emg", "sub-01_ses-pre_task-holdWeight")
    _copy(custom, stem, root / "sub-01/ses-post/emg", "sub-01_ses-post_task-holdWeight_run-2")
    _copy(custom, stem, root / "sub-02/emg", "sub-02_task-curl")
    if with_bad:  # the Multimodal example's EDF (255-byte fixed header), cut short
        multi = shared_file(MULTI + "sub-01_task-pullstand_emg.edf").parent
        _copy(multi, "sub-01_task-pullstand", root / "sub-03/emg", "sub-03_task-pullstand")
        bad = root / "sub-03/emg/sub-03_task-pullstand_emg.edf"
        bad.chmod(0o644)
        bad.write_bytes(bad.read_bytes()[:-100])
    (root / "derivatives/sub-01/emg").mkdir(parents=True)  # derivatives are not raw data
    return root


def test_bids_folder_gives_labelled_recordings(tmp_path: Path, shared_data: Path) -> None:
    pyedflib = pytest.importorskip("pyedflib")
    root = _dataset(tmp_path)
    ds = read_bids(root)
    assert ds.description["Name"] == "EMG Custom Bipolar Example"
    assert ds.subjects == ["01", "02"]
    labels = [
        (r.metadata["subject"], r.metadata["session"], r.metadata["task"]) for r in ds.recordings
    ]
    assert labels == [
        ("01", "post", "holdWeight"),
        ("01", "pre", "holdWeight"),
        ("02", None, "curl"),
    ]
    post = ds.recordings[0]
    assert post.metadata["run"] == "2"
    assert post.source == "sub-01/ses-post/emg/sub-01_ses-post_task-holdWeight_run-2_emg.edf"
    assert ds.recordings[2].metadata["participant"]["age"] == "51"
    # the EDF reader read each file with its own sidecars (EDF header: uV)
    with pyedflib.EdfReader(str(shared_file(CUSTOM + "sub-01_task-holdWeight_emg.edf"))) as f:
        raw = f.readSignal(0)
    for rec in ds.recordings:
        ch = rec.channels["EMG1"]
        assert ch.kind == "emg" and ch.rate == 2000.0
        np.testing.assert_allclose(ch.data, raw * 1e-6, rtol=1e-12)
        assert rec.metadata["bids"]
    # the same as reading one file alone
    alone = read_recording(root / "sub-02/emg/sub-02_task-curl_emg.edf")
    np.testing.assert_array_equal(
        alone.channels["EMG1"].data, ds.recordings[2].channels["EMG1"].data
    )
    # filters
    only = read_bids(root, subjects=["sub-01"], sessions=["pre"])
    assert [r.metadata["session"] for r in only.recordings] == ["pre"]
    assert [r.metadata["subject"] for r in read_bids(root, tasks=["curl"]).recordings] == ["02"]


def test_bids_unreadable_file_named_or_skipped(tmp_path: Path, shared_data: Path) -> None:
    root = _dataset(tmp_path, with_bad=True)
    with pytest.raises(RecordingError, match=r"sub-03/emg/sub-03_task-pullstand_emg\.edf: .*255"):
        read_bids(root)
    ds = read_bids(root, skip_unreadable=True)
    assert ds.subjects == ["01", "02"]
    assert list(ds.skipped) == ["sub-03/emg/sub-03_task-pullstand_emg.edf"]


def test_bids_bad_folders(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match=r"no dataset_description\.json"):
        read_bids(tmp_path)
    (tmp_path / "dataset_description.json").write_text(json.dumps({"Name": "x"}))
    with pytest.raises(RecordingError, match="has no EMG recording"):
        read_bids(tmp_path)
    (tmp_path / "sub-02/emg").mkdir(parents=True)
    (tmp_path / "sub-02/emg/sub-01_task-curl_emg.edf").write_bytes(b"0       ")
    with pytest.raises(RecordingError, match="in folder sub-02 but names subject sub-01"):
        read_bids(tmp_path)


def test_bids_entities() -> None:
    assert bids_entities("sub-01_ses-pre_task-curl_acq-wireless_run-3_emg.edf") == {
        "sub": "01", "ses": "pre", "task": "curl", "acq": "wireless", "run": "3",
    }  # fmt: skip
