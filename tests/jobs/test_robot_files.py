"""Issue 24 item 3: the public loader of uploaded robot files (``app.planning.robots``
``write_robot_files``/``robot_files_in``/``load_robot_files``/``joint_table``), used by the
jobs' ``robot_from_spec``. Checked on the UR5 of example-robot-data against Pinocchio built
straight from the same URDF."""

from __future__ import annotations

import zipfile
from io import BytesIO
from pathlib import Path

import numpy as np
import pytest

from app.jobs.tasks import describe_robot, robot_from_spec
from app.planning.robots import (
    UPLOAD_NAMES,
    RobotError,
    joint_table,
    load_robot_files,
    robot_files_in,
    write_robot_files,
)
from tests.utils.example_robots import UR5, robot_file
from tests.utils.ur5_package import ur5_package


def _pinocchio_gravity(urdf: Path, q: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(urdf))
    return np.asarray(pin.computeGeneralizedGravity(model, model.createData(), q))


def test_a_single_urdf_is_written_under_its_fixed_name_and_loads(tmp_path: Path) -> None:
    urdf = robot_file(UR5)
    spec = {"name": "my ur5", "urdf": urdf.read_bytes()}
    files = write_robot_files(spec, tmp_path / "robot")
    assert files.urdf == tmp_path / "robot" / UPLOAD_NAMES["urdf"]
    assert files.mjcf is None and files.sidecar is None and files.package_dirs == ()
    robot = load_robot_files(files, spec, payload=0.0)
    assert len(robot.joint_names) == 6
    q = np.array([0.3, -1.1, 0.8, -0.4, 1.2, 0.2])
    tau = robot.dynamics(armature=False).inverse_dynamics(q, np.zeros(6), np.zeros(6))
    np.testing.assert_allclose(tau, _pinocchio_gravity(urdf, q), rtol=1e-9, atol=1e-9)
    # read again from the folder (a kept robot): the same files, the same robot
    assert robot_files_in(spec, tmp_path / "robot") == files


def test_a_payload_changes_the_loaded_dynamics(tmp_path: Path) -> None:
    spec = {"name": "ur5", "urdf": robot_file(UR5).read_bytes()}
    files = write_robot_files(spec, tmp_path / "robot")
    q = np.array([0.0, -1.0, 0.5, 0.0, 0.0, 0.0])
    zero = np.zeros(6)
    light = load_robot_files(files, spec, payload=0.0).dynamics(armature=False)
    heavy = load_robot_files(files, spec, payload=3.0).dynamics(armature=False)
    extra = heavy.inverse_dynamics(q, zero, zero) - light.inverse_dynamics(q, zero, zero)
    assert abs(extra[1]) > 1.0  # 3 kg at the flange loads the shoulder lift joint [Nm]


def test_joint_table_matches_the_urdf_read_by_pinocchio(tmp_path: Path) -> None:
    import pinocchio as pin

    urdf = robot_file(UR5)
    spec = {"name": "ur5", "urdf": urdf.read_bytes(), "locks": {"wrist_3_joint": 30.0}}
    robot = load_robot_files(write_robot_files(spec, tmp_path / "robot"), spec)
    model = pin.buildModelFromUrdf(str(urdf))
    rows = {row["name"]: row for row in joint_table(robot)}
    assert list(rows) == [model.names[i] for i in range(1, model.njoints)]
    for i in range(1, model.njoints):
        row = rows[model.names[i]]
        k = model.joints[i].idx_q
        assert row["lower"] == pytest.approx(model.lowerPositionLimit[k])
        assert row["upper"] == pytest.approx(model.upperPositionLimit[k])
        assert row["effort"] == pytest.approx(model.effortLimit[k])
    # the lock is given in degrees and kept in radians
    assert rows["wrist_3_joint"]["locked"] and rows["wrist_3_joint"]["lock_value"] == (
        pytest.approx(np.radians(30.0))
    )
    assert "wrist_3_joint" not in robot.joint_names


def test_a_package_loads_from_its_member_with_its_meshes(tmp_path: Path) -> None:
    member = f"example-robot-data/robots/{UR5}"
    spec = {"name": "ur5", "package": ur5_package(), "urdf_member": member}
    files = write_robot_files(spec, tmp_path / "robot")
    assert files.urdf is not None and files.urdf.name == Path(UR5).name
    assert files.root in files.package_dirs
    with robot_from_spec(spec, folder=tmp_path / "kept") as robot:
        assert len(robot.joint_names) == 6
    # kept: read again from the folder, without the zip being unpacked a second time
    assert (tmp_path / "kept" / ".complete").exists()
    described = describe_robot(spec, folder=tmp_path / "kept")
    assert described["missing_meshes"] == []
    assert [row["name"] for row in described["joints"]] == described["all_joint_names"]


def test_a_member_outside_the_package_is_refused_by_name(tmp_path: Path) -> None:
    buffer = BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("arm/robot.urdf", robot_file(UR5).read_bytes())
    (tmp_path / "secret.urdf").write_bytes(robot_file(UR5).read_bytes())
    spec = {"name": "x", "package": buffer.getvalue(), "urdf_member": "../secret.urdf"}
    with pytest.raises(RobotError, match=r"urdf '\.\./secret\.urdf' is not a file of the robot"):
        write_robot_files(spec, tmp_path / "robot")


def test_no_model_file_is_refused(tmp_path: Path) -> None:
    spec = {"name": "x", "sidecar": b"motors: {}\n"}
    files = write_robot_files(spec, tmp_path / "robot")
    with pytest.raises(RobotError, match="no URDF and no MJCF"):
        load_robot_files(files, spec)
