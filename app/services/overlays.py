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
from typing import TYPE_CHECKING

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from app.db import crud
from app.db.arrays import decode_arrays
from app.db.models import Analysis, JobRecord, RecordingFile, RecordingSession
from app.services.errors import AnalysisPending, NotFoundError
from app.services.jobs import job_to_dict

if TYPE_CHECKING:
    from app.analysis import AnalysisOverlays


class RecordingOverlays:
    """Decoded overlays of recent analyses, most recently used kept (decoding takes ~0.1 s).

    Args:
        sessions: session factory of the service database.
        size: analyses kept in memory.
    """

    def __init__(self, sessions: sessionmaker[Session], *, size: int = 8) -> None:
        self.sessions = sessions
        self.size = size
        self._items: OrderedDict[int, AnalysisOverlays] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, recording_id: int) -> tuple[int, AnalysisOverlays]:
        """The newest finished analysis of a recording and its overlays.

        Returns:
            (analysis id, overlays).

        Raises:
            NotFoundError: no such recording.
            AnalysisPending: no finished analysis with overlays yet (says which job to wait for).
        """
        from app.analysis import AnalysisOverlays  # the science stack, on first use

        with self.sessions() as session:
            analysis_id = self._newest(session, recording_id)
            with self._lock:
                if analysis_id in self._items:
                    self._items.move_to_end(analysis_id)
                    return analysis_id, self._items[analysis_id]
            data = session.scalars(
                select(Analysis.arrays).where(Analysis.id == analysis_id)
            ).first()
        if data is None:  # deleted with its recording meanwhile
            raise AnalysisPending(f"analysis {analysis_id} was just deleted")
        overlays = AnalysisOverlays.from_arrays(decode_arrays(data))
        with self._lock:
            self._items[analysis_id] = overlays
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        return analysis_id, overlays

    @staticmethod
    def _pose_pending(session: Session, recording_id: int) -> None:
        """Raise when the recording's video is still being turned into pose, or when that
        failed and nothing else can be analysed (the page follows or reports that job)."""
        jobs = crud.pose_jobs(session=session, recording_id=recording_id)
        if not jobs:
            return
        job = job_to_dict(max(jobs.values(), key=lambda j: j.id))
        if job["state"] in ("queued", "running"):
            raise AnalysisPending(
                f"the video of recording {recording_id} is being turned into pose (job"
                f" {job['id']}, {job['state']}); it is analysed when that ends",
                job=job,
            )
        has_data = session.scalars(
            select(RecordingFile.id)
            .where(RecordingFile.session_id == recording_id, RecordingFile.role == "recording")
            .limit(1)
        ).first()
        if job["state"] != "succeeded" and has_data is None:
            reason = job["error"] or job["message"]
            raise AnalysisPending(
                f"pose extraction {job['id']} of recording {recording_id} {job['state']}: {reason}",
                job=job,
            )

    @staticmethod
    def _newest(session: Session, recording_id: int) -> int:
        """The id of the recording's newest finished analysis with overlays."""
        if session.get(RecordingSession, recording_id) is None:
            raise NotFoundError(f"recording {recording_id} does not exist")
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
        if analysis_id is not None:
            return int(analysis_id)
        RecordingOverlays._pose_pending(session, recording_id)
        # Never analysed, still running, failed, or analysed by a version that kept no
        # overlays: say which job (if any) the page should wait for or report.
        newest_id = session.scalars(mine.order_by(Analysis.id.desc()).limit(1)).first()
        newest = None if newest_id is None else session.get(JobRecord, newest_id)
        job = None if newest is None else job_to_dict(newest)
        if job is None or job["state"] == "succeeded":
            raise AnalysisPending(
                f"recording {recording_id} has no analysis with plot overlays yet"
            )
        if job["state"] in ("queued", "running"):
            raise AnalysisPending(
                f"analysis {job['id']} of recording {recording_id} is {job['state']}", job=job
            )
        reason = job["error"] or job["message"]
        raise AnalysisPending(
            f"analysis {job['id']} of recording {recording_id} {job['state']}: {reason}", job=job
        )
