"""``GET /api/caps``: the bounds of the fields the pages fill, as this server enforces them
(issue 29: a cap was refused unannounced, and the page's own ``max`` disagreed with it)."""

from __future__ import annotations

from pathlib import Path

from app.names import MAX_DURATION
from tests.utils.api import assert_problem, make_client
from tests.utils.jobs import RecordingRunner


def test_caps_follow_the_configuration_and_the_refusals(tmp_path: Path) -> None:
    runner = RecordingRunner()
    with make_client(tmp_path, runner=runner, max_particles=50, max_iterations=70) as client:
        caps = client.get("/api/caps").json()
        plan = caps["plan"]
        assert plan["particles"] == {"minimum": 2.0, "maximum": 50.0}
        assert plan["iterations"] == {"minimum": 1.0, "maximum": 70.0}
        assert plan["duration"] == {"maximum": MAX_DURATION, "exclusiveMinimum": 0.0}
        assert caps["upload"]["load_kg"] == {"minimum": 0.0, "maximum": 100.0}
        assert caps["upload"]["emg_rate"]["minimum"] == 100.0
        # What the caps say is what the server refuses, and accepts.
        body = {"robot": "human_arm_2dof", "duration": 1.0, "methods": ["quintic"]}
        over = client.post("/api/plans", json={**body, "particles": 51})
        assert_problem(over, 422, field="particles")
        assert client.post("/api/plans", json={**body, "particles": 50}).status_code == 202
        too_long = client.post("/api/plans", json={**body, "duration": MAX_DURATION + 1})
        assert_problem(too_long, 422, field="duration")
    with make_client(tmp_path / "b", runner=RecordingRunner()) as client:
        assert client.get("/api/caps").json()["plan"]["particles"]["maximum"] == 400.0
