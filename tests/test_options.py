"""Options defined once (issue 24 item 1): each dataclass field's default, range, choices and
unit reach the library, ``bioplan`` and the API unchanged, and a new field reaches all three."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

import pytest

from app.analysis.pipeline import AnalysisOptions
from app.api.schemas import (
    AnalysisRequest,
    PlanRequest,
    ProfilesRequest,
    SimulationRequest,
    SweepRequest,
    options_model,
)
from app.cli import build_parser
from app.cli._common import CliError, Parser, add_options, options_from_args
from app.names import (
    DEFAULT_OBJECTIVE,
    MAX_DURATION,
    OBJECTIVES,
    OPTIMAL_INTERVALS,
    PSO_DEFAULTS,
    STANDARD_METHODS,
)
from app.options import OptionsError, option, option_specs
from app.planning.options import PlanOptions
from app.simulation.options import SimulationOptions, SweepGrid

#: (options class, request model, the ``bioplan`` command offering it).
INTERFACES: list[tuple[Any, Any, str]] = [
    (PlanOptions, PlanRequest, "plan"),
    (SimulationOptions, SimulationRequest, "simulate"),
    (SweepGrid, SweepRequest, "sweep"),
]


def _sub(command: str) -> argparse.ArgumentParser:
    parser = build_parser()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            sub: argparse.ArgumentParser = action.choices[command]
            return sub
    raise AssertionError(command)


def _action(parser: argparse.ArgumentParser, dest: str) -> argparse.Action | None:
    return next((a for a in parser._actions if a.dest == dest), None)


# ---------------------------------------------------------------------------- the dataclasses


def test_the_defaults_are_the_shared_names() -> None:
    """The values that were literals in many places come from one home each."""
    o = PlanOptions()
    assert o.objective == DEFAULT_OBJECTIVE == "abs_work"
    assert (o.seed, o.particles, o.iterations, o.n_samples) == (
        PSO_DEFAULTS.seed, PSO_DEFAULTS.particles, PSO_DEFAULTS.iterations, PSO_DEFAULTS.n_samples
    )  # fmt: skip
    assert o.n_intervals == OPTIMAL_INTERVALS == 40
    assert SweepGrid().objectives == (DEFAULT_OBJECTIVE,)
    assert ProfilesRequest().objective == DEFAULT_OBJECTIVE
    # The library plans the quick pair; the CLI and the API every standard method.
    assert o.methods == ("quintic", "paper")
    from app.planning.methods import DEFAULT_METHODS

    assert o.methods == DEFAULT_METHODS
    spec = next(s for s in option_specs(PlanOptions) if s.name == "methods")
    assert spec.interface_default == STANDARD_METHODS


def test_round_trip_and_normalisation() -> None:
    o = PlanOptions(methods=["paper", "bound"], duration=2, particles=12)  # type: ignore[arg-type]
    assert o.methods == ("paper", "bound") and isinstance(o.duration, float)
    d = o.to_dict()
    assert d["methods"] == ["paper", "bound"] and d["duration"] == 2.0
    assert PlanOptions.from_dict(d) == o
    assert PlanOptions(methods="bound, paper").methods == ("bound", "paper")  # type: ignore[arg-type]
    a = AnalysisOptions(exclude_channels=["EMG1"], muscle_map={"EMG1": "biceps"})  # type: ignore[arg-type]
    assert AnalysisOptions.from_dict(a.to_dict()) == a
    assert a.to_dict()["exclude_channels"] == ["EMG1"]


@pytest.mark.parametrize(
    ("cls", "changes", "says"),
    [
        (PlanOptions, {"particles": 1}, "particles must be >= 2, got 1"),
        (PlanOptions, {"iterations": 10001}, "iterations must be <= 10000, got 10001"),
        (PlanOptions, {"n_intervals": 4}, "n_intervals must be >= 8, got 4"),
        (PlanOptions, {"duration": 0.0}, "duration must be > 0 s, got 0"),
        (PlanOptions, {"duration": 1e4}, f"duration must be <= {MAX_DURATION:g} s"),
        (PlanOptions, {"peak_angle_deg": 190.0}, "peak_angle_deg must be < 180 deg"),
        (PlanOptions, {"objective": "beauty"}, "unknown objective 'beauty'"),
        (PlanOptions, {"human_constraint": "smile"}, "unknown human_constraint 'smile'"),
        (PlanOptions, {"methods": ["paper", "magic"]}, "unknown methods 'magic'"),
        (PlanOptions, {"methods": []}, "methods needs at least 1 item"),
        (PlanOptions, {"seed": True}, "seed must be a number, got True"),
        (PlanOptions, {"particles": 2.5}, "particles must be a whole number"),
        (PlanOptions, {"converge": 1}, "converge must be true or false"),
        (PlanOptions, {"objective": None}, "objective must be given"),
        (SweepGrid, {"payloads": [-1.0]}, "payloads must be >= 0 kg, got -1"),
        (SweepGrid, {"seeds": 0}, "seeds must be >= 1, got 0"),
        (SimulationOptions, {"timestep": 0.0}, "timestep must be > 0 s"),
        (SimulationOptions, {"feedforward": "guess"}, "unknown feedforward 'guess'"),
    ],
)
def test_a_bad_value_names_the_option(cls: Any, changes: dict[str, Any], says: str) -> None:
    with pytest.raises(OptionsError, match=says.replace("(", r"\(")):
        cls(**changes)
    with pytest.raises(OptionsError, match=says.replace("(", r"\(")):
        cls.from_dict(changes)


def test_unknown_keys_are_named() -> None:
    with pytest.raises(OptionsError, match=r"unknown option.*particle_count.*PlanOptions"):
        PlanOptions.from_dict({"particle_count": 3})
    with pytest.raises(OptionsError, match="speed"):
        PlanOptions().replace(speed=2)
    # A job payload holds the robot and the task beside the options: picked out on request.
    payload = {**PlanRequest(particles=12).model_dump(), "robot": "x"}
    assert PlanOptions.from_dict(payload, ignore_unknown=True).particles == 12


# -------------------------------------------------------------------------------- the library


@pytest.fixture(scope="module")
def human() -> Any:
    from app.planning.robots import load_robot

    return load_robot("human_arm_2dof")


def test_plan_takes_the_options_object_or_keywords_alike(human: Any) -> None:
    from app.planning.planner import PlanningError, plan

    kwargs: dict[str, Any] = {"duration": 1.0, "particles": 20, "iterations": 40, "seed": 3}
    by_object = plan(human, PlanOptions(**kwargs)).to_dict()
    by_keyword = plan(human, **kwargs).to_dict()
    longer = plan(human, PlanOptions(**kwargs), duration=1.1).to_dict()
    for d in (by_object, by_keyword, longer):
        d["optimizer"].pop("seconds")
        d["methods"]["paper"]["solver"].pop("seconds", None)
    assert by_object == by_keyword  # the same plan, bit for bit
    assert longer["duration"] == 1.1 and longer["methods"] != by_object["methods"]
    with pytest.raises(PlanningError, match=r"unknown option.*swarm"):
        plan(human, swarm=3)
    with pytest.raises(PlanningError, match="particles must be >= 2"):
        plan(human, particles=1)


def test_sweep_grid_keywords_keep_their_meaning() -> None:
    from app.simulation.sweep import _sweep_grid

    assert _sweep_grid(None, {"check_seed": None}).no_check
    g = _sweep_grid(SweepGrid(seed=3), {"durations": [1.0], "methods": None})
    assert g.durations == (1.0,) and g.seed == 3 and g.methods == ("quintic", "paper")
    payload = SweepRequest(durations=[1.0, 2.0], seeds=2).model_dump()
    grid = SweepGrid.from_dict(payload, ignore_unknown=True)
    assert grid.durations == (1.0, 2.0) and grid.seeds == 2
    assert grid.methods == STANDARD_METHODS  # the API's default, as requested


# ------------------------------------------------------------------------------------ the CLI


@pytest.mark.parametrize(("cls", "_model", "command"), INTERFACES)
def test_every_cli_option_is_built_from_its_field(cls: type, _model: Any, command: str) -> None:
    parser = _sub(command)
    for spec in option_specs(cls):
        action = _action(parser, spec.name)
        if not spec.meta["cli"]:
            assert action is None or spec.name == "duration", spec.name
            continue
        if command == "simulate" and spec.name in ("no_reversal", "n_intervals", "converge"):
            assert action is None  # plan's transcription flags, not simulate's (as before)
            continue
        assert action is not None, f"bioplan {command} lacks {spec.name}"
        default = spec.interface_default
        if spec.sequence:
            assert action.default.split(",") == [
                f"{v:g}" if isinstance(v, float) else v for v in default
            ]
        elif spec.kind is not bool:
            scale = spec.meta.get("cli_scale", 1.0)
            wanted = default * scale if default is not None and scale != 1 else default
            assert action.default == wanted, spec.name
        if spec.choices is not None and not spec.sequence:
            assert tuple(action.choices) == spec.choices  # type: ignore[arg-type]
        for bound in spec.bounds().values():
            shown = bound * spec.meta.get("cli_scale", 1.0)
            assert (str(int(shown)) if float(shown).is_integer() else f"{shown:g}") in str(
                action.help
            ), (spec.name, action.help)


def test_the_flags_of_today_are_still_there() -> None:
    flags = {
        "plan": ["--objective", "--peak-angle-deg", "--template", "--seed", "--particles",
                 "--iterations", "--method", "--human-constraint", "--allow-reversal",
                 "--intervals", "--converge", "--duration"],
        "simulate": ["--objective", "--peak-angle-deg", "--template", "--seed", "--particles",
                     "--iterations", "--method", "--human-constraint", "--timestep-ms"],
        "sweep": ["--robot", "--mjcf", "--durations", "--payloads", "--objectives", "--method",
                  "--seed", "--check-seed", "--seeds", "--no-check", "--converge", "--particles",
                  "--iterations", "--workers", "--executor", "--json", "--out"],
    }  # fmt: skip
    for command, wanted in flags.items():
        have = {s for a in _sub(command)._actions for s in a.option_strings}
        assert set(wanted) <= have, (command, set(wanted) - have)


def test_parsed_flags_become_the_options() -> None:
    args = _sub("plan").parse_args(
        ["--particles", "12", "--method", "paper,bound", "--allow-reversal", "--intervals", "20",
         "--objective", "tau_sq", "--duration", "2"]
    )  # fmt: skip
    o = options_from_args(PlanOptions, args)
    assert (o.particles, o.methods, o.no_reversal, o.n_intervals, o.objective, o.duration) == (
        12, ("paper", "bound"), False, 20, "tau_sq", 2.0
    )  # fmt: skip
    assert options_from_args(PlanOptions, _sub("plan").parse_args([])).methods == STANDARD_METHODS
    sim = options_from_args(SimulationOptions, _sub("simulate").parse_args(["--timestep-ms", "2"]))
    assert sim.timestep == pytest.approx(0.002)
    grid = options_from_args(
        SweepGrid, _sub("sweep").parse_args(["--durations", "1,2", "--no-check"])
    )
    assert grid.durations == (1.0, 2.0) and grid.no_check
    with pytest.raises(CliError, match="--particles: particles must be >= 2, got 1"):
        options_from_args(PlanOptions, _sub("plan").parse_args(["--particles", "1"]))


# ------------------------------------------------------------------------------------ the API


_JSON_BOUNDS = {
    "ge": "minimum",
    "gt": "exclusiveMinimum",
    "le": "maximum",
    "lt": "exclusiveMaximum",
}


def _schema_without_title(schema: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in schema.items() if k != "title"}


@pytest.mark.parametrize(("cls", "model", "_command"), INTERFACES)
def test_every_api_option_is_its_field(cls: type, model: Any, _command: str) -> None:
    """Each option offered by the API has the field's default, bounds, length, choices and
    description; and it is what ``options_model`` generates from the dataclass."""
    schema = model.model_json_schema()["properties"]
    generated = options_model(cls, "Generated").model_json_schema()["properties"]
    for spec in option_specs(cls):
        if not spec.meta["api"]:
            assert spec.name not in schema, spec.name
            continue
        field = schema[spec.name]
        assert _schema_without_title(field) == _schema_without_title(generated[spec.name])
        default = spec.interface_default
        assert field["default"] == (list(default) if isinstance(default, tuple) else default)
        assert field["description"].startswith(spec.help)
        values = field.get("items", field)
        if spec.nullable:
            values = field["anyOf"][0]
        names = {
            "ge": "minimum",
            "gt": "exclusiveMinimum",
            "le": "maximum",
            "lt": "exclusiveMaximum",
        }
        for key, bound in spec.bounds().items():
            assert values[names[key]] == bound, (spec.name, key)
        if spec.choices is not None:
            assert tuple(values["enum"]) == spec.choices, spec.name
        if "max_items" in spec.meta:
            assert field["maxItems"] == spec.meta["max_items"]


@pytest.mark.parametrize(("cls", "model", "_command"), INTERFACES)
def test_the_request_offers_exactly_the_api_options(cls: type, model: Any, _command: str) -> None:
    """Beside its hand-written base (robot, task, workers), a request model has one field per
    API option of its dataclass and no other: none is written twice, none is forgotten."""
    own = set(model.model_fields) - set(model.__base__.model_fields)
    assert own == {s.name for s in option_specs(cls) if s.meta["api"]}


def test_the_profiles_request_takes_the_pso_options_from_plan_options() -> None:
    """``ProfilesRequest``'s duration, objective and PSO budget are ``PlanOptions``' fields:
    the same default, bounds, choices and description as the plan request's."""
    from app.api.schemas import PROFILES_OPTIONS

    profiles = ProfilesRequest.model_json_schema()["properties"]
    plan = PlanRequest.model_json_schema()["properties"]
    assert set(PROFILES_OPTIONS) == {"duration", "objective", "seed", "particles", "iterations"}
    for spec in option_specs(PlanOptions):
        if spec.name not in PROFILES_OPTIONS:
            continue
        field = profiles[spec.name]
        assert _schema_without_title(field) == _schema_without_title(plan[spec.name])
        assert field["default"] == spec.default
        for key, bound in spec.bounds().items():
            assert field[_JSON_BOUNDS[key]] == bound, (spec.name, key)
    assert profiles["particles"]["minimum"] == 2 and profiles["particles"]["maximum"] == 1000
    assert profiles["seed"]["maximum"] == 2**32 - 1
    # ``methods`` stays its own: a comparison of the profiles alone plans none.
    assert ProfilesRequest(methods=[]).model_dump()["methods"] == []
    with pytest.raises(ValueError, match="has no option"):
        options_model(PlanOptions, "Bad", only=["particle_count"])
    only = options_model(PlanOptions, "OnlyPso", only=["seed", "particles"]).model_fields
    assert set(only) == {"seed", "particles"}


