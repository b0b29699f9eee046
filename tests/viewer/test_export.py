"""Exports: the recorded 3-D scene (viser's serializer) and the Plotly report."""

from __future__ import annotations

import base64
import re

import numpy as np
import pytest

from app.viewer.comparison import Comparison
from app.viewer.export import report_html, scene_html
from app.viewer.scene import PreparedComparison


def _recording(page: str) -> dict[str, object]:
    """Decode the .viser recording viser embeds in its standalone page."""
    import msgspec
    import zstandard

    match = re.search(r'window\.__VISER_EMBED_DATA__="([A-Za-z0-9+/=]+)"', page)
    assert match, "no embedded scene in the page"
    raw = base64.b64decode(match.group(1))
    size = int.from_bytes(raw[:8], "little")
    inner = zstandard.ZstdDecompressor().decompress(raw[8:], max_output_size=size)
    assert len(inner) == size
    meta_len = int.from_bytes(inner[:8], "little")
    decoded: dict[str, object] = msgspec.msgpack.decode(inner[8 : 8 + meta_len])
    return decoded


def test_scene_export_records_the_whole_motion(plan_comparison: Comparison) -> None:
    prepared = PreparedComparison(plan_comparison)
    page = scene_html(prepared, fps=20.0)
    assert page.lstrip().lower().startswith("<!doctype html")
    assert "<title>Plan #7: curtain_wall_6dof" in page
    # Offline: no script or stylesheet from the network.
    assert not re.search(r'<script[^>]+src="https?://', page)
    rec = _recording(page)
    # 1 s at 20 fps = 21 poses, 1/20 s apart, then the 0.6 s hold.
    assert rec["durationSeconds"] == pytest.approx(21 / 20 + 0.6)
    messages = rec["messages"]
    assert isinstance(messages, list)
    times = sorted({t for t, _ in messages})
    assert len(times) >= 21
    # The elbow frame of the optimised robot is posed at every recorded instant.
    elbow = "/bioplan/optimized/pedestal/turret/upper_arm/forearm"
    poses = [m for t, m in messages if m.get("name") == elbow and "wxyz" in str(m)]
    assert len(poses) >= 20


def test_scene_export_rejects_bad_fps(plan_comparison: Comparison) -> None:
    with pytest.raises(ValueError, match=r"fps must lie in \[1, 120\]"):
        scene_html(PreparedComparison(plan_comparison), fps=0.0)


def test_report_has_metrics_floors_and_inline_plotly(plan_comparison: Comparison) -> None:
    page = report_html(plan_comparison)
    result = plan_comparison.result
    assert "<!doctype html>" in page[:20].lower()
    assert not re.search(r'<script[^>]+src="https?://', page)
    assert "plotly.js v" in page or "Plotly" in page[:200_000]
    # Every metric row, with the standard value as the table shows it.
    for metric in ("tau_sq", "abs_work", "pos_work", "electrical_energy", "peak_power"):
        assert f"<td>{metric}</td>" in page
        assert f"{result['standard'][metric]:.4g}" in page
    assert f"{result['floors']['delta_potential']:.4g}" in page
    # The six panels each carry both trajectories.
    assert page.count('"name":"standard quintic"') == 6
    assert np.isfinite(result["improvement_pct"]["abs_work"])
