"""The recorded human beside the robots, the camera framing, the method choice, narrow screens."""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np
import pytest

from app.analysis.replay import replay_lift
from app.viewer.comparison import Comparison
from app.viewer.framing import (
    box_of,
    corners,
    frame_camera,
    human_box,
    human_placement,
    in_view,
    union,
)
from app.viewer.human import about_minus_y
from app.viewer.scene import ComparisonScene, PreparedCache, PreparedComparison
from tests.viewer._fakes import FakeTarget


def _overlap(a: Any, b: Any) -> bool:
    return bool(np.all(a[0] < b[1]) and np.all(b[0] < a[1]))


@pytest.mark.parametrize(("aspect", "covered"), [(1.6, 0.0), (0.66, 0.0), (1.6, 340 / 1280)])
def test_the_camera_frames_every_box_and_no_closer_camera_would(
    aspect: float, covered: float
) -> None:
    """Every corner inside the view (left of the panel covering the right ``covered`` of the
    canvas), and 10 % closer some corner is cropped."""
    # The viewer's row along x: two robots side by side, the human beyond them.
    robots = [
        (np.array([-0.5, -0.5, 0.0]), np.array([1.2, 0.5, 1.5])),
        (np.array([1.5, -0.5, 0.0]), np.array([3.2, 0.5, 1.5])),
    ]
    human = human_box((3.9, 0.0, 0.8), 0.7)
    boxes = [*robots, human]
    position, look_at = frame_camera(boxes, aspect=aspect, margin=1.0, covered_right=covered)
    pts = np.concatenate([corners(b) for b in boxes])
    view = {"aspect": aspect, "covered_right": covered}
    assert all(in_view(p, position, look_at, **view) for p in pts)
    # Tight: 10% closer along the same line, some corner falls outside (would be cropped).
    closer = np.asarray(look_at) + 0.9 * (np.asarray(position) - np.asarray(look_at))
    assert not all(in_view(p, closer, look_at, **view) for p in pts)
    if covered == 0.0:
        np.testing.assert_allclose(look_at, 0.5 * (union(boxes)[0] + union(boxes)[1]))
    else:  # framed for the whole canvas instead, the panel would hide some corner
        naive = frame_camera(boxes, aspect=aspect, margin=1.0)
        assert not all(in_view(p, *naive, **view) for p in pts)


def test_the_human_stands_beside_the_robots_at_a_readable_size() -> None:
    robots = [(np.array([-0.3, 0.2, 0.0]), np.array([1.0, 1.4, 1.6]))]
    shoulder, scale = human_placement(robots, 0.65)
    # The arm is 0.6 of the robots' height (1.6 m), in the robots' row beyond their x.
    assert scale * 0.65 == pytest.approx(0.6 * 1.6)
    box = human_box(shoulder, scale * 0.65)
    assert not _overlap(box, robots[0]) and box[0][0] > robots[0][1][0]
    assert box[0][2] > 0.0  # the hanging hand clears the floor
    small = [(np.zeros(3), np.array([0.2, 0.2, 0.3]))]
    assert human_placement(small, 0.65)[1] == 1.0  # never smaller than life size
    tall = [(np.zeros(3), np.array([0.2, 0.2, 5.0]))]
    assert human_placement(tall, 0.65)[1] == 2.0  # nor a giant
    # A robot hanging below its base (the human arm model): the floor is its lowest point.
    hanging = [(np.array([-0.6, -0.6, -0.65]), np.array([0.6, 0.6, 0.6]))]
    shoulder, scale = human_placement(hanging, 0.65)
    assert human_box(shoulder, scale * 0.65)[0][2] > -0.65


@pytest.fixture(scope="module")
def with_human(plan_comparison: Comparison) -> Comparison:
    """The plan with a synthetic curl: elbow 5 -> 140 deg, shoulder 0 -> 20 deg in 2 s."""
    t_rec = np.linspace(0.0, 3.0, 301)
    ramp = np.clip((t_rec - 0.5) / 2.0, 0.0, 1.0)
    human = replay_lift(
        plan_comparison.t, t_rec, 20.0 * ramp, 5.0 + 135.0 * ramp, start=0.5, top=2.5
    )
    return dataclasses.replace(plan_comparison, human=human, human_note="synthetic curl")


