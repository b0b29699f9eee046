"""Figures: offline HTML with one local plotly.js, EMG and kinematics pages per recording."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from app.analysis import analyze_recordings, write_analysis_plots
from app.analysis.plots import _envelope_decimate
from tests.analysis._data import pyomeca_c3d


def test_pages_are_offline_and_show_phases(tmp_path: Path) -> None:
    result = analyze_recordings([pyomeca_c3d()], load_mass=2.0)
    files = write_analysis_plots(result, tmp_path / "figs")
    names = sorted(p.name for p in files)
    assert names == [
        "01_markers_analogs.c3d_emg.html",
        "01_markers_analogs.c3d_kinematics.html",
        "plotly.min.js",
    ]
    assert (tmp_path / "figs" / "plotly.min.js").stat().st_size > 1_000_000
    for page in files[:2]:
        html = page.read_text()
        assert re.search(r'<script[^>]* src="plotly.min.js"', html)
        assert "cdn.plot.ly" not in html
    kin = (tmp_path / "figs" / "01_markers_analogs.c3d_kinematics.html").read_text()
    # One shaded rectangle per phase and subplot row.
    n_phases = sum(len(r.phases) for r in result.lifts)
    shapes = re.search(r'"shapes":(\[.*?\])', kin)
    assert shapes is not None
    rects = [s for s in json.loads(shapes.group(1)) if s.get("type") == "rect"]
    assert len(rects) == 2 * n_phases


def test_decimation_keeps_extremes() -> None:
    t = np.arange(100_000) / 2000.0
    x = np.sin(t) * 0.01
    x[12_345] = 5.0
    x[77_777] = -4.0
    td, xd = _envelope_decimate(t, x, max_points=2000)
    assert len(td) <= 2000
    assert xd.max() == 5.0
    assert xd.min() == -4.0
    assert np.all(np.diff(td) >= 0)
