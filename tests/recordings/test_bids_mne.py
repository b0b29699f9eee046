"""BIDS datasets written by MNE-BIDS (the reference writer) read back through BioPlan, and the
condition a recording's file names or sidecars name (issue 29)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from app.recordings import condition_from_files, read_bids
from tests.recordings._writers import emg_like

RATE = 2000.0


def _write_dataset(root: Path) -> dict[tuple[str, str], np.ndarray]:
    """Two subjects x two acquisitions of two EMG channels [V], written by mne-bids as EDF;
    returns the written samples by (subject, acquisition)."""
    mne = pytest.importorskip("mne")
    mne_bids = pytest.importorskip("mne_bids")
    pytest.importorskip("edfio")  # mne's EDF export
    written = {}
    for k, (sub, acq) in enumerate(
        [("01", "neutral"), ("01", "supinated"), ("02", "neutral"), ("02", "supinated")]
    ):
        data = np.vstack(
            [emg_like(4000, RATE, seed=2 * k) * 0.5, emg_like(4000, RATE, seed=2 * k + 1) * 0.2]
        )
        info = mne.create_info(["biceps", "triceps"], RATE, ["emg", "emg"])
        raw = mne.io.RawArray(data, info, verbose=False)
        path = mne_bids.BIDSPath(
            subject=sub, task="curl", acquisition=acq, datatype="emg", root=root
        )
        with warnings.catch_warnings():  # no electrode positions or events: said, not needed
            warnings.simplefilter("ignore", RuntimeWarning)
            mne_bids.write_raw_bids(
                raw, path, format="EDF", allow_preload=True, emg_placement="Measured",
                verbose=False,
            )  # fmt: skip
        written[(sub, acq)] = data
    return written


def test_mne_bids_dataset_reads_back_sample_for_sample(tmp_path: Path) -> None:
    pyedflib = pytest.importorskip("pyedflib")
    written = _write_dataset(tmp_path / "ds")
    ds = read_bids(tmp_path / "ds")
    assert ds.subjects == ["01", "02"]
    got = {(r.metadata["subject"], r.metadata["acquisition"]): r for r in ds.recordings}
    assert set(got) == set(written)
    for key, data in written.items():
        rec = got[key]
        assert rec.metadata["task"] == "curl" and rec.format == "edf"
        assert list(rec.channels) == ["biceps", "triceps"]  # names from channels.tsv
        edf = tmp_path / "ds" / str(rec.source)
        with pyedflib.EdfReader(str(edf)) as ref:  # the writer's scaling, read independently
            heads = [ref.getSignalHeader(i) for i in range(2)]
        for row, ch, head in zip(data, rec.channels.values(), heads, strict=True):
            assert ch.kind == "emg" and ch.rate == RATE and ch.unit == "V"
            assert ch.data.shape == row.shape
            # EDF stores integers: within one quantisation step of the written volts
            assert head["dimension"] == "uV"
            step = (
                1e-6
                * (head["physical_max"] - head["physical_min"])
                / (head["digital_max"] - head["digital_min"])
            )
            assert np.max(np.abs(ch.data - row)) <= step
            assert np.corrcoef(ch.data, row)[0, 1] > 0.999999


def test_mne_bids_file_names_give_the_condition(tmp_path: Path) -> None:
    _write_dataset(tmp_path / "ds")
    names = sorted(p.name for p in (tmp_path / "ds").rglob("*_emg.edf"))
    assert names[0] == "sub-01_task-curl_acq-neutral_emg.edf"
    assert condition_from_files([names[0]]) == (
        "neutral",
        "the acq-neutral (BIDS acquisition) entity of sub-01_task-curl_acq-neutral_emg.edf",
    )


def test_condition_rule_order_and_disagreement() -> None:
    side = {"s_emg.json": json.dumps({"Condition": "heavy", "TaskName": "curl"}).encode()}
    # cond- beats the sidecar, the sidecar beats acq-, acq- beats task-
    assert condition_from_files(["sub-1_task-curl_acq-x_cond-light_emg.edf"], side) == (
        "light",
        "the cond-light entity of sub-1_task-curl_acq-x_cond-light_emg.edf",
    )
    assert condition_from_files(["sub-1_task-curl_acq-x_emg.edf"], side) == (
        "heavy",
        "the Condition field of s_emg.json",
    )
    assert condition_from_files(["sub-1_task-curl_emg.edf"]) == (
        "curl",
        "the task-curl (BIDS task) entity of sub-1_task-curl_emg.edf",
    )
    assert condition_from_files(["S01_cond-fatigued.csv"]) == (
        "fatigued",
        "the cond-fatigued entity of S01_cond-fatigued.csv",
    )
    # two files that agree name it; two that disagree name none
    assert condition_from_files(["a_cond-x.csv", "b_cond-x.csv"]) == (
        "x",
        "the cond-x entity of a_cond-x.csv, b_cond-x.csv",
    )
    assert condition_from_files(["a_cond-x.csv", "b_cond-y.csv"]) is None
    assert condition_from_files(["S01_curls.csv", "second.cond.csv"]) is None