def test_the_human_is_posed_from_its_angles_and_its_phase_changes(with_human: Comparison) -> None:
    prepared = PreparedComparison(with_human)
    target = FakeTarget()
    scene = ComparisonScene(target, prepared)
    nodes = target.scene.nodes
    assert {"/bioplan/human/upper/arm", "/bioplan/human/upper/fore/arm"} <= set(nodes)
    human = prepared.human
    assert human is not None
    # Beside the robots, not over them, in the default (side by side) and the ghost layout.
    hbox = human_box(human.shoulder, human.scale * with_human.human.reach)  # type: ignore[union-attr]
    for layout in ("side_by_side", "ghost"):
        assert not any(_overlap(hbox, b) for b in prepared.robot_boxes(layout))  # type: ignore[arg-type]
    texts = []
    for index in range(0, len(with_human.t), 50):
        phases = scene.show(index)
        upper, fore = nodes["/bioplan/human/upper"], nodes["/bioplan/human/upper/fore"]
        np.testing.assert_allclose(upper.wxyz, about_minus_y(with_human.human.shoulder)[index])  # type: ignore[union-attr]
        np.testing.assert_allclose(fore.wxyz, about_minus_y(with_human.human.elbow)[index])  # type: ignore[union-attr]
        # The drawn hand, composed from the two rotations, is the closed-form hand.
        l1 = human.scale * with_human.human.upper_arm  # type: ignore[union-attr]
        l2 = human.scale * with_human.human.forearm  # type: ignore[union-attr]
        q1 = 2.0 * math.atan2(-upper.wxyz[2], upper.wxyz[0])
        q2 = 2.0 * math.atan2(-fore.wxyz[2], fore.wxyz[0])
        drawn = np.array([l1 * math.sin(q1) + l2 * math.sin(q1 + q2), 0.0,
                          -l1 * math.cos(q1) - l2 * math.cos(q1 + q2)])  # fmt: skip
        np.testing.assert_allclose(
            np.asarray(human.shoulder) + drawn, human.hand_world()[index], atol=1e-9
        )
        texts.append(nodes["/bioplan/human/upper/fore/phase"].text)
        assert phases["human"] == human.phases[index]
    assert [t.split(":")[1][:2] for t in dict.fromkeys(texts)] == [" A", " B", " C"]
    assert scene.phases_now["human"] == "C"


def test_without_an_analysis_the_scene_says_so(plan_comparison: Comparison) -> None:
    note = "no recorded human: this comparison used the paper's default template"
    c = dataclasses.replace(plan_comparison, human_note=note)
    target = FakeTarget()
    scene = ComparisonScene(target, PreparedComparison(c))
    assert scene.human is None and "human" not in scene.show(10)
    assert target.scene.nodes["/bioplan/no_human"].args[0] == note
    assert not any(n.startswith("/bioplan/human") for n in target.scene.nodes)


def test_any_two_methods_on_the_solid_and_the_ghost_robot(plan_comparison: Comparison) -> None:
    prepared = PreparedComparison(plan_comparison)
    assert plan_comparison.methods == ("quintic", "paper")
    target = FakeTarget()
    scene = ComparisonScene(target, prepared)
    nodes = target.scene.nodes
    assert scene.shown == {"standard": "quintic", "optimized": "paper"}
    assert nodes["/bioplan/standard/name"].args[0] == "solid: standard quintic"
    scene.show(300)
    scene.set_methods("paper", "quintic")  # swapped: the ghost now shows the quintic
    for slot, label in (("standard", "paper"), ("optimized", "quintic")):
        for joint, frame in scene._frames[slot].items():
            np.testing.assert_array_equal(frame.wxyz, prepared.joint_wxyz[label][joint][300])
    assert nodes["/bioplan/optimized/name"].text == "ghost: standard quintic"
    assert nodes["/bioplan/optimized/trace"].args[0] is prepared.traces["quintic"][0]
    ghost_mesh = next(
        h for n, h in nodes.items() if n.startswith("/bioplan/optimized/") and "visual_" in n
    )
    assert ghost_mesh.color == (0x25, 0x63, 0xEB)  # the quintic's blue (app.names.METHODS)
    with pytest.raises(ValueError, match="unknown trajectory"):
        scene.set_methods("paper", "nonsense")


def test_boxes_hold_every_link_the_trajectory_reaches(plan_comparison: Comparison) -> None:
    prepared = PreparedComparison(plan_comparison)
    world = prepared.chain.link_poses(plan_comparison.q["paper"], plan_comparison.joint_names)
    origins = np.concatenate([p[:, :3, 3] for p in world.values()])
    lo, hi = prepared.bounds["paper"]
    assert np.all(origins >= lo) and np.all(origins <= hi)
    assert box_of(origins)[1][2] < hi[2]  # grown by the meshes around the link origins


# A real websocket: the human's nodes exist, move, and its phase label changes ------------------


def _inner(raw: bytes) -> bytes:
    """The msgpack part of one viser 1.1 websocket frame: [8 bytes size][8 bytes compressed
    size][zstd msgpack][raw buffers]."""
    import zstandard

    size = int.from_bytes(raw[:8], "little")
    n = int.from_bytes(raw[8:16], "little")
    return bytes(zstandard.ZstdDecompressor().decompress(raw[16 : 16 + n], max_output_size=size))


