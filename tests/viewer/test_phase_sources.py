"""Issue 29 item 6: the phase the viewer's labels show (over each robot and the human) and the
phase its panel states are one, at every moment of a playback, not a GUI refresh apart."""

from __future__ import annotations

import dataclasses
import re
from contextlib import nullcontext
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from app.analysis.replay import replay_lift
from app.viewer import server as server_module
from app.viewer.comparison import Comparison
from app.viewer.playback import PlaybackClock
from app.viewer.scene import ComparisonScene, PreparedComparison
from app.viewer.server import ViewerSession
from tests.viewer._fakes import FakeTarget


class _Gui:
    def __init__(self, **props: Any) -> None:
        for key, value in props.items():
            setattr(self, key, value)


def _panel_phases(text: str) -> dict[str, str]:
    """slot -> phase letter in the panel's markdown."""
    out = {}
    for line in text.split("\n"):
        m = re.match(r"\s*(solid|ghost|recorded human)\b.*\*\*([ABC])\*\*", line)
        if m:
            out[{"solid": "standard", "ghost": "optimized"}.get(m[1], "human")] = m[2]
    return out


def test_labels_and_panel_show_one_phase_at_every_sampled_time(
    plan_comparison: Comparison, monkeypatch: pytest.MonkeyPatch
) -> None:
    t_rec = np.linspace(0.0, 3.0, 301)
    ramp = np.clip((t_rec - 0.5) / 2.0, 0.0, 1.0)
    human = replay_lift(
        plan_comparison.t, t_rec, 20.0 * ramp, 5.0 + 135.0 * ramp, start=0.5, top=2.5
    )
    c = dataclasses.replace(plan_comparison, human=human, human_note="synthetic curl")
    now = [50.0]
    monkeypatch.setattr(server_module.time, "monotonic", lambda: now[0])
    target = FakeTarget()
    client = SimpleNamespace(client_id=1, scene=target.scene, atomic=nullcontext)
    scene = ComparisonScene(client, PreparedComparison(c))
    gui = {name: _Gui(max=c.duration, content="") for name in ("play", "time", "phase", "plot")}
    clock = PlaybackClock(c.duration, loop=False, now=lambda: now[0])
    session = ViewerSession(client=client, kind="plan", id=7, scene=scene, clock=clock, gui=gui)
    clock.play()
    nodes = target.scene.nodes
    seen_human = set()
    while now[0] < 50.0 + c.duration + 0.1:  # 60 ticks a second
        session.tick()
        panel = _panel_phases(gui["phase"].content)
        human_label = nodes["/bioplan/human/upper/fore/phase"].text
        assert human_label.startswith(f"human: {panel['human']} "), (now[0], human_label, panel)
        for slot in ("standard", "optimized"):
            label = next(
                n.text
                for name, n in nodes.items()
                if name.startswith(f"/bioplan/{slot}/") and name.endswith("/phase_label")
            )
            assert label == f"phase {panel[slot]}", (now[0], slot, label, panel)
        assert panel == scene.phases_now
        seen_human.add(panel["human"])
        now[0] += 1 / 60
    assert seen_human == {"A", "B", "C"}  # the sampled times crossed both boundaries
