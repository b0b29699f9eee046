"""A BIDS dataset folder (EMG-BIDS): every subject's and session's EMG recordings, labelled.

A BIDS dataset has ``dataset_description.json`` at its root and, per subject (and optional
session), ``sub-<label>/[ses-<label>/]emg/sub-<label>[_ses-<label>]_task-<label>[_acq-<label>]
[_run-<index>]_emg.edf`` (or ``.bdf``) with its ``_channels.tsv`` and ``_emg.json`` sidecars
beside it. Each data file becomes one :class:`Recording` (the EDF reader joins the sidecars),
labelled from its file name's entities: ``metadata["subject"]``, ``["session"]``,
``["task"]``, ``["run"]``, ``["acquisition"]`` (None when absent), plus the subject's row of
``participants.tsv`` in ``metadata["participant"]``. ``Recording.source`` is the file's path
relative to the dataset root.
"""

from __future__ import annotations

import csv
import io
import json
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app.recordings.types import Recording, RecordingError

#: Data files of EMG-BIDS that BioPlan reads (EDF and BDF; BrainVision is not supported).
BIDS_EMG_SUFFIXES = ("_emg.edf", "_emg.bdf")
_ENTITY = re.compile(r"^(?P<key>[a-zA-Z]+)-(?P<value>[a-zA-Z0-9]+)$")
_LABELS = {"sub": "subject", "ses": "session", "task": "task", "acq": "acquisition", "run": "run"}


@dataclass
class BidsDataset:
    """What :func:`read_bids` found.

    Attributes:
        root: the dataset folder.
        description: ``dataset_description.json`` (Name, BIDSVersion, License...).
        recordings: one per EMG data file, sorted by subject, session, task, run.
        skipped: relative path -> why, for files left out with ``skip_unreadable=True``.
    """

    root: Path
    description: dict[str, Any]
    recordings: list[Recording] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)

    @property
    def subjects(self) -> list[str]:
        return sorted({str(r.metadata["subject"]) for r in self.recordings})


def bids_entities(filename: str) -> dict[str, str]:
    """``sub-01_ses-2_task-curl_run-1_emg.edf`` -> ``{"sub": "01", "ses": "2", ...}``."""
    stem = filename.split(".", 1)[0]
    out: dict[str, str] = {}
    for part in stem.split("_")[:-1]:  # the last part is the suffix ("emg")
        m = _ENTITY.match(part)
        if m:
            out[m["key"]] = m["value"]
    return out


#: Where a recording's condition comes from when the user gives none (first match wins).
CONDITION_RULE = (
    "a cond-<label> entity in a file name, else the Condition field of a BIDS _emg.json"
    " sidecar, else the acq-<label> entity, else the task-<label> entity; all files of the"
    " session must agree"
)
_ENTITY_ANYWHERE = re.compile(r"(?:^|_)(?P<key>cond|acq|task)-(?P<value>[a-zA-Z0-9]+)(?=_|\.|$)")


def condition_from_files(
    names: Iterable[str], sidecars: dict[str, bytes] | None = None
) -> tuple[str, str] | None:
    """The condition named by an upload's file names or BIDS sidecars (:data:`CONDITION_RULE`).

    Args:
        names: the recording files' names (``sub-01_task-curl_acq-supinated_emg.edf``; the
            entities are also found in non-BIDS names such as ``S01_cond-heavy.csv``).
        sidecars: ``_emg.json`` sidecars by file name (their ``Condition`` string is used).

    Returns:
        (condition, where it came from in words), or None when nothing names one or the
        files disagree at the first level that names one.
    """
    files = list(names)
    found: dict[str, dict[str, str]] = {"cond": {}, "json": {}, "acq": {}, "task": {}}
    for name in files:
        for m in _ENTITY_ANYWHERE.finditer(name):
            found[m["key"]].setdefault(name, m["value"][:100])  # the column holds 100
    for side, data in (sidecars or {}).items():
        if not side.lower().endswith("_emg.json"):
            continue
        try:
            info = json.loads(data.decode("utf-8-sig"))
        except (UnicodeDecodeError, ValueError):
            continue
        value = info.get("Condition") if isinstance(info, dict) else None
        if isinstance(value, str) and value.strip():
            found["json"][side] = value.strip()[:100]
    words = {
        "cond": "the cond-{v} entity of {f}",
        "json": "the Condition field of {f}",
        "acq": "the acq-{v} (BIDS acquisition) entity of {f}",
        "task": "the task-{v} (BIDS task) entity of {f}",
    }
    for level, by_file in found.items():
        values = set(by_file.values())
        if len(values) == 1:
            value = values.pop()
            where = ", ".join(sorted(by_file))
            return value, words[level].format(v=value, f=where)
        if len(values) > 1:
            return None
    return None