def _messages(
    ws: Any, until: Any, timeout: float = 120.0, out: list[dict[str, Any]] | None = None
) -> list[dict[str, Any]]:
    """Messages viser sends to a tab, decoded, until ``until(messages)`` holds (or timeout)."""
    import msgspec

    out = [] if out is None else out
    deadline = time.monotonic() + timeout

    def walk(value: Any) -> None:
        if isinstance(value, dict) and "type" in value:
            out.append(value)
        elif isinstance(value, dict):
            for v in value.values():
                walk(v)
        elif isinstance(value, list | tuple):
            for v in value:
                walk(v)

    while time.monotonic() < deadline and not until(out):
        try:
            raw = ws.recv(timeout=0.5)
        except TimeoutError:
            continue
        if isinstance(raw, bytes):
            walk(msgspec.msgpack.decode(_inner(raw)))
    return out


def _human_played(messages: list[dict[str, Any]]) -> bool:
    """The forearm turned in many frames and the human's phase label showed B and C."""
    turns = {tuple(m["wxyz"]) for m in messages
             if m.get("name") == "/bioplan/human/upper/fore" and "wxyz" in m}  # fmt: skip
    texts = [str(m) for m in messages if m.get("name") == "/bioplan/human/upper/fore/phase"]
    return (
        len(turns) > 10
        and any("human: B" in t for t in texts)
        and any("human: C" in t for t in texts)
    )


def test_over_a_real_websocket_the_human_moves_and_a_narrow_tab_gets_a_minimised_panel(
    with_human: Comparison,
) -> None:
    from app.viewer.server import ViewerServer
    from tests.viewer._fakes import connect_client as _connect
    from tests.viewer._fakes import issued_path
    from tests.viewer._fakes import listening_socket as _listening_socket

    with _listening_socket() as sock:
        port = sock.getsockname()[1]
    viewer = ViewerServer(PreparedCache(lambda k, i: with_human), port=port, autoplay=True)
    viewer.start()
    try:
        with _connect(viewer, issued_path(viewer, "plan", 7), width=400) as ws:
            messages = _messages(ws, _human_played)
            session = next(iter(viewer._sessions.values()))
            session.set_methods("paper", "quintic")  # what the two dropdowns do
            _messages(ws, lambda ms: any("ghost: standard quintic" in str(m) for m in ms),
                      out=messages)  # fmt: skip
            sessions = viewer.sessions()
    finally:
        viewer.stop()
    names = {m.get("name") for m in messages}
    assert {"/bioplan/human/upper/arm", "/bioplan/human/upper/fore/hand"} <= names
    assert _human_played(messages)  # the forearm turns with the frames, its phase changes
    assert sessions[0]["human"] and sessions[0]["panel_minimised"]
    assert (sessions[0]["solid"], sessions[0]["ghost"]) == ("paper", "quintic")
    assert any(m.get("name") == "/bioplan/optimized/name" and "ghost: standard quintic" in str(m)
               for m in messages)  # fmt: skip
    collapsed = [m for m in messages if m["type"] == "GuiSetPanelCollapsedMessage"]
    assert any(m.get("collapsed") is True for m in collapsed), collapsed
    # viser's phone layout cannot be collapsed from the server: all but play and time sit in
    # a closed folder there.
    folders = [m for m in messages if "Folder" in m["type"]]
    assert any("'expand_by_default': False" in str(m) for m in folders), folders


def test_a_simulation_offers_its_methods_by_name(simulation_comparison: Comparison) -> None:
    c = simulation_comparison
    assert c.methods == ("quintic", "paper") and c.choices == c.methods
    assert c.default_pair == ("quintic", "paper")
    # The method arrays are the same runs as the standard / optimised ones.
    np.testing.assert_array_equal(c.q["quintic"], c.q["standard"])
    np.testing.assert_array_equal(c.tau["paper"], c.tau["optimized"])
    old = dataclasses.replace(c, methods=())  # stored before methods existed
    assert old.choices == ("standard", "optimized") == old.default_pair


def test_the_compare_page_gets_the_human_elbow_velocity_over_the_planned_ones(
    with_human: Comparison, plan_comparison: Comparison
) -> None:
    """The synthetic curl's elbow rises linearly from the lift's start to its top, so on the
    plan's grid its velocity is constant: 1 everywhere over its peak. The quintic's elbow
    velocity is 30 s^2 (1 - s)^2 / T...: 0 at both ends, 1 at mid-time."""
    n = len(with_human.t)
    curves = with_human.curves(points=n)
    human = curves["human"]
    np.testing.assert_allclose(human["elbow_velocity_normalised"], 1.0, atol=1e-9)
    assert human["elbow_flexion_deg"][0] == pytest.approx(5.0)
    assert human["elbow_flexion_deg"][-1] == pytest.approx(140.0)
    quintic = np.asarray(curves["standard"]["elbow_velocity_normalised"])
    assert abs(quintic[0]) < 1e-9 and abs(quintic[-1]) < 1e-6
    assert np.max(np.abs(quintic)) == pytest.approx(1.0)
    assert abs(quintic[n // 2]) == pytest.approx(1.0, abs=1e-3)
    summary = with_human.summary()["human"]
    assert summary["shown"] and summary["note"] == "synthetic curl"
    assert plan_comparison.curves(points=10)["human"] is None
    assert plan_comparison.summary()["human"]["shown"] is False
