"""The recorded human of a plan or simulation, for the viewer: the lift of its template's analysis.

A plan (or simulation) planned with ``template_analysis_id`` was shaped by that analysis' lifts;
the viewer replays the first lift with recorded angles beside the robot
(``app.analysis.replay_from_overlays``). Without one (the paper's default template, an inline
template, a deleted analysis, lifts found from EMG only) the comparison says why instead.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from sqlalchemy.orm import Session, sessionmaker, undefer

from app.analysis import AnalysisOverlays, OverlaysError, ReplayError, replay_from_overlays
from app.db.arrays import decode_arrays
from app.db.models import Analysis, JobRecord, RecordingSession
from app.viewer.comparison import Comparison, template_provenance


class HumanReplayLoader:
    """Attaches the recorded human to a comparison (``PreparedCache(..., human=this)``).

    Args:
        sessions: session factory of the service database.
        lift: which lift with recorded angles to replay (0 = the first).
    """

    def __init__(self, sessions: sessionmaker[Session], *, lift: int = 0) -> None:
        self.sessions = sessions
        self.lift = lift

    def __call__(self, comparison: Comparison) -> Comparison:
        """``comparison`` with ``human`` set, or with ``human_note`` saying why there is none."""
        with self.sessions() as session:
            job = session.get(JobRecord, comparison.id)
            params: dict[str, Any] = dict(job.params) if job is not None else {}
            analysis_id = params.get("template_analysis_id")
            if analysis_id is None:
                inline = params.get("template")
                comparison = dataclasses.replace(
                    comparison,
                    template=template_provenance(
                        comparison.result, template=inline, inline=inline is not None
                    ),
                )
                return dataclasses.replace(comparison, human_note=_why_none(comparison, params))
            row = session.get(Analysis, int(analysis_id), options=[undefer(Analysis.arrays)])
            if row is not None:
                comparison = dataclasses.replace(
                    comparison,
                    template=template_provenance(
                        comparison.result,
                        template=row.template,
                        analysis_id=int(analysis_id),
                        recording=_recording_name(session, row.recording_id),
                    ),
                )
            if row is None or row.arrays is None:
                note = f"no recorded human: analysis #{analysis_id} no longer exists"
                return dataclasses.replace(comparison, human_note=note)
            arrays, result = decode_arrays(row.arrays), dict(row.result or {})
        height = float((result.get("settings") or {}).get("body_height_m") or 1.75)
        try:
            overlays = AnalysisOverlays.from_arrays(arrays)
            human = replay_from_overlays(overlays, comparison.t, lift=self.lift, body_height=height)
        except (OverlaysError, ReplayError) as exc:
            note = f"no recorded human: analysis #{analysis_id}: {exc}"
            return dataclasses.replace(comparison, human_note=note)
        note = f"recorded human from analysis #{analysis_id}: {human.describe()}"
        if human.notes:
            note += "; " + "; ".join(human.notes)
        return dataclasses.replace(comparison, human=human, human_note=note)


def _recording_name(session: Session, recording_id: int | None) -> str | None:
    """How to name a recording: "recording #3 “label”" (or its subject)."""
    if recording_id is None:
        return None
    rec = session.get(RecordingSession, recording_id)
    if rec is None:
        return None
    name = rec.label or rec.subject
    return f"recording #{rec.id}" + (f" “{name}”" if name else "")


def _why_none(comparison: Comparison, params: dict[str, object]) -> str:
    if params.get("template") is not None:
        return "no recorded human: the template was given inline, without its recording"
    conditions = comparison.result.get("conditions") or {}
    if conditions.get("template_is_paper_default", True):
        return "no recorded human: this comparison used the paper's default template"
    return "no recorded human: the template's analysis is not known"
