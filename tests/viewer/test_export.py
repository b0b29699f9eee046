"""Exports: the recorded 3-D scene (viser's serializer) and the Plotly report."""

from __future__ import annotations

import base64
import re
from typing import Any

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
        assert f"<td>{metric}<div" in page
        assert f"{result['standard'][metric]:.4g}" in page
    assert f"{result['floors']['delta_potential']:.4g}" in page
    # The six panels each carry every planned trajectory.
    assert page.count('"name":"standard quintic"') == 6
    assert page.count('"name":"paper\'s method"') == 6
    assert np.isfinite(result["improvement_pct"]["abs_work"])


def _root_x(messages: list[Any], name: str) -> float:
    """The last x position the recording gives a node (0: never moved from its parent)."""
    xs = [m["position"][0] for _, m in messages
          if m.get("name") == name and m.get("type") == "SetPositionMessage"]  # fmt: skip
    return float(xs[-1]) if xs else 0.0


def test_the_exported_scene_puts_the_robots_side_by_side(plan_comparison: Comparison) -> None:
    """Issue 29 item 5: the exported scene overlaid both robots and their labels; it now places
    them apart as the live viewer first does (``PreparedComparison.slot_offsets``)."""
    prepared = PreparedComparison(plan_comparison)
    rec = _recording(scene_html(prepared, fps=5.0))
    messages = rec["messages"]
    assert isinstance(messages, list)
    solid = _root_x(messages, "/bioplan/standard")
    ghost = _root_x(messages, "/bioplan/optimized")
    assert abs(ghost - solid) >= prepared.reach  # bases apart by at least the robot's reach
    assert ghost - solid == pytest.approx(prepared.slot_offsets("side_by_side")["optimized"][0])
    # The name labels hang at their robots' roots: as far apart, never over each other.
    for slot in ("standard", "optimized"):
        label = [m for _, m in messages if m.get("name") == f"/bioplan/{slot}/name"]
        assert label and label[0]["type"] == "LabelMessage"
    # The robots' boxes (every trajectory, both slots) do not overlap.
    a, b = prepared.robot_boxes("side_by_side")
    assert a[1][0] < b[0][0]
