"""``bioplan validate`` and ``bioplan identify`` on synthetic logs (MuJoCo torques of a known arm).

Every option is shown to change the result. The plan test writes a result file with the
``motion`` block of ``bioplan plan --json --out`` (joint names, each method's t and q, metrics)
and a log of that plan's motion started at a planted time.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.cli import main
from app.planning.robots import load_robot
from tests.utils.robot_logs import arm_urdf, excitation, mujoco_torques, write_generic_csv

N = 3


@pytest.fixture(scope="module")
def arm(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("validate")
    nominal = folder / "arm.urdf"
    nominal.write_text(arm_urdf(N))
    true = folder / "true" / "arm.urdf"
    true.parent.mkdir()
    true.write_text(arm_urdf(N, masses=[4.0, 4.2, 3.0], payload=1.0))
    robot = load_robot(str(true))
    t, q, qd, qdd = excitation(12.0, 250.0, N, seed=9)
    rng = np.random.default_rng(1)
    tau = mujoco_torques(robot, q, qd, qdd) + 0.8 * qd + rng.normal(0, 0.05, q.shape)
    log = write_generic_csv(folder / "log.csv", t, robot.joint_names, q, tau)
    return {"folder": folder, "nominal": nominal, "true": true, "log": log}


def run_json(capsys: pytest.CaptureFixture[str], *args: str) -> dict[str, Any]:
    code = main([*args, "--json"])
    out = capsys.readouterr()
    assert code == 0, out.err
    data: dict[str, Any] = json.loads(out.out)  # one JSON object and nothing else
    return data


def _residual(data: dict[str, Any]) -> float:
    return float(sum(row["residual_rms"] for row in data["joints"].values()))


def test_validate_json_and_every_option_changes_the_result(capsys, arm):
    base = ["validate", "--robot", str(arm["nominal"]), "--log", str(arm["log"])]
    data = run_json(capsys, *base)
    assert set(data["joints"]) == {"joint1", "joint2", "joint3"}
    assert set(data["abs_work"]) == {"measured", "predicted"}
    assert data["filter"]["delay_s"] == 0.0
    for option in (
        ["--cutoff-hz", "4"],
        ["--payload", "1.0"],
        ["--lock", "joint3=30"],
    ):
        args = base + option
        if option[0] == "--lock":  # the log's joint3 is then ignored
            args = base + option
        assert _residual(run_json(capsys, *args)) != pytest.approx(_residual(data), rel=1e-6)
    # The true model with a friction sidecar fits the log at its noise level.
    sidecar = arm["folder"] / "friction.yaml"
    sidecar.write_text(
        "friction:\n  joint1: {viscous: 0.8}\n  joint2: {viscous: 0.8}\n  joint3: {viscous: 0.8}\n"
    )
    good = run_json(
        capsys,
        "validate",
        "--robot",
        str(arm["true"]),
        "--sidecar",
        str(sidecar),
        "--log",
        str(arm["log"]),
    )
    for row in good["joints"].values():
        assert row["r2"] > 0.999 and row["residual_rms"] < 0.05
    assert good["abs_work"]["predicted"] == pytest.approx(good["abs_work"]["measured"], rel=0.01)


def test_validate_plot_writes_html(capsys, arm, tmp_path):
    data = run_json(
        capsys,
        "validate",
        "--robot",
        str(arm["nominal"]),
        "--log",
        str(arm["log"]),
        "--plot",
        str(tmp_path / "plots"),
    )
    assert sorted(Path(p).name for p in data["plots"]) == ["power.html", "torque.html"]
    assert (tmp_path / "plots" / "torque.html").stat().st_size > 10_000
    # --out writes the same JSON object to a file.
    out = tmp_path / "validation.json"
    again = run_json(
        capsys,
        "validate",
        "--robot",
        str(arm["nominal"]),
        "--log",
        str(arm["log"]),
        "--out",
        str(out),
    )
    assert json.loads(out.read_text())["joints"] == again["joints"]


def test_identify_writes_a_sidecar_every_command_accepts(capsys, arm, tmp_path):
    out = tmp_path / "identified.yaml"
    data = run_json(
        capsys,
        "identify",
        "--robot",
        str(arm["nominal"]),
        "--log",
        str(arm["log"]),
        "--out",
        str(out),
        "--validate-fraction",
        "0.25",
    )
    assert out.is_file() and data["n_base_parameters"] > 0
    assert set(data["held_back"]) == {"joint1", "joint2", "joint3"}
    before = run_json(capsys, "validate", "--robot", str(arm["nominal"]), "--log", str(arm["log"]))
    after = run_json(
        capsys,
        "validate",
        "--robot",
        str(arm["nominal"]),
        "--sidecar",
        str(out),
        "--log",
        str(arm["log"]),
    )
    assert _residual(after) < 0.2 * _residual(before)
    # --validate-fraction changes what is held back.
    other = run_json(
        capsys,
        "identify",
        "--robot",
        str(arm["nominal"]),
        "--log",
        str(arm["log"]),
        "--out",
        str(tmp_path / "o.yaml"),
        "--validate-fraction",
        "0.1",
    )
    assert other["held_back"] != data["held_back"]
    # plan accepts the sidecar and its prediction changes (simulate loads robots the same way).
    plan_args = ["plan", "--robot", str(arm["nominal"]), "--method", "quintic", "--duration", "3"]
    work = run_json(capsys, *plan_args)["methods"]["quintic"]["abs_work"]
    identified_work = run_json(capsys, *plan_args, "--sidecar", str(out))["methods"]["quintic"]
    assert identified_work["abs_work"] != pytest.approx(work, rel=0.01)
    plain = load_robot(str(arm["nominal"]))
    identified = load_robot(str(arm["nominal"]), sidecar=out)
    q = np.full((1, N), 0.4)
    zero = np.zeros((1, N))
    assert not np.allclose(
        plain.dynamics().inverse_dynamics(q, zero, zero),
        identified.dynamics().inverse_dynamics(q, zero, zero),
    )


def _quintic(t: np.ndarray, start: np.ndarray, goal: np.ndarray, duration: float) -> np.ndarray:
    s = np.clip(t / duration, 0.0, 1.0)[:, None]
    return start + (goal - start) * (10 * s**3 - 15 * s**4 + 6 * s**5)


def test_plan_validated_against_itself_recovers_a_planted_shift(capsys, arm, tmp_path):
    robot = load_robot(str(arm["true"]))
    start, goal, duration = np.zeros(N), np.array([0.6, 0.9, -0.5]), 2.0
    t_plan = np.linspace(0.0, duration, 201)
    methods = {}
    for name, stretch in (("quintic", 1.0), ("paper", 0.8)):
        q = _quintic(t_plan, start, goal, duration * stretch)
        methods[name] = {
            "kind": "samples",
            "t": t_plan.tolist(),
            "q": q.tolist(),
            "metrics": {"abs_work": 10.0 if name == "quintic" else 9.0},
        }
    plan = tmp_path / "plan.json"
    plan.write_text(
        json.dumps({"motion": {"joint_names": list(robot.joint_names), "methods": methods}})
    )
    shift, rate = 0.7372, 500.0
    t = np.arange(int(4.0 * rate)) / rate
    q = _quintic(t - shift, start, goal, duration)
    qd = np.gradient(q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    tau = mujoco_torques(robot, q, qd, qdd)
    log = write_generic_csv(tmp_path / "run.csv", t, robot.joint_names, q, tau, qd)
    data = run_json(
        capsys, "validate", "--robot", str(arm["true"]), "--log", str(log), "--plan", str(plan)
    )
    result = data["plan"]
    assert result["method"] == "quintic"
    assert result["time_shift_s"] == pytest.approx(shift, abs=1.0 / rate)
    assert max(result["tracking_error_rms_rad"].values()) < 2e-3
    assert result["saving_pct"]["planned"] == pytest.approx(0.0)
    assert "measured" in result["saving_pct"]
    # Without --plan there is no plan block.
    assert "plan" not in run_json(
        capsys, "validate", "--robot", str(arm["true"]), "--log", str(log)
    )


def test_bad_logs_are_refused_with_a_clear_message(capsys, arm, tmp_path):
    t, q, _, _ = excitation(3.0, 100.0, N)
    wrong = write_generic_csv(tmp_path / "wrong.csv", t, ("a", "b", "c"), q, np.zeros_like(q))
    code = main(["validate", "--robot", str(arm["nominal"]), "--log", str(wrong)])
    err = capsys.readouterr().err
    assert code == 2 and "wrong.csv" in err and "['a', 'b', 'c']" in err and "joint1" in err
    short = write_generic_csv(
        tmp_path / "short.csv",
        t[:150],
        ("joint1", "joint2", "joint3"),
        q[:150],
        np.ones_like(q[:150]),
    )
    code = main(
        [
            "identify",
            "--robot",
            str(arm["nominal"]),
            "--log",
            str(short),
            "--out",
            str(tmp_path / "x.yaml"),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and "expected at least 2 s" in err
    assert not (tmp_path / "x.yaml").exists()


def test_validate_topic_chooses_the_bag_topic(capsys, arm, tmp_path):
    from tests.utils.robot_logs import write_bag

    robot = load_robot(str(arm["true"]))
    t, q, qd, qdd = excitation(4.0, 100.0, N, seed=2)
    tau = mujoco_torques(robot, q, qd, qdd)
    bag = write_bag(
        tmp_path / "bag",
        t,
        robot.joint_names,
        q,
        qd,
        tau,
        other=("/joint_states_offset", tau + 5.0),
    )
    base = ["validate", "--robot", str(arm["true"]), "--log", str(bag)]
    default = run_json(capsys, *base)  # two topics: /joint_states is taken
    offset = run_json(capsys, *base, "--topic", "/joint_states_offset")
    assert _residual(default) < 0.1
    assert _residual(offset) > 10.0


@pytest.mark.parametrize(
    "option",
    [["--cutoff-hz", "4"], ["--payload", "1.0"], ["--identify-payload"], ["--lock", "joint3=30"]],
)
def test_every_identify_option_changes_the_result(capsys, arm, tmp_path, option):
    base = ["identify", "--robot", str(arm["nominal"]), "--log", str(arm["log"])]
    plain = run_json(capsys, *base, "--out", str(tmp_path / "a.yaml"))
    changed = run_json(capsys, *base, "--out", str(tmp_path / "b.yaml"), *option)
    assert changed["held_back"] != plain["held_back"]
    if option == ["--identify-payload"]:
        assert changed["payload"]["mass"] > 0.5  # the true arm carries 1 kg
    if option[0] == "--lock":
        assert "locks" in (tmp_path / "b.yaml").read_text()


def test_ur_log_with_currents_reports_electrical_energy(capsys, tmp_path):
    """A UR RTDE CSV of motor currents: torque and electrical energy through the motor model."""
    from app.planning.energy import FRICTION_VELOCITY_SCALE
    from tests.utils.robot_logs import write_ur_csv

    robot = load_robot("curtain_wall_6dof")
    t, q, qd, qdd = excitation(6.0, 250.0, 6, seed=4, amplitude=0.4)
    rigid = robot.dynamics().inverse_dynamics(q, qd, qdd)
    viscous = np.array([m.viscous_friction for m in robot.motors])
    coulomb = np.array([m.coulomb_friction for m in robot.motors])
    total = rigid + viscous * qd + coulomb * np.tanh(qd / FRICTION_VELOCITY_SCALE)
    gain = np.array([m.gear_ratio * m.torque_constant for m in robot.motors])
    log = write_ur_csv(tmp_path / "ur.csv", t, q, qd, current=total / gain)
    data = run_json(capsys, "validate", "--robot", "curtain_wall_6dof", "--log", str(log))
    for row in data["joints"].values():
        assert row["r2"] > 0.99
    energy = data["electrical_energy"]
    assert energy["measured"] == pytest.approx(energy["predicted"], rel=0.03)
    code = main(["validate", "--robot", "curtain_wall_6dof", "--log", str(log)])
    text = capsys.readouterr().out
    assert code == 0 and "electrical: measured" in text and "torque constant" in text


def test_a_real_plan_file_is_aligned_to_its_executed_method(capsys, arm, tmp_path):
    """`bioplan plan --json --out`, its jerk-limited motion run 0.8123 s into a log."""
    plan = tmp_path / "plan.json"
    run_json(
        capsys,
        "plan",
        "--robot",
        str(arm["true"]),
        "--method",
        "quintic,jerk_limited",
        "--duration",
        "3",
        "--out",
        str(plan),
    )
    motion = json.loads(plan.read_text())["motion"]["methods"]["jerk_limited"]
    t_plan, q_plan = np.array(motion["t"]), np.array(motion["q"])
    robot = load_robot(str(arm["true"]))
    shift, rate = 0.8123, 500.0
    t = np.arange(int(5.0 * rate)) / rate
    q = np.stack([np.interp(t - shift, t_plan, q_plan[:, j]) for j in range(N)], axis=1)
    qd = np.gradient(q, t, axis=0)
    tau = mujoco_torques(robot, q, qd, np.gradient(qd, t, axis=0))
    log = write_generic_csv(tmp_path / "run.csv", t, robot.joint_names, q, tau, qd)
    result = run_json(
        capsys, "validate", "--robot", str(arm["true"]), "--log", str(log), "--plan", str(plan)
    )["plan"]
    assert result["method"] == "jerk_limited"
    assert result["time_shift_s"] == pytest.approx(shift, abs=1.0 / rate)
    assert result["abs_work"]["measured"] == pytest.approx(result["abs_work"]["planned"], rel=0.02)
