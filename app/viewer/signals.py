"""What the recording detail page plots beyond the raw channels: the stored analysis overlays.

The analysis job decimates envelopes, angles and velocities once and stores them with the
analysis (``app.analysis.AnalysisOverlays``), so the page never waits for an analysis. Here the
newest finished analysis of a recording is loaded (decoded once, a few kept in memory) and cut
into windows for the plots. A recording without one yet answers with the analysis job to wait
for, or with none so that the page can start it.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from app.analysis import AnalysisOverlays
    from app.api.deps import Services


class SignalsError(LookupError):
    """The recording does not exist."""


class AnalysisPending(LookupError):
    """The recording has no finished analysis with overlays.

    Attributes:
        job: the newest analysis job of the recording (queued, running, failed or cancelled;
            ``app.api.schemas.Job``), or None when none was ever submitted.
    """

    def __init__(self, message: str, job: dict[str, Any] | None) -> None:
        super().__init__(message)
        self.job = job


class SignalsCache:
    """Decoded overlays of recent analyses, most recently used kept (decoding takes ~0.1 s).

    Args:
        size: analyses kept in memory.
    """

    def __init__(self, size: int = 8) -> None:
        self.size = size
        self._items: OrderedDict[int, AnalysisOverlays] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, services: Services, recording_id: int) -> tuple[int, AnalysisOverlays]:
        """The newest finished analysis of a recording and its overlays.

        Returns:
            (analysis id, overlays).

        Raises:
            SignalsError: no such recording.
            AnalysisPending: no finished analysis with overlays yet (says which job to wait for).
        """
        from sqlalchemy import select

        from app.analysis import AnalysisOverlays
        from app.db.arrays import decode_arrays
        from app.db.models import Analysis, JobRecord, RecordingSession
        from app.jobs.service import job_to_dict

        with services.sessions() as session:
            if session.get(RecordingSession, recording_id) is None:
                raise SignalsError(f"recording {recording_id} does not exist")
            mine = (
                select(Analysis.id)
                .join(JobRecord, JobRecord.id == Analysis.id)
                .where(Analysis.recording_id == recording_id)
            )
            analysis_id = session.scalars(
                mine.where(JobRecord.state == "succeeded", Analysis.arrays.is_not(None))
                .order_by(Analysis.id.desc())
                .limit(1)
            ).first()
            if analysis_id is None:
                # Never analysed, still running, failed, or analysed by a version that kept no
                # overlays: say which job (if any) the page should wait for or report.
                newest_id = session.scalars(mine.order_by(Analysis.id.desc()).limit(1)).first()
                newest = None if newest_id is None else session.get(JobRecord, newest_id)
                job = None if newest is None else job_to_dict(newest)
                if job is None or job["state"] == "succeeded":
                    message = f"recording {recording_id} has no analysis with plot overlays yet"
                    raise AnalysisPending(message, None)
                if job["state"] in ("queued", "running"):
                    message = f"analysis {job['id']} of recording {recording_id} is {job['state']}"
                    raise AnalysisPending(message, job)
                reason = job["error"] or job["message"]
                message = (
                    f"analysis {job['id']} of recording {recording_id} {job['state']}: {reason}"
                )
                raise AnalysisPending(message, job)
            with self._lock:
                if analysis_id in self._items:
                    self._items.move_to_end(analysis_id)
                    return analysis_id, self._items[analysis_id]
            data = session.scalars(
                select(Analysis.arrays).where(Analysis.id == analysis_id)
            ).first()
        if data is None:  # deleted with its recording meanwhile
            raise AnalysisPending(f"analysis {analysis_id} was just deleted", None)
        overlays = AnalysisOverlays.from_arrays(decode_arrays(data))
        with self._lock:
            self._items[analysis_id] = overlays
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        return analysis_id, overlays
