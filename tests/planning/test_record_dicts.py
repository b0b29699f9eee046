"""The JSON blocks of small planning records (an actuator envelope, an export exceedance, a
safety finding): exactly the keys, order and JSON types the result files and the API carry.

The expected dicts are written out literally (the contract the page, the export files and
saved results read), so a renamed, reordered or non-JSON field fails here.
"""

from __future__ import annotations

import json

from app.planning.actuators import ActuatorEnvelope
from app.planning.export._checks import Exceedance
from app.planning.safety import Finding


def _json_round_trip(d: dict[str, object]) -> dict[str, object]:
    out: dict[str, object] = json.loads(json.dumps(d))
    return out


def test_actuator_envelope_block() -> None:
    env = ActuatorEnvelope(
        peak_torque=120.0,
        rated_speed=3.0,
        max_speed=6.5,
        corner_speed=4.0,
        rms_torque=45.0,
        duty_cycle=10.0,
        source="sidecar ur5.sidecar.yaml",
    )
    d = env.to_dict()
    assert list(d.items()) == [
        ("peak_torque", 120.0),
        ("rated_speed", 3.0),
        ("max_speed", 6.5),
        ("corner_speed", 4.0),
        ("rms_torque", 45.0),
        ("duty_cycle", 10.0),
        ("source", "sidecar ur5.sidecar.yaml"),
    ]
    assert _json_round_trip(d) == d


def test_exceedance_block() -> None:
    ex = Exceedance("elbow_joint", "velocity", 3.15, 3.15114, 0.53, "rad/s")
    d = ex.to_dict()
    assert list(d.items()) == [
        ("joint", "elbow_joint"),
        ("limit", "velocity"),
        ("bound", 3.15),
        ("value", 3.15114),
        ("time", 0.53),
        ("unit", "rad/s"),
    ]
    assert _json_round_trip(d) == d


def test_finding_block_lists_its_links() -> None:
    finding = Finding(
        method="quintic",
        time=0.312,
        kind="self",
        links=("forearm_link", "base_link"),
        obstacle=None,
        depth=0.0042,
        deepest_time=0.5,
    )
    d = finding.to_dict()
    assert list(d.items()) == [
        ("method", "quintic"),
        ("time", 0.312),
        ("kind", "self"),
        ("links", ["forearm_link", "base_link"]),  # a JSON list, not the record's tuple
        ("obstacle", None),
        ("depth", 0.0042),
        ("deepest_time", 0.5),
        ("between_samples", False),
    ]
    assert _json_round_trip(d) == d
    # The one-line description is made from this block.
    assert finding.describe() == (
        "quintic: forearm_link touches base_link from 0.312 s, 4.2 mm deep at 0.500 s"
    )
