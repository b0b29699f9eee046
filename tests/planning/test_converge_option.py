"""``converge`` exposed (issue 25 item 1): ``bioplan plan --converge``, the plan, simulation and
sweep API requests' ``converge``, and ``bioplan sweep --seeds``/``--converge``; each option
changes the result and the mesh-refinement evidence reaches the JSON and the text."""

from __future__ import annotations

import itertools
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from app.planning.methods import mesh_error_estimate
from app.planning.planner import plan
from app.planning.robots import load_robot
from tests.utils.api import TestClient, make_client, wait_job

#: A coarse mesh (16 intervals) on the 2-DOF arm: refinement has something to change, quickly.
PLAN = (
    *("plan", "--robot", "human_arm_2dof", "--particles", "8", "--iterations", "6"),
    *("--method", "quintic,bound", "--intervals", "16", "--objective", "tau_sq"),
)


def _cli_json(capsys: pytest.CaptureFixture[str], *args: str) -> dict[str, Any]:
    from app.cli import main

    code = main([*args, "--json"])
    out = capsys.readouterr()
    assert code == 0, out.err
    data: dict[str, Any] = json.loads(out.out)
    return data


def _check_evidence(conv: dict[str, Any], value: float, start: int) -> None:
    """The sequence starts on the asked mesh and doubles; the reported value is the final
    mesh's; the error estimate is the last step's relative change."""
    seq = conv["sequence"]
    assert [s["n_intervals"] for s in seq] == [start * 2**i for i in range(len(seq))]
    assert len(seq) >= 2
    objs = [s["objective"] for s in seq]
    assert conv["final_intervals"] in [s["n_intervals"] for s in seq]
    final = next(s["objective"] for s in seq if s["n_intervals"] == conv["final_intervals"])
    assert value == pytest.approx(final, rel=1e-12)
    assert conv["relative_change"] == pytest.approx(
        abs(objs[-1] - objs[-2]) / max(abs(objs[-1]), abs(objs[-2])), rel=1e-9
    )
    # Converged: the last change, or the Richardson estimate of the error left (from the third
    # mesh, when the changes shrink at least by half), is under the tolerance.
    estimate, _ = mesh_error_estimate(objs)
    assert conv["error_estimate"] == pytest.approx(estimate, rel=1e-9)
    assert conv["error_estimate"] <= conv["relative_change"] * (1 + 1e-12)
    assert conv["converged"] == (conv["error_estimate"] < conv["tolerance"])


