"""The cohort job: compare groups of stored recordings (``bioplan cohort``)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, overload

from app.jobs.tasks.recordings import read_upload
from app.jobs.tasks.types import CohortPayload, JobResult, UploadedFile
from app.jsonsafe import json_safe
from app.progress import ProgressFn, no_progress, report

if TYPE_CHECKING:
    from app.analysis.cohort import CohortOptions, CohortResult
    from app.recordings import Recording


class _CohortFile(UploadedFile, total=False):
    """A recording file of a cohort group, with its recording's id and excluded channels."""

    recording_id: int
    exclude_channels: list[str]


class _GroupFiles(Sequence["Recording"]):
    """One group's recording files, read when the comparison reaches each (one recording's
    arrays held at a time), reporting progress per recording file."""

    def __init__(self, files: list[_CohortFile], counter: list[int], total: int,
                 progress: ProgressFn, emg_rate: float | None) -> None:  # fmt: skip
        self.files, self.counter, self.total = files, counter, total
        self.progress, self.emg_rate = progress, emg_rate

    def __len__(self) -> int:
        return len(self.files)

    @overload
    def __getitem__(self, i: int) -> Recording: ...
    @overload
    def __getitem__(self, i: slice) -> Sequence[Recording]: ...
    def __getitem__(self, i: int | slice) -> Recording | Sequence[Recording]:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        f = self.files[i]
        done = self.counter[0]
        report(self.progress, "analyse", done, self.total, fraction=0.95 * done / self.total,
               message=f"analysing {f['name']} (recording #{f['recording_id']})")  # fmt: skip
        self.counter[0] += 1
        read_options = dict(f["read_options"])
        if self.emg_rate is not None:  # as ``bioplan cohort --emg-rate``: every file reads so
            read_options["emg_rate"] = self.emg_rate
        with_options: _CohortFile = {**f, "read_options": read_options}
        rec = read_upload(with_options, {})
        excluded = {str(n).strip().lower() for n in f.get("exclude_channels", ())}
        for name in [n for n in rec.channels if n.strip().lower() in excluded]:
            del rec.channels[name]
        return rec


def cohort(payload: CohortPayload, progress: ProgressFn = no_progress) -> JobResult:
    """Compare groups of stored recordings (``bioplan cohort``).

    Payload: ``groups`` {name: [{"recording_id", "subject" (stored, or None), "exclude_channels",
    "files": [as :func:`analyse`'s]}]}, ``options``: the fields of ``CohortOptions``. Every
    recording file is one measured recording; a recording's stored subject, where it has one,
    is its subject (pairing by subject uses it), else the library's rule.

    Progress: stage ``analyse``, one unit per recording file; then ``compare``.

    Returns:
        ``{"result": CohortResult.to_dict() + "recording_ids"}`` (aligned with
        ``recordings``).
    """
    from app.analysis.cohort import CohortOptions, cohort_statistics

    options = CohortOptions(**payload["options"])
    files: dict[str, list[_CohortFile]] = {}
    for name, recs in payload["groups"].items():
        files[name] = [
            {**f, "recording_id": r["recording_id"], "exclude_channels": r["exclude_channels"]}
            for r in recs
            for f in r["files"]
        ]
    total = max(sum(len(v) for v in files.values()), 1)
    counter = [0]
    groups = {
        name: _GroupFiles(fs, counter, total, progress, options.emg_rate)
        for name, fs in files.items()
    }
    result = cohort_statistics(groups, options)
    if any(r.get("subject") for recs in payload["groups"].values() for r in recs):
        report(progress, "compare", 0, 1, fraction=0.96, message="pairing by stored subjects")
        result = _with_stored_subjects(result, payload, options)
    report(progress, "done", 1, 1, message="compared")
    out = json_safe(result.to_dict())
    out["recording_ids"] = [f["recording_id"] for fs in files.values() for f in fs]
    return {"result": out}


def _with_stored_subjects(
    result: CohortResult, payload: CohortPayload, options: CohortOptions
) -> CohortResult:
    """The comparison again with each recording's stored subject (no analysis rerun)."""
    from app.analysis.cohort import compare_groups

    subjects = [r.get("subject") for recs in payload["groups"].values() for r in recs
                for _ in r["files"]]  # fmt: skip
    measures = [
        m if not s else replace(m, subject=str(s), subject_from="the recording's stored subject")
        for m, s in zip(result.recordings, subjects, strict=True)
    ]
    again = compare_groups(measures, options)
    rule = str(again.subject_rule).removeprefix("subject = ")
    return replace(
        again,
        subject_rule="subject = the recording's stored subject (set at upload or by PATCH) where"
        f" it has one, else {rule}",
    )