def test_analysis_request_shares_the_analysis_options(tmp_path: Path) -> None:
    schema = AnalysisRequest.model_json_schema()["properties"]
    for spec in option_specs(AnalysisOptions):
        if spec.meta["api"] and spec.name in ("emg_rate", "keep_low_quality_lifts"):
            assert schema[spec.name]["default"] == spec.default


def test_the_openapi_document_states_the_ranges(tmp_path: Path) -> None:
    from tests.utils.api import make_client

    with make_client(tmp_path) as client:
        doc = client.get("/openapi.json").json()
    components = doc["components"]["schemas"]
    for cls, model, _ in INTERFACES:
        served = components[model.__name__]["properties"]
        local = model.model_json_schema()["properties"]
        for spec in option_specs(cls):
            if spec.meta["api"]:
                assert served[spec.name].get("default") == local[spec.name].get("default")
                assert served[spec.name].get("description") == local[spec.name]["description"]
                for key in ("minimum", "exclusiveMinimum", "exclusiveMaximum"):
                    assert served[spec.name].get(key) == local[spec.name].get(key)
                # The server may cap a job budget lower (BIOPLAN_MAX_*), never raise it.
                top = local[spec.name].get("maximum")
                assert top is None or served[spec.name]["maximum"] <= top
    plan_fields = components["PlanRequest"]["properties"]
    assert (
        plan_fields["n_intervals"]["maximum"] == 400 and plan_fields["n_intervals"]["minimum"] == 8
    )


