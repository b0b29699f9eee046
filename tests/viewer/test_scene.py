"""The comparison scene: built once, then only posed; geometry checked against Pinocchio."""

from __future__ import annotations

import numpy as np
import pytest

from app.viewer.comparison import Comparison
from app.viewer.scene import (
    GHOST_OPACITY,
    TRACE_RADIUS,
    TRACE_SIDES,
    ComparisonScene,
    PreparedCache,
    PreparedComparison,
    trace_tube,
)
from tests.viewer._fakes import FakeTarget


@pytest.fixture(scope="module")
def prepared(plan_comparison: Comparison) -> PreparedComparison:
    return PreparedComparison(plan_comparison)


def test_payload_path_matches_pinocchio(prepared: PreparedComparison) -> None:
    import pinocchio as pin

    from app.planning.robots import load_robot

    c = prepared.comparison
    robot = load_robot(c.robot)
    model = pin.buildModelFromUrdf(str(robot.urdf_path))
    data = model.createData()
    frame = model.getFrameId(c.payload_body)
    for i in (0, 250, 500, 999):
        pin.framesForwardKinematics(model, data, c.q["optimized"][i])
        expected = data.oMf[frame].act(c.payload_com)
        np.testing.assert_allclose(prepared.payload_path["optimized"][i], expected, atol=1e-12)
    assert 0.3 < prepared.reach < 1.2  # upper arm 0.495 m + forearm 0.45 m + wrist


def test_only_moving_links_form_the_ghost(prepared: PreparedComparison) -> None:
    # The curl turns J2 and J3 only: the pedestal and turret stay put.
    assert {"pedestal", "turret"}.isdisjoint(prepared.moving_links)
    assert {"upper_arm", "forearm", "flange"} <= prepared.moving_links


def test_scene_is_built_once_and_then_only_posed(prepared: PreparedComparison) -> None:
    target = FakeTarget()
    scene = ComparisonScene(target, prepared)
    nodes = dict(target.scene.nodes)
    joints = [j.name for j in prepared.chain.joints]
    for label in ("standard", "optimized"):
        trace = nodes[f"/bioplan/{label}/trace"]
        assert trace.kind == "add_mesh_simple"  # one plain mesh, not instanced fat lines
        assert trace.args[0] is prepared.traces[scene.shown[label]][0]
        payload = [n for n in nodes if n.endswith("/flange/payload") and f"/{label}/" in n]
        assert len(payload) == 1
        np.testing.assert_allclose(nodes[payload[0]].dimensions, prepared.comparison.payload_size)
    target.scene.updates.clear()
    for index in (1, 400, 400, 999, 0):
        phases = scene.show(index)
        frames = scene._frames
        for slot in ("standard", "optimized"):
            label = scene.shown[slot]
            for joint, handle in frames[slot].items():
                np.testing.assert_array_equal(handle.wxyz, prepared.joint_wxyz[label][joint][index])
                np.testing.assert_array_equal(
                    handle.position, prepared.joint_position[label][joint][index]
                )
            assert phases[slot] == prepared.comparison.phase_at(label, index)
    assert target.scene.nodes.keys() == nodes.keys()  # nothing added while playing
    # The curl turns the shoulder and elbow pitch joints only: per new index, one rotation of
    # each for both robots; the repeated index 400 sends nothing; labels ride on the flange.
    for label in ("standard", "optimized"):
        assert prepared.animated[label] == [
            ("j2_shoulder_pitch", "wxyz"),
            ("j3_elbow_pitch", "wxyz"),
        ]
    frame_updates = [u for u in target.scene.updates if u[1] in ("wxyz", "position")]
    assert len(frame_updates) == 4 * 2 * 2
    assert len(joints) == 6


