"""Robot packages from a folder or a zip: safe extraction, package:// resolution, loading."""

from __future__ import annotations

import shutil
import stat
import zipfile
from pathlib import Path

import pytest

from app.planning.robots import RobotError, load_robot, open_robot_package, resolve_mesh
from tests.utils.example_robots import UR5, robot_file


def _zip(path: Path, members: dict[str, bytes], *, link: str | None = None) -> Path:
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
        if link is not None:
            info = zipfile.ZipInfo(link)
            info.external_attr = (stat.S_IFLNK | 0o777) << 16
            archive.writestr(info, "/etc/passwd")
    return path


def _ur_package(tmp_path: Path) -> Path:
    """A zip of UR5's URDF and meshes laid out as a ROS package would be."""
    urdf = robot_file(UR5)
    meshes = urdf.parents[1] / "meshes" / "ur5"
    members = {"ur_description/urdf/ur5_robot.urdf": urdf.read_bytes()}
    members["ur_description/package.xml"] = b"<package><name>ur_description</name></package>"
    for mesh in meshes.rglob("*"):
        if mesh.is_file():
            members[f"ur_description/meshes/ur5/{mesh.relative_to(meshes)}"] = mesh.read_bytes()
    return _zip(tmp_path / "ur5.zip", members)


def test_a_zip_is_extracted_and_its_meshes_found(tmp_path: Path) -> None:
    package = open_robot_package(_ur_package(tmp_path), tmp_path / "robots" / "ur5")
    urdf = package.only_urdf()
    assert urdf.is_relative_to(tmp_path / "robots" / "ur5")
    reference = "package://example-robot-data/robots/ur_description/meshes/ur5/visual/base.dae"
    # the file names another package; the uploaded one resolves its own package:// paths
    assert resolve_mesh(reference, base_dir=urdf.parent, package_dirs=package.package_dirs) is None
    own = "package://ur_description/meshes/ur5/visual/base.dae"
    found = resolve_mesh(own, base_dir=urdf.parent, package_dirs=package.package_dirs)
    assert found == package.root / "ur_description/meshes/ur5/visual/base.dae"
    relative = resolve_mesh("../meshes/ur5/visual/base.dae", base_dir=urdf.parent)
    assert relative == found
    robot = load_robot(urdf, package_dirs=package.package_dirs)
    assert robot.package_dirs == package.package_dirs


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("../evil.urdf", "points outside the archive"),
        ("a/../../evil.urdf", "points outside the archive"),
        ("/etc/evil.urdf", "absolute path"),
        ("C:/evil.urdf", "absolute path"),
    ],
)
def test_a_zip_escaping_its_folder_is_refused_before_extraction(
    tmp_path: Path, name: str, message: str
) -> None:
    archive = _zip(tmp_path / "bad.zip", {"robot.urdf": b"<robot/>", name: b"x"})
    dest = tmp_path / "out"
    with pytest.raises(RobotError, match=message) as info:
        open_robot_package(archive, dest)
    assert "\n" not in str(info.value)
    assert not dest.exists()  # nothing was extracted, not even the good member
    assert not (tmp_path / "evil.urdf").exists()


def test_links_and_non_zips_are_refused(tmp_path: Path) -> None:
    archive = _zip(tmp_path / "link.zip", {"robot.urdf": b"<robot/>"}, link="meshes")
    with pytest.raises(RobotError, match="symbolic link"):
        open_robot_package(archive, tmp_path / "out")
    text = tmp_path / "robot.txt"
    text.write_text("not a zip")
    with pytest.raises(RobotError, match="neither a folder nor a zip"):
        open_robot_package(text)
    with pytest.raises(RobotError, match="needs a folder to extract into"):
        open_robot_package(archive)


def test_members_that_cannot_be_written_are_bad_input(tmp_path: Path) -> None:
    """A name longer than the file system allows, a file where a folder must go, a corrupt
    stream: each a RobotError naming the member (were OSError and zlib.error: a 500)."""
    damaged = tmp_path / "d.zip"
    with zipfile.ZipFile(damaged, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("robot.urdf", b"<robot name='r'/>" * 400)
    data = bytearray(damaged.read_bytes())
    start = data.index(b"robot.urdf") + len("robot.urdf") + 8  # inside the deflate stream
    data[start : start + 24] = bytes(b ^ 0xFF for b in data[start : start + 24])
    damaged.write_bytes(bytes(data))
    for archive, member, reason in (
        (_zip(tmp_path / "l.zip", {"x" * 300 + ".urdf": b"<robot/>"}), "x" * 79 + "…", "too long"),
        (_zip(tmp_path / "c.zip", {"a": b"1", "a/robot.urdf": b"2"}), "a/robot.urdf", "exists"),
        (damaged, "robot.urdf", "decompressing"),
    ):
        with pytest.raises(RobotError, match=reason) as caught:
            open_robot_package(archive, tmp_path / archive.stem)
        assert f"member '{member}" in str(caught.value) and len(str(caught.value)) < 300


def test_a_folder_is_opened_in_place(tmp_path: Path) -> None:
    folder = tmp_path / "arm"
    shutil.copytree(robot_file(UR5).parent, folder / "urdf")
    package = open_robot_package(folder)
    assert package.root == folder.resolve() and len(package.urdfs) == 9
    with pytest.raises(RobotError, match="expected exactly one"):
        package.only_urdf()