def test_plan_converge_refines_the_bound_and_shows_the_evidence(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from app.cli import main

    coarse = _cli_json(capsys, *PLAN)
    # One run: the text on stdout, the JSON in --out.
    assert main([*PLAN, "--converge", "--out", str(tmp_path / "plan.json")]) == 0
    text = capsys.readouterr().out
    fine = json.loads((tmp_path / "plan.json").read_text(encoding="utf-8"))
    assert coarse["methods"]["bound"]["solver"].get("convergence") is None
    conv = fine["methods"]["bound"]["solver"]["convergence"]
    value = fine["methods"]["bound"]["tau_sq"]
    _check_evidence(conv, value, 16)
    # Graded ends: the first mesh's L is kept, so each finer mesh's end pieces are half as long
    # (a grading capped afresh per mesh would hold them and fake the convergence).
    smallest = [s["smallest_interval"] for s in conv["sequence"]]
    assert all(b == pytest.approx(a / 2, rel=1e-6) for a, b in itertools.pairwise(smallest))
    # The meshes are nested (a cubic is cubic on an interval's halves): the converged bound is
    # never above the coarse one, and the coarse mesh's graded ends already put it within the
    # issue's 0.3 %.
    assert value <= coarse["methods"]["bound"]["tau_sq"] <= value * (1 + 3e-3)
    # Independently: the library's own plan at the final mesh gives the same optimum.
    robot = load_robot("human_arm_2dof")
    again = plan(
        robot, duration=1.0, objective="tau_sq", methods=("quintic", "bound"),
        n_intervals=conv["final_intervals"],
    )  # fmt: skip
    assert again.objective_values["bound"] == pytest.approx(value, rel=2e-3)
    assert "mesh refinement (intervals: objective) 16: " in text
    assert f"final mesh {conv['final_intervals']} intervals" in text


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with make_client(tmp_path_factory.mktemp("converge")) as c:
        yield c


def _finished(client: TestClient, path: str, body: dict[str, Any]) -> dict[str, Any]:
    r = client.post(path, json=body)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"], timeout=600)
    assert job["state"] == "succeeded", job
    out: dict[str, Any] = client.get(job["result_url"]).json()["result"]
    return out


def test_the_plan_request_converge_changes_the_result(client: TestClient) -> None:
    body = {
        "robot": "human_arm_2dof", "objective": "tau_sq", "particles": 8, "iterations": 6,
        "methods": ["quintic", "bound"], "n_intervals": 16,
    }  # fmt: skip
    off = _finished(client, "/api/plans", body)
    on = _finished(client, "/api/plans", {**body, "converge": True})
    assert off["methods"]["bound"]["solver"].get("convergence") is None
    _check_evidence(
        on["methods"]["bound"]["solver"]["convergence"], on["methods"]["bound"]["tau_sq"], 16
    )
    assert on["methods"]["bound"]["tau_sq"] < off["methods"]["bound"]["tau_sq"]
    r = client.post("/api/plans", json={**body, "converge": "sometimes"})
    assert r.status_code == 422 and "converge" in r.text
    # The simulation request shares the option; its methods carry the same evidence.
    sim_off = _finished(client, "/api/simulations", body)
    sim_on = _finished(client, "/api/simulations", {**body, "converge": True})
    assert sim_off["methods"]["bound"]["solver"].get("convergence") is None
    sim_seq = sim_on["methods"]["bound"]["solver"]["convergence"]["sequence"]
    plan_seq = on["methods"]["bound"]["solver"]["convergence"]["sequence"]
    # The same meshes; objectives on the simulation's grid (1001 samples, not 1000).
    assert [m["n_intervals"] for m in sim_seq] == [m["n_intervals"] for m in plan_seq]
    assert [m["objective"] for m in sim_seq] == pytest.approx(
        [m["objective"] for m in plan_seq], rel=1e-4
    )
    assert sim_on["methods"]["bound"]["tau_sq"] < sim_off["methods"]["bound"]["tau_sq"]


def test_the_sweep_request_seeds_and_converge_change_the_result(client: TestClient) -> None:
    body = {
        "robot": "human_arm_2dof", "durations": [1.0], "payloads": [4.0],
        "objectives": ["tau_sq"], "particles": 6, "iterations": 4, "workers": 1,
        "methods": ["quintic", "paper", "bound"], "seeds": 2,
    }  # fmt: skip
    base = _finished(client, "/api/sweeps", body)
    assert base["conditions"]["seeds"] == [0, 1] and base["conditions"]["converge"] is False
    more = _finished(client, "/api/sweeps", {**body, "seeds": 3})
    assert more["conditions"]["seeds"] == [0, 1, 2]
    assert len(more["cells"][0]["paper_share_by_seed"]) == 3
    conv = _finished(client, "/api/sweeps", {**body, "converge": True})
    assert conv["conditions"]["converge"] is True
    # The refined bound is another (lower) trajectory: its simulated saving changes.
    got = conv["cells"][0]["methods_change_pct"]["bound"]["tau_sq"]
    assert got != base["cells"][0]["methods_change_pct"]["bound"]["tau_sq"]
    r = client.post("/api/sweeps", json={**body, "seeds": 0})
    assert r.status_code == 422 and "seeds" in r.text


def test_sweep_cli_seeds_and_converge(capsys: pytest.CaptureFixture[str]) -> None:
    sweep = (
        *("sweep", "--robot", "human_arm_2dof", "--durations", "1.0", "--payloads", "6"),
        *("--particles", "12", "--iterations", "12", "--workers", "1"),
    )
    one = _cli_json(capsys, *sweep, "--method", "quintic,paper", "--seeds", "1")
    two = _cli_json(capsys, *sweep, "--method", "quintic,paper", "--seeds", "2")
    assert one["cells"][0]["status"] == two["cells"][0]["status"] == "ok"
    assert one["cells"][0]["seeds"] == [0] and two["cells"][0]["seeds"] == [0, 1]
    assert one["conditions"]["pso_budget"]["seeds"] == 1
    assert two["conditions"]["pso_budget"]["seeds"] == 2
    base = _cli_json(capsys, *sweep, "--method", "quintic,bound", "--objectives", "tau_sq")
    conv = _cli_json(
        capsys, *sweep, "--method", "quintic,bound", "--objectives", "tau_sq", "--converge"
    )
    assert conv["conditions"]["converge"] is True
    b0 = base["cells"][0]["methods_change_pct"]["bound"]["tau_sq"]
    assert conv["cells"][0]["methods_change_pct"]["bound"]["tau_sq"] != b0