def test_trace_is_a_tube_around_the_payload_path(prepared: PreparedComparison) -> None:
    import trimesh

    path = prepared.payload_path["standard"]
    vertices, faces = prepared.traces["standard"]
    rings = vertices.reshape(-1, TRACE_SIDES, 3).astype(np.float64)
    centres = rings.mean(axis=1)
    assert 2 <= len(rings) <= 120
    # Ring centres are points of the path (Pinocchio-checked above), first and last included.
    gaps = np.linalg.norm(centres[:, None, :] - path[None, :, :], axis=2).min(axis=1)
    assert gaps.max() < 1e-6
    np.testing.assert_allclose(centres[[0, -1]], path[[0, -1]], atol=1e-6)
    # Every vertex lies one radius from its centre, in the plane across the path.
    spoke = rings - centres[:, None, :]
    np.testing.assert_allclose(np.linalg.norm(spoke, axis=2), TRACE_RADIUS, rtol=1e-4)
    direction = np.gradient(centres, axis=0)
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    # (within 0.6 degrees: the direction here comes from float32 centres of tiny end steps)
    assert np.abs(np.einsum("rsk,rk->rs", spoke, direction)).max() < 1e-2 * TRACE_RADIUS
    # A closed side wall: only the two end rings are open edges; faces point outwards.
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    assert len(faces) == 2 * TRACE_SIDES * (len(rings) - 1)
    open_edges = trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)
    assert len(open_edges) == 2 * TRACE_SIDES
    ring_of_face = faces.min(axis=1) // TRACE_SIDES
    outward = mesh.triangles_center - centres[ring_of_face]
    assert (np.einsum("fk,fk->f", mesh.face_normals, outward) > 0).all()


def test_trace_of_a_still_or_short_path() -> None:
    still = np.tile([0.3, 0.1, 0.9], (50, 1))
    vertices, faces = trace_tube(still)
    assert vertices.shape == (0, 3) and faces.shape == (0, 3)
    # Held poses (repeated points) are skipped; the rings keep to the moving part.
    line = np.vstack([np.zeros((5, 3)), np.linspace([0, 0, 0], [1, 0, 0], 11), np.ones((3, 3))])
    vertices, faces = trace_tube(line, samples=1000, sides=4, radius=0.01)
    centres = vertices.reshape(-1, 4, 3).mean(axis=1)
    assert len(centres) == 12  # ten distinct steps along x, then the jump to (1, 1, 1)
    assert np.isfinite(vertices).all() and faces.max() < len(vertices)
    vertices, _ = trace_tube(np.linspace([0, 0, 0], [0, 0, 1], 1000), samples=50)
    assert len(vertices) // TRACE_SIDES <= 50


def test_layouts(prepared: PreparedComparison) -> None:
    target = FakeTarget()
    scene = ComparisonScene(target, prepared, layout="ghost")
    nodes = target.scene.nodes
    # The ghost is shifted sideways: its rest poses do not coincide with the solid robot's.
    assert nodes["/bioplan/standard"].position == (0.0, 0.0, 0.0)
    assert nodes["/bioplan/optimized"].position == (prepared.ghost_shift, 0.0, 0.0)
    assert prepared.ghost_shift >= 0.08
    ghosts = [
        h for n, h in nodes.items() if n.startswith("/bioplan/optimized/") and "/visual_" in n
    ]
    # The mesh's link is its parent node: /bioplan/optimized/<link path>/visual_k.
    static = [h for h in ghosts if h.name.split("/")[-2] not in prepared.moving_links]
    moving = [h for h in ghosts if h not in static]
    assert len(static) == 4  # pedestal column and plate, turret body and shoulder housing
    assert all(h.opacity == GHOST_OPACITY for h in ghosts)
    assert not any(h.visible for h in static) and all(h.visible for h in moving)
    scene.set_layout("side_by_side")
    # Side by side along x, far enough apart that their boxes do not meet.
    assert nodes["/bioplan/standard"].position == (0.0, 0.0, 0.0)
    assert nodes["/bioplan/optimized"].position == (prepared.side_offset, 0.0, 0.0)
    a, b = prepared.robot_boxes("side_by_side")
    assert a[1][0] < b[0][0]
    assert all(h.opacity == 1.0 for h in ghosts) and all(h.visible for h in static)
    with pytest.raises(ValueError, match="unknown layout"):
        scene.set_layout("stacked")  # type: ignore[arg-type]


def test_scene_on_a_real_viser_server(prepared: PreparedComparison) -> None:
    import viser

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        with server.atomic():
            scene = ComparisonScene(server, prepared, layout="side_by_side")
        for i in range(0, 1000, 97):
            with server.atomic():
                scene.show(i)
        assert scene.index == 970
    finally:
        server.stop()


def test_prepared_cache_reuses_and_evicts(plan_comparison: Comparison) -> None:
    calls: list[tuple[str, int]] = []

    def loader(kind: str, result_id: int) -> Comparison:
        calls.append((kind, result_id))
        return plan_comparison

    cache = PreparedCache(loader, size=2)
    first = cache("plan", 1)
    assert cache("plan", 1) is first
    cache("plan", 2)
    cache("plan", 3)  # evicts plan 1
    cache("plan", 1)
    assert calls == [("plan", 1), ("plan", 2), ("plan", 3), ("plan", 1)]
