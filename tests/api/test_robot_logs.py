"""Robot logs through the API: upload (validated before it is stored), validation against the
nominal and the identified robot and against a plan, identification as a job that stores a new
robot version, and every bad log refused with a clear message and nothing stored.

The logs are synthetic: MuJoCo's inverse dynamics (``mj_inverse``) of a *true* arm (heavier
second link, a 1 kg payload) plus viscous friction and noise, while the robot uploaded is the
nominal arm; the identified version must then predict the log (and plan) like the true arm.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sqlalchemy import func, select

from app.db.models import JobRecord, RobotLogRecord
from app.planning.robots import load_robot
from tests.utils.api import TestClient, assert_problem, wait_job
from tests.utils.robot_logs import (
    arm_urdf,
    excitation,
    mujoco_torques,
    write_bag,
    write_generic_csv,
)

N = 3
RATE = 200.0  # [Hz]
VISCOUS = 0.8  # [Nm s/rad], every joint
NOISE = 0.05  # [Nm]
TRUE_MASSES = [4.0, 4.2, 3.0]
TRUE_PAYLOAD = 1.0  # [kg]


@pytest.fixture(scope="module")
def arm(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("robot-logs")
    true = folder / "true.urdf"
    true.write_text(arm_urdf(N, masses=TRUE_MASSES, payload=TRUE_PAYLOAD))
    friction = folder / "friction.yaml"
    friction.write_text(
        "friction:\n" + "".join(f"  joint{j + 1}: {{viscous: {VISCOUS}}}\n" for j in range(N))
    )
    robot = load_robot(str(true))
    t, q, qd, qdd = excitation(12.0, RATE, N, seed=9)
    rng = np.random.default_rng(1)
    tau = mujoco_torques(robot, q, qd, qdd) + VISCOUS * qd + rng.normal(0, NOISE, q.shape)
    log = write_generic_csv(folder / "log.csv", t, robot.joint_names, q, tau)
    return {
        "folder": folder,
        "nominal": arm_urdf(N).encode(),
        "true": true,
        "friction": friction,
        "t": t,
        "q": q,
        "qd": qd,
        "tau": tau,
        "log": log,
        "names": list(robot.joint_names),
    }


def _upload_robot(client: TestClient, arm: dict[str, Any], name: str = "arm") -> None:
    r = client.post(
        "/api/robots", data={"name": name}, files={"urdf": ("arm.urdf", arm["nominal"])}
    )
    assert r.status_code == 201, r.text


def _upload_log(client: TestClient, robot: str, name: str, data: bytes, **form: str) -> Any:
    return client.post(
        "/api/robot-logs", data={"robot": robot, **form}, files={"file": (name, data)}
    )


def _residuals(result: dict[str, Any]) -> np.ndarray:
    return np.array([row["residual_rms"] for row in result["joints"].values()])


def _plan(client: TestClient, robot: str) -> dict[str, Any]:
    body = {"robot": robot, "duration": 1.0, "methods": ["quintic"], "particles": 4}
    r = client.post("/api/plans", json={**body, "iterations": 2})
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"], timeout=300)
    assert job["state"] == "succeeded", job
    out: dict[str, Any] = client.get(job["result_url"]).json()
    return out


def _count(client: TestClient, model: Any) -> int:
    services = client.app.state.services  # type: ignore[attr-defined]
    with services.sessions() as session:
        return int(session.scalar(select(func.count()).select_from(model)) or 0)


def _blobs(client: TestClient) -> set[str]:
    return set(client.app.state.services.blobs.hashes())  # type: ignore[attr-defined]


def test_upload_validate_identify_and_plan_with_the_identified_version(
    client: TestClient, arm: dict[str, Any]
) -> None:
    from app.planning.validation import validate
    from app.recordings import read_robot_log

    _upload_robot(client, arm)
    r = _upload_log(client, "arm", "log.csv", arm["log"].read_bytes(), label="excitation")
    assert r.status_code == 201, r.text
    log = r.json()
    assert log["format"] == "csv" and log["robot"] == "arm" and log["label"] == "excitation"
    assert log["joint_names"] == arm["names"] and log["rate_hz"] == pytest.approx(RATE)
    assert log["samples"] == arm["t"].size
    # The upload's validation is the library's (the CLI's) on the same file and robot.
    nominal_urdf = arm["folder"] / "nominal.urdf"
    nominal_urdf.write_bytes(arm["nominal"])
    library = validate(load_robot(str(nominal_urdf)), read_robot_log(arm["log"])).result
    stored = log["validation"]
    assert _residuals(stored) == pytest.approx(_residuals(library), rel=1e-9)
    assert stored["abs_work"] == pytest.approx(library["abs_work"], rel=1e-9)
    assert [x["id"] for x in client.get("/api/robot-logs?robot=arm").json()] == [log["id"]]
    assert client.get("/api/robot-logs?robot=other").json() == []

    nominal = client.get(f"/api/robot-logs/{log['id']}/validation").json()
    series = nominal["series"]
    assert series["joints"] == arm["names"]
    assert len(series["measured"]) == N and len(series["measured"][0]) == len(series["t"])
    assert _residuals(nominal) == pytest.approx(_residuals(library), rel=1e-9)
    # The cutoff option changes the result.
    slow = client.get(f"/api/robot-logs/{log['id']}/validation?cutoff_hz=3").json()
    assert slow["filter"]["cutoff_hz"] == 3.0
    assert not np.allclose(_residuals(slow), _residuals(nominal), rtol=1e-3)

    jobs_before = _count(client, JobRecord)
    r = client.post("/api/identifications", json={"log_ids": [log["id"]], "label": "lab"})
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"], timeout=300)
    assert job["state"] == "succeeded", job
    assert job["kind"] == "identify" and _count(client, JobRecord) == jobs_before + 1
    ident = client.get(job["result_url"]).json()
    assert ident["robot"] == "arm" and ident["version"] == "arm-identified"
    assert ident["result"]["held_back"], "20 % of the log is held back by default"
    # Identified friction is the planted viscous friction (within the noise's reach).
    for row in ident["result"]["friction"].values():
        assert row["viscous"] == pytest.approx(VISCOUS, abs=0.15)

    robots = {r["name"]: r for r in client.get("/api/robots").json()}
    version = robots["arm-identified"]
    assert version["identified_from"] == {
        "robot": "arm",
        "log_ids": [log["id"]],
        "job_id": job["id"],
    }
    assert robots["arm"]["identified_from"] is None
    assert version["joint_names"] == robots["arm"]["joint_names"]

    # Against the identified version the log's residuals fall to the noise's order, and the
    # predicted work comes close to the measured one.
    better = client.get(f"/api/robot-logs/{log['id']}/validation?robot=arm-identified").json()
    assert np.all(_residuals(better) < 0.5 * _residuals(nominal))
    work = better["abs_work"]
    assert abs(work["predicted"] - work["measured"]) < 0.5 * abs(
        nominal["abs_work"]["predicted"] - nominal["abs_work"]["measured"]
    )
    assert abs(work["predicted"] - work["measured"]) < 0.05 * work["measured"]

    # The version plans with other predictions than the nominal robot, close to the true
    # arm's (planned here by the library with its true friction).
    from app.planning import plan

    planned_nominal = _plan(client, "arm")
    planned_version = _plan(client, "arm-identified")
    true_robot = load_robot(str(arm["true"]), sidecar=arm["friction"])
    truth = plan(true_robot, duration=1.0, methods=["quintic"], particles=4, iterations=2)
    true_work = truth.to_dict()["methods"]["quintic"]["abs_work"]
    w_nominal = planned_nominal["result"]["methods"]["quintic"]["abs_work"]
    w_version = planned_version["result"]["methods"]["quintic"]["abs_work"]
    assert abs(w_version - true_work) < 0.5 * abs(w_nominal - true_work)
    assert abs(w_version - true_work) < 0.05 * true_work

    # A second identification of the same robot gets the next free name; a taken one is a 409.
    r = client.post("/api/identifications", json={"log_ids": [log["id"]], "version": "arm"})
    assert_problem(r, 409, field="version")

    # The log of the planned motion, started 0.7 s in: validated with the plan, the alignment
    # finds the planted shift and the tracking error of a perfectly tracked plan is ~0.
    _plan_alignment(client, arm, planned_nominal)

    # Deleting the log removes its row and its file (the version stays).
    sha = _log_sha(client, log["id"])
    assert client.delete(f"/api/robot-logs/{log['id']}").status_code == 204
    assert sha not in _blobs(client)
    assert client.get(f"/api/robot-logs/{log['id']}").status_code == 404
    assert client.get("/api/robots/arm-identified").status_code == 200


def _log_sha(client: TestClient, log_id: int) -> str:
    services = client.app.state.services  # type: ignore[attr-defined]
    with services.sessions() as session:
        row = session.get(RobotLogRecord, log_id)
        assert row is not None
        return str(row.sha256)


SHIFT = 0.7  # [s] the planted start of the plan in its log


def _plan_alignment(client: TestClient, arm: dict[str, Any], planned: dict[str, Any]) -> None:
    motion = planned["result"]["motion"]
    method = motion["methods"]["quintic"]
    t_plan, q_plan = np.asarray(method["t"]), np.asarray(method["q"])
    t = np.arange(round((SHIFT + t_plan[-1] + 1.0) * RATE) + 1) / RATE
    q = np.stack([np.interp(t - SHIFT, t_plan, q_plan[:, j]) for j in range(N)], axis=1)
    qd = np.gradient(q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    true_robot = load_robot(str(arm["true"]))
    tau = mujoco_torques(true_robot, q, qd, qdd) + VISCOUS * qd
    path = write_generic_csv(arm["folder"] / "planned.csv", t, arm["names"], q, tau)
    r = _upload_log(client, "arm", "planned.csv", path.read_bytes())
    assert r.status_code == 201, r.text
    log_id = r.json()["id"]
    without = client.get(f"/api/robot-logs/{log_id}/validation").json()
    assert "plan" not in without
    out = client.get(f"/api/robot-logs/{log_id}/validation?plan={planned['id']}").json()
    assert out["plan_id"] == planned["id"]
    assert out["plan"]["method"] == "quintic"
    assert out["plan"]["time_shift_s"] == pytest.approx(SHIFT, abs=1.5 / RATE)
    assert max(out["plan"]["tracking_error_rms_rad"].values()) < 0.01
    # A plan that does not exist is a 404 naming the field.
    assert_problem(client.get(f"/api/robot-logs/{log_id}/validation?plan=99999"), 404)


# -- refusals ------------------------------------------------------------------------------


def _csv(arm: dict[str, Any], rows: slice = slice(None), names: list[str] | None = None) -> str:
    buffer = io.StringIO()
    t, q, tau = arm["t"][rows], arm["q"][rows], arm["tau"][rows]
    names = names or arm["names"]
    header = ["time"] + [f"{n}/{k}" for n in names for k in ("position", "effort")]
    table = np.column_stack([t] + [c for j in range(N) for c in (q[:, j], tau[:, j])])
    np.savetxt(buffer, table, delimiter=",", header=",".join(header), comments="", fmt="%.10g")
    return buffer.getvalue()


def _bad_logs(arm: dict[str, Any]) -> dict[str, tuple[str, list[str]]]:
    """name -> (CSV text, words the refusal must contain)."""
    lines = _csv(arm).splitlines()
    back = list(lines)
    back[101], back[102] = back[102], back[101]  # data line 102 goes back in time
    nan = [lines[0]] + [
        ",".join(
            "" if (200 <= k < 220 and c == 3) else cell for c, cell in enumerate(row.split(","))
        )
        for k, row in enumerate(lines[1:])
    ]
    no_torque = [
        ",".join(
            cell
            for c, cell in enumerate(row.split(","))
            if c == 0 or c % 2 == 1  # time and positions
        )
        for row in lines
    ]
    return {
        "wrong joint names": (
            _csv(arm, names=["joint1", "elbow", "joint3"]),
            ["joint2", "elbow", "not in the log"],
        ),
        "time going back": ("\n".join(back) + "\n", ["line 10"]),
        "a NaN run": ("\n".join(nan) + "\n", ["joint2/position", "NaN"]),
        "too short": (_csv(arm, slice(0, 20)), ["20 samples", "at least 30"]),
        "no torque": ("\n".join(no_torque) + "\n", ["torque"]),
        "not a log": ("hello,world\n1,2\n", ["not a robot log"]),
    }


def test_every_bad_log_is_refused_naming_what_is_wrong_and_nothing_is_stored(
    client: TestClient, arm: dict[str, Any]
) -> None:
    _upload_robot(client, arm)
    blobs = _blobs(client)
    for case, (text, words) in _bad_logs(arm).items():
        r = _upload_log(client, "arm", f"{case.replace(' ', '_')}.csv", text.encode())
        body = assert_problem(r, 422)
        assert body["detail"].startswith(f"{case.replace(' ', '_')}.csv"), (case, body)
        for word in words:
            assert word in body["detail"], (case, word, body["detail"])
    assert_problem(_upload_log(client, "arm", "empty.csv", b""), 422)
    assert_problem(_upload_log(client, "nobody", "log.csv", arm["log"].read_bytes()), 404)
    assert _count(client, RobotLogRecord) == 0 and _blobs(client) == blobs
    assert client.get("/api/robot-logs").json() == []


def test_identification_requests_refused_before_a_job(
    client: TestClient, arm: dict[str, Any]
) -> None:
    _upload_robot(client, arm)
    # 2.2 s validates, but after holding back 20 % it is too short to identify from.
    short = _csv(arm, slice(0, round(2.2 * RATE)))
    r = _upload_log(client, "arm", "short.csv", short.encode())
    assert r.status_code == 201, r.text
    short_id = r.json()["id"]
    # A built-in robot's log validates, but a built-in takes no identified sidecar.
    t, q = arm["t"][:1000], np.zeros((1000, 2))
    human = write_generic_csv(
        arm["folder"] / "human.csv", t, ["shoulder_flexion", "elbow_flexion"], q, q
    )
    r = _upload_log(client, "human_arm_2dof", "human.csv", human.read_bytes())
    assert r.status_code == 201, r.text
    human_id = r.json()["id"]
    jobs = _count(client, JobRecord)
    body = assert_problem(
        client.post("/api/identifications", json={"log_ids": [short_id]}), 422, field="log_ids"
    )
    assert "short.csv" in body["detail"] and "at least 2 s" in body["detail"]
    # Held back less, the same log has enough to fit: the option changes the answer.
    plain = client.post(
        "/api/identifications", json={"log_ids": [short_id], "validate_fraction": 0.0}
    )
    assert plain.status_code == 202, plain.text
    jobs += 1
    assert_problem(client.post("/api/identifications", json={"log_ids": [human_id]}), 409)
    assert_problem(client.post("/api/identifications", json={"log_ids": [short_id, human_id]}), 409)
    assert_problem(client.post("/api/identifications", json={"log_ids": [99999]}), 404)
    assert_problem(client.post("/api/identifications", json={"log_ids": []}), 422)
    assert _count(client, JobRecord) == jobs

    # Every option of an identification reaches it: the name, the label, the cutoff and the
    # payload (identified instead of the last link's inertia).
    options = {"version": "custom", "label": "lab", "cutoff_hz": 4.0, "identify_payload": True}
    r = client.post(
        "/api/identifications",
        json={"log_ids": [short_id], "validate_fraction": 0.0, **options},
    )
    assert r.status_code == 202, r.text
    default = client.get(wait_job(client, plain.json()["id"], timeout=300)["result_url"]).json()
    chosen_job = wait_job(client, r.json()["id"], timeout=300)
    assert chosen_job["state"] == "succeeded", chosen_job
    chosen = client.get(chosen_job["result_url"]).json()
    assert default["job"]["state"] == "succeeded", default["job"]
    assert (default["version"], chosen["version"]) == ("arm-identified", "custom")
    assert (default["job"]["label"], chosen["job"]["label"]) == (None, "lab")
    assert default["result"]["filter"]["cutoff_hz"] == 10.0
    assert chosen["result"]["filter"]["cutoff_hz"] == 4.0
    assert default["result"]["payload"] is None and chosen["result"]["payload"]["mass"] > 0
    assert default["result"]["held_back"] == {} and chosen["result"]["held_back"] == {}
    names = [i["version"] for i in client.get("/api/identifications?robot=arm").json()["items"]]
    assert names == ["custom", "arm-identified"]
    assert client.get("/api/identifications?robot=other").json()["items"] == []


def test_a_zipped_ros2_bag_is_read(client: TestClient, arm: dict[str, Any], tmp_path: Path) -> None:
    _upload_robot(client, arm)
    rows = slice(0, 600)
    other = 2.0 * arm["tau"][rows]  # the same motion, torques doubled, on a second topic
    bag = write_bag(
        tmp_path / "bag",  # per test: the arm's folder is shared by the database variants
        arm["t"][rows],
        arm["names"],
        arm["q"][rows],
        None,
        arm["tau"][rows],
        storage="sqlite3",
        other=("/other_states", other),
    )
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for path in Path(bag).iterdir():
            archive.write(path, f"bag/{path.name}")
    r = _upload_log(client, "arm", "bag.zip", buffer.getvalue())
    assert r.status_code == 201, r.text
    assert r.json()["format"] == "ros2_bag" and r.json()["samples"] == 600
    # The same motion as CSV validates to the same residuals (the bag's /joint_states).
    csv = _upload_log(client, "arm", "same.csv", _csv(arm, rows).encode()).json()
    assert _residuals(r.json()["validation"]) == pytest.approx(
        _residuals(csv["validation"]), rel=1e-6
    )
    # The topic option reads the other topic: its measured torques are doubled (the filter is
    # linear).
    r2 = _upload_log(client, "arm", "bag.zip", buffer.getvalue(), topic="/other_states")
    assert r2.status_code == 201, r2.text
    assert r2.json()["topic"] == "/other_states"
    doubled = r2.json()["validation"]["joints"]
    for name, row in csv["validation"]["joints"].items():
        assert doubled[name]["rms_measured"] == pytest.approx(2 * row["rms_measured"], rel=1e-6)
    body = assert_problem(
        _upload_log(client, "arm", "bag.zip", buffer.getvalue(), topic="/nope"), 422
    )
    assert "/nope" in body["detail"] and "/other_states" in body["detail"]
    # The validation of a stored bag reads its topic again.
    again = client.get(f"/api/robot-logs/{r2.json()['id']}/validation").json()
    assert _residuals(again) == pytest.approx(_residuals(r2.json()["validation"]), rel=1e-9)
