"""Issue 24 item 3: the job payloads are typed per kind. The planning payload types list every
field of the options object whose dict they carry (so a new option cannot be left untyped), and
the robot spec's options are exactly the ones the robot catalogue stores."""

from __future__ import annotations

from dataclasses import fields

import pytest

from app.jobs.tasks.types import (
    PlanPayload,
    ProfilesPayload,
    RobotOptions,
    SimulationPayload,
    SweepPayload,
    robot_options,
)
from app.planning.options import PlanOptions
from app.services.robots import _OPTION_KEYS
from app.simulation.options import SimulationOptions, SweepGrid


@pytest.mark.parametrize(
    ("payload_type", "options_type"),
    [
        (PlanPayload, PlanOptions),
        (SimulationPayload, SimulationOptions),
        (SweepPayload, SweepGrid),
        (ProfilesPayload, PlanOptions),
    ],
)
def test_payload_type_lists_every_option(payload_type: type, options_type: type) -> None:
    keys = set(payload_type.__annotations__)
    option_names = {f.name for f in fields(options_type)}
    assert option_names <= keys, sorted(option_names - keys)
    assert "robot" in keys
    # and the options object's dict, as the service stores it, has only typed keys
    assert set(options_type().to_dict()) <= keys


def test_sweep_payload_keys_are_the_grid_and_the_job_keys() -> None:
    """``SweepPayload`` (static typing only: a TypedDict cannot be made from a dataclass) lists
    exactly ``SweepGrid``'s fields besides the job's own keys: an option added to the grid and
    not typed here, or one typed here that the grid lost, fails."""
    job_keys = {"robot", "label", "workers", "cell_executor"}
    keys = set(SweepPayload.__annotations__)
    assert keys - job_keys == {f.name for f in fields(SweepGrid)}


def test_robot_options_are_the_catalogue_options() -> None:
    assert set(RobotOptions.__annotations__) == set(_OPTION_KEYS)
    stored = {"shoulder_joint": "j2", "locks": {"j1": 10.0}, "not_an_option": 1}
    picked = robot_options(stored)
    assert set(picked) == set(_OPTION_KEYS)
    assert picked["shoulder_joint"] == "j2" and picked["locks"] == {"j1": 10.0}
    assert picked["elbow_joint"] is None