def _participants(root: Path) -> dict[str, dict[str, str]]:
    path = root / "participants.tsv"
    if not path.is_file():
        return {}
    text = path.read_text(encoding="utf-8-sig", errors="replace")
    rows = csv.DictReader(io.StringIO(text), delimiter="\t")
    out: dict[str, dict[str, str]] = {}
    for row in rows:
        pid = (row.get("participant_id") or "").strip()
        if pid:
            out[pid.removeprefix("sub-")] = {k: (v or "").strip() for k, v in row.items() if k}
    return out


def _wanted(value: str | None, allowed: Iterable[str] | None) -> bool:
    if allowed is None:
        return True
    return value is not None and value in {str(a).removeprefix("sub-") for a in allowed}


def _check_root(root: Path) -> dict[str, Any]:
    name = root.name or str(root)
    if not root.is_dir():
        raise RecordingError("is not a folder", file=name, expected="a BIDS dataset folder")
    desc = root / "dataset_description.json"
    if not desc.is_file():
        raise RecordingError(
            "has no dataset_description.json",
            file=name,
            expected="a BIDS dataset root (dataset_description.json, sub-<label>/ folders)",
        )
    try:
        description = json.loads(desc.read_text(encoding="utf-8-sig"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise RecordingError(
            f"dataset_description.json is not valid JSON: {exc}", file=name, expected="JSON"
        ) from None
    if not isinstance(description, dict):
        raise RecordingError("dataset_description.json is not an object", file=name)
    return description


def _data_files(root: Path) -> list[Path]:
    files = [
        p
        for p in root.rglob("*")
        if p.is_file()
        and p.name.lower().endswith(BIDS_EMG_SUFFIXES)
        and not any(part.startswith((".", "derivatives", "sourcedata")) for part in
                    p.relative_to(root).parts[:-1])
    ]  # fmt: skip
    return sorted(files)


def read_bids(
    root: str | Path,
    *,
    subjects: Iterable[str] | None = None,
    sessions: Iterable[str] | None = None,
    tasks: Iterable[str] | None = None,
    skip_unreadable: bool = False,
) -> BidsDataset:
    """Read every EMG recording of a BIDS dataset folder, labelled by subject, session, task.

    Args:
        root: the dataset folder (holding ``dataset_description.json``).
        subjects, sessions, tasks: only these labels (``"01"`` or ``"sub-01"``); None = all.
        skip_unreadable: leave files that cannot be read out (listed in ``skipped`` with the
            reason) instead of raising.

    Returns:
        The dataset: description, labelled recordings, skipped files.

    Raises:
        RecordingError: not a BIDS root, no EMG data file (after the filters), a file name
            without a ``sub-`` entity or in another subject's folder, or (unless
            ``skip_unreadable``) a file that cannot be read; the message names the file.
    """
    from app.recordings._read import read_recording

    base = Path(root)
    dataset = BidsDataset(root=base, description=_check_root(base))
    participants = _participants(base)
    for path in _data_files(base):
        rel = path.relative_to(base).as_posix()
        entities = bids_entities(path.name)
        labels = {_LABELS[k]: entities.get(k) for k in _LABELS}
        _check_subject(rel, labels["subject"], path.relative_to(base).parts)
        if not (
            _wanted(labels["subject"], subjects)
            and _wanted(labels["session"], sessions)
            and _wanted(labels["task"], tasks)
        ):
            continue
        try:
            rec = read_recording(path)
        except RecordingError as exc:
            if not skip_unreadable:
                raise RecordingError(str(exc).replace(path.name, rel, 1)) from exc
            dataset.skipped[rel] = str(exc)
            continue
        rec.source = rel
        rec.metadata.update(labels)
        rec.metadata["bids_path"] = rel
        if labels["task"] is None:
            rec.metadata["warnings"].append(f"{rel}: no task- entity in the file name")
        if labels["subject"] in participants:
            rec.metadata["participant"] = participants[str(labels["subject"])]
        dataset.recordings.append(rec)
    if not dataset.recordings and not dataset.skipped:
        raise RecordingError(
            "has no EMG recording" + (" matching the filters" if subjects or sessions or tasks
                                      else ""),
            file=base.name or str(base),
            expected="sub-<label>/[ses-<label>/]emg/sub-<label>_..._task-<label>_emg.edf (or .bdf)",
        )  # fmt: skip
    dataset.recordings.sort(
        key=lambda r: tuple(str(r.metadata.get(k) or "") for k in ("subject", "session", "task",
                                                                   "run", "bids_path"))
    )  # fmt: skip
    return dataset


def _check_subject(rel: str, subject: str | None, parts: tuple[str, ...]) -> None:
    if subject is None:
        raise RecordingError(
            "file name has no sub- entity", file=rel, expected="sub-<label>_..._emg.edf"
        )
    folder = next((p for p in parts[:-1] if p.startswith("sub-")), None)
    if folder is not None and folder != f"sub-{subject}":
        raise RecordingError(
            f"is in folder {folder} but names subject sub-{subject}",
            file=rel,
            expected="the file's sub- entity to match its folder",
        )
