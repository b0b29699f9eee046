"""The service finds a comparison's recorded human (its template's analysis), or says why not."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sqlalchemy.orm import Session, sessionmaker

from app.analysis import AnalysisOverlays
from app.db import crud
from app.db.models import Analysis
from app.db.session import make_engine, make_sessionmaker, upgrade
from app.services.human_replay import HumanReplayLoader
from app.viewer.comparison import Comparison


@pytest.fixture
def sessions(tmp_path: Path) -> Iterator[sessionmaker[Session]]:
    url = f"sqlite:///{tmp_path / 'human.db'}"
    upgrade(url)
    engine = make_engine(url)
    yield make_sessionmaker(engine)
    engine.dispose()


def _overlays(with_angles: bool) -> dict[str, Any]:
    """Stored overlays of one file with one lift (1 s -> 2 s), the elbow 10 -> 130 deg."""
    t = np.linspace(0.0, 3.0, 301)
    elbow = np.interp(t, [0.0, 1.0, 2.0, 3.0], [10.0, 10.0, 130.0, 130.0])
    series = {"files.0.angles.elbow_deg": (t, elbow)} if with_angles else {}
    meta = {
        "files": [{"file": "curls.csv"}],
        "lifts": [{"file": "curls.csv", "index": 0, "start_s": 1.0, "top_s": 2.0}],
        "angles": None,
        "emg": [],
    }
    return dict(AnalysisOverlays(meta=meta, series=series).to_arrays())


def _job(sessions: sessionmaker[Session], kind: str, params: dict[str, Any], **done: Any) -> int:
    with sessions() as session:
        resource = {"robot": "curtain_wall_6dof"} if kind == "plan" else {}
        job = crud.create_job(session=session, kind=kind, params=params, resource=resource)
        if done:
            crud.store_result(session=session, job_id=job.id, kind=kind, **done)
        return int(job.id)


def test_the_recorded_human_of_a_plan_and_why_others_have_none(
    sessions: sessionmaker[Session], plan_comparison: Comparison
) -> None:
    settings = {"settings": {"body_height_m": 1.60}}
    good = _job(sessions, "analysis", {}, result=settings, arrays=_overlays(True))
    emg_only = _job(sessions, "analysis", {}, result=settings, arrays=_overlays(False))
    loader = HumanReplayLoader(sessions)

    def load(params: dict[str, Any]) -> Comparison:
        plan_id = _job(sessions, "plan", params)
        return loader(dataclasses.replace(plan_comparison, id=plan_id))

    c = load({"template_analysis_id": good})
    assert c.human is not None and f"analysis #{good}" in c.human_note
    # Lengths from the analysis' body height; the lift's start -> top on the plan's 0 -> T.
    assert c.human.upper_arm == pytest.approx(0.2817 * 1.60 / 1.741, rel=1e-5)
    assert np.degrees(c.human.elbow[[0, -1]]) == pytest.approx([10.0, 130.0], abs=1e-3)
    assert "no shoulder angle" in c.human_note

    paper = load({})
    assert paper.human is None and "paper's default template" in paper.human_note
    inline = load({"template": {"n_lifts": 0}})
    assert inline.human is None and "given inline" in inline.human_note
    no_angles = load({"template_analysis_id": emg_only})
    assert no_angles.human is None and "no lift with recorded elbow angles" in no_angles.human_note
    with sessions() as session:
        session.delete(session.get(Analysis, good))
        session.commit()
    gone = load({"template_analysis_id": good})
    assert gone.human is None and "no longer exists" in gone.human_note