# --------------------------------------------------- a new option: one field, and it is everywhere


def test_a_new_field_reaches_the_cli_and_the_api_with_its_range() -> None:
    extended: Any = dataclasses.make_dataclass(
        "ExtendedPlanOptions",
        [("stiffness", float, option(2.0, help="spring stiffness", unit="N/m", gt=0, le=50))],
        bases=(PlanOptions,),
        frozen=True,
    )
    parser = Parser(prog="probe")
    add_options(parser, extended)
    action = _action(parser, "stiffness")
    assert action is not None and action.option_strings == ["--stiffness"]
    assert action.default == 2.0 and "[N/m]; > 0 and <= 50" in str(action.help)
    parsed = options_from_args(extended, parser.parse_args(["--stiffness", "3.5"]))
    assert parsed.stiffness == 3.5
    with pytest.raises(CliError, match="--stiffness: stiffness must be <= 50 N/m, got 60"):
        options_from_args(extended, parser.parse_args(["--stiffness", "60"]))

    model = options_model(extended, "ExtendedPlanRequest")
    field = model.model_json_schema()["properties"]["stiffness"]
    assert field["default"] == 2.0 and field["exclusiveMinimum"] == 0 and field["maximum"] == 50
    assert field["description"] == "spring stiffness [N/m]"
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match="stiffness"):
        model(stiffness=60)
    body = model(stiffness=4.0, particles=8)
    job = extended.from_dict(body.model_dump(), ignore_unknown=True)  # the job payload's way
    assert job.stiffness == 4.0 and job.particles == 8
    assert (
        "objective" in model.model_fields
        and tuple(model.model_json_schema()["properties"]["objective"]["enum"]) == OBJECTIVES
    )


def test_a_job_payload_gives_its_options() -> None:
    """What the job side does: the payload is the request's dict; robot, task and label are
    the task's own, a None of an option that takes none is its default (old payloads)."""
    body = PlanRequest(particles=12, methods=["paper"], n_intervals=20).model_dump()
    payload = {**body, "robot": {"name": "human_arm_2dof"}, "payload": None}
    o = PlanOptions.from_payload(payload)
    assert (o.particles, o.methods, o.n_intervals, o.peak_angle_deg) == (12, ("paper",), 20, None)
    old_sweep = {**SweepRequest().model_dump(), "particles": None, "iterations": None}
    assert SweepGrid.from_payload(old_sweep).particles == SweepGrid().particles
    sim = SimulationOptions.from_payload(SimulationRequest(duration=2.0).model_dump())
    assert sim.duration == 2.0 and sim.timestep == SimulationOptions().timestep
