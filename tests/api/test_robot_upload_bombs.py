"""Robot uploads that cost far more than their size (issue 15 items 6, 7, 8, 9, 11, 13).

A 0.87 MB zip held a 300 MB STL the viewer then parsed in the API process; an MJCF cube
texture's ``fileright`` read any server file; a 1 MB zip left 1.07 GB on disk with no quota; a
sidecar's numbers and nesting were server errors; ``<replicate>`` split across included files
passed the copy limit. Every zip is built here, in the test's folder.
"""

from __future__ import annotations

import io
import logging
import struct
import zipfile
import zlib
from pathlib import Path

import pytest

from app.planning.robots._package import (
    MJCF_FILE_ATTRIBUTES,
    MeshLimitError,
    MeshLimits,
    check_mesh,
    check_mjcf_files,
    check_package_zip,
)
from app.planning.robots._types import RobotError
from tests.conftest import TWO_LINK_URDF
from tests.utils.api import TestClient, assert_problem, make_client

MB = 1024 * 1024


def _urdf_with_mesh(filename: str) -> str:
    """The two-link arm with a visual mesh on its upper link."""
    visual = f'<visual><geometry><mesh filename="{filename}"/></geometry></visual>'
    return TWO_LINK_URDF.replace('<link name="upper">', f'<link name="upper">{visual}', 1)


def _zeros(archive: zipfile.ZipFile, name: str, size: int, head: bytes = b"") -> None:
    """A member of ``size`` bytes: ``head``, then zeros (they deflate to almost nothing)."""
    info = zipfile.ZipInfo(name)
    info.compress_type = zipfile.ZIP_DEFLATED
    with archive.open(info, "w", force_zip64=size > 2**31) as out:
        out.write(head)
        left, block = size - len(head), bytes(MB)
        while left > 0:
            out.write(block[: min(left, MB)])
            left -= MB


def _binary_stl_head(triangles: int) -> bytes:
    return b"\0" * 80 + struct.pack("<I", triangles)


def _package(members: dict[str, bytes | int], stl_heads: dict[str, bytes] | None = None) -> bytes:
    """A zip of ``members``: bytes as given, an int as that many bytes (a head, then zeros)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, content in members.items():
            if isinstance(content, int):
                _zeros(archive, name, content, (stl_heads or {}).get(name, b""))
            else:
                archive.writestr(name, content)
    return buffer.getvalue()


def _small_stl(triangles: int) -> bytes:
    """A binary STL of ``triangles`` small distinct triangles."""
    out = [_binary_stl_head(triangles)]
    for i in range(triangles):
        x = 0.001 * i
        out.append(struct.pack("<12fH", 0, 0, 1, x, 0, 0, x + 0.01, 0, 0, x, 0.01, 0, 0))
    return b"".join(out)


def laughs() -> str:
    """Nested anchors inside a field (so the old reader's error message spelled them out):
    nine aliases a level, 9**9 strings in all, in under 400 bytes."""
    levels = ["&a [" + ",".join(['"lol"'] * 9) + "]"]
    for p, n in zip("abcdefgh", "bcdefghi", strict=True):
        levels.append(f"&{n} [" + ",".join([f"*{p}"] * 9) + "]")
    return "locks: [" + ", ".join(levels) + "]\n"


def _robots(client: TestClient) -> list[str]:
    return [r["name"] for r in client.get("/api/robots").json() if not r["builtin"]]


# ------------------------------------------------------------------------- item 6: meshes


def test_a_300_mb_stl_in_a_small_zip_is_refused_naming_the_member(tmp_path: Path) -> None:
    triangles = 6_000_000  # 84 + 50 * 6e6 bytes: a header that agrees with its size
    size = 84 + 50 * triangles
    package = _package(
        {"arm/robot.urdf": _urdf_with_mesh("meshes/big.stl").encode(), "arm/meshes/big.stl": size},
        {"arm/meshes/big.stl": _binary_stl_head(triangles)},
    )
    assert len(package) < 1 * MB and size > 300_000_000
    with make_client(tmp_path) as client:
        r = client.post(
            "/api/robots", data={"name": "bomb"}, files={"package": ("bomb.zip", package)}
        )
        problem = assert_problem(r, 422, file="bomb.zip", field="package")
        detail = problem["detail"]
        assert "member 'arm/meshes/big.stl'" in detail, detail
        assert f"expected at most {64 * MB} bytes per mesh" in detail, detail
        assert "BIOPLAN_MAX_MESH_MB" in detail, detail
        assert _robots(client) == []
        assert not list((tmp_path / "data").rglob("big.stl"))  # nothing extracted


def test_meshes_past_the_triangle_cap_or_lying_headers_are_refused(tmp_path: Path) -> None:
    urdf = _urdf_with_mesh("meshes/m.stl").encode()
    cases = {
        # 5,000 triangles in 250 KB: under the byte cap, over a 1,000-triangle cap
        "many.zip": ({"robot.urdf": urdf, "meshes/m.stl": _small_stl(5000)}, "5000 triangles"),
        # a header claiming a billion triangles in 1 KB
        "liar.zip": (
            {"robot.urdf": urdf, "meshes/m.stl": _binary_stl_head(10**9) + bytes(1000)},
            "header states 1000000000 triangles",
        ),
        # ASCII STL and OBJ faces are counted from the text
        "ascii.zip": (
            {"robot.urdf": urdf, "meshes/m.stl": b"solid x\n" + b"facet\nendfacet\n" * 1500},
            "triangles: expected at most 1000 triangles per mesh",
        ),
        "obj.zip": (
            {"robot.urdf": urdf, "meshes/m.obj": b"v 0 0 0\n" + b"f 1 1 1\n" * 1200},
            "triangles: expected at most 1000 triangles per mesh",
        ),
        "dae.zip": (
            {"robot.urdf": urdf, "meshes/m.dae": b'<COLLADA><triangles count="99999"/></COLLADA>'},
            "99999 triangles",
        ),
    }
    with make_client(tmp_path, max_mesh_triangles=1000) as client:
        for name, (members, expected) in cases.items():
            r = client.post(
                "/api/robots", data={"name": "m"}, files={"package": (name, _package(members))}
            )
            detail = assert_problem(r, 422, file=name, field="package")["detail"]
            assert expected in detail and "member 'meshes/m." in detail, detail
            assert "BIOPLAN_MAX_MESH_TRIANGLES" in detail, detail
        assert _robots(client) == []


def test_a_real_robot_package_passes_the_mesh_caps() -> None:
    """UR5 and Panda (example-robot-data) with every mesh: the default caps let them in."""
    from tests.utils.example_robots import PANDA, UR5, robot_file, robots_dir

    base = robots_dir()
    for relative in (UR5, PANDA):
        folder = robot_file(relative).parents[1]
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in folder.rglob("*"):
                if path.is_file():
                    archive.write(path, str(path.relative_to(base)))
        unpacked = check_package_zip(buffer.getvalue(), name="real.zip", limits=MeshLimits())
        assert unpacked > 1 * MB
    for path in base.rglob("*"):  # every mesh of the package, one by one
        if path.suffix.lower() in (".stl", ".dae", ".obj"):
            assert check_mesh(path, MeshLimits()) is None, path


def test_the_viewer_skips_a_stored_mesh_past_the_caps(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A mesh already stored (uploaded before the caps, or under larger ones) is never parsed
    by the viewer in the API process: it is skipped with a warning, the robot still drawn."""
    from app.viewer import kinematics

    folder = tmp_path / "robot"
    (folder / "meshes").mkdir(parents=True)
    (folder / "meshes" / "small.stl").write_bytes(_small_stl(20))
    (folder / "meshes" / "big.stl").write_bytes(_small_stl(300))
    urdf = folder / "robot.urdf"

    def drawn(mesh: str) -> int:
        urdf.write_text(_urdf_with_mesh(f"meshes/{mesh}"))
        model = kinematics.load_urdf(urdf, meshes=True, allowed_roots=(folder,))
        return sum(len(g.faces) for g in model.scene.geometry.values())

    try:
        kinematics.use_mesh_limits(MeshLimits(max_triangles=100))
        assert drawn("small.stl") == 20
        with caplog.at_level(logging.WARNING, logger="app.viewer.kinematics"):
            assert drawn("big.stl") == 0
        assert any("big.stl: a mesh of 300 triangles" in r.message for r in caplog.records)
        kinematics.use_mesh_limits(MeshLimits(max_bytes=1000))
        assert drawn("small.stl") == 0  # 1,084 bytes: past the byte cap
    finally:
        kinematics.use_mesh_limits(None)
    assert drawn("big.stl") == 300  # the defaults let it in


# ----------------------------------------------------------- item 7: every MJCF file attribute


def _png() -> bytes:
    """A 1x1 PNG (a file a server might hold)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0)
    pixels = zlib.compress(b"\0\xff\x00\x00")
    return (
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", pixels) + chunk(b"IEND", b"")
    )


_ARM_MJCF = """<mujoco><compiler angle="radian"/>
  <asset>{asset}</asset>
  <worldbody><body name="upper"><joint name="shoulder" axis="0 1 0" range="-1 2"/>
    <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03"/>
    <body name="fore" pos="0 0 -0.3"><joint name="elbow" axis="0 1 0" range="0 2.5"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.25" size="0.03"/></body></body></worldbody>
  <actuator><motor joint="shoulder" gear="80" ctrlrange="-1 1"/>
    <motor joint="elbow" gear="40" ctrlrange="-1 1"/></actuator>
</mujoco>"""


def test_a_cube_texture_face_outside_the_upload_is_refused_alike(tmp_path: Path) -> None:
    """``<texture fileright=...>`` pointing at a server PNG and at no file: one 422 message
    (no existence oracle), nothing stored, the PNG's bytes nowhere in the data folder."""
    secret = tmp_path / "secret" / "face.png"
    secret.parent.mkdir()
    secret.write_bytes(_png())
    missing = tmp_path / "secret" / "no-such-face.png"
    details = []
    with make_client(tmp_path / "server") as client:
        for target in (secret, missing, Path("../" * 12 + str(secret).lstrip("/"))):
            faces = " ".join(f'{a}="{target}"' for a in MJCF_FILE_ATTRIBUTES if a != "file")
            model = _ARM_MJCF.format(asset=f'<texture name="sky" type="skybox" {faces}/>')
            r = client.post(
                "/api/robots", data={"name": "cube"}, files={"mjcf": ("arm.xml", model)}
            )
            details.append(assert_problem(r, 422)["detail"])
        assert len(set(details)) == 1, details
        assert "<texture file" in details[0] and "outside the uploaded robot's files" in details[0]
        assert str(secret) not in details[0] and "face.png" not in details[0]
        assert _robots(client) == []
    stored = b"".join(p.read_bytes() for p in (tmp_path / "server").rglob("*") if p.is_file())
    assert _png() not in stored


@pytest.mark.parametrize("attr", MJCF_FILE_ATTRIBUTES)
@pytest.mark.parametrize("element", ["texture", "mesh", "hfield", "skin", "model", "flexcomp"])
def test_every_mjcf_file_attribute_is_confined(tmp_path: Path, element: str, attr: str) -> None:
    """Whatever element carries it, an attribute MuJoCo opens a file by is checked, with one
    message for an existing and a missing target; a path inside the upload passes."""
    secret = tmp_path / "outside.png"
    secret.write_bytes(_png())
    root = tmp_path / "upload"
    root.mkdir()
    (root / "inside.png").write_bytes(_png())
    model = root / "robot.xml"
    messages = set()
    for target in (str(secret), str(tmp_path / "nothing.png"), "../outside.png"):
        model.write_text(f'<mujoco><asset><{element} name="a" {attr}="{target}"/></asset></mujoco>')
        with pytest.raises(RobotError) as info:
            check_mjcf_files(model, root)
        messages.add(str(info.value))
    assert messages == {
        f"robot.xml: <{element} {attr}=...>: a path outside the uploaded robot's files: "
        "expected a relative path inside the upload (a zip holds the included files, meshes "
        "and textures)"
    }
    model.write_text(f'<mujoco><asset><{element} name="a" {attr}="inside.png"/></asset></mujoco>')
    check_mjcf_files(model, root)


def test_an_include_climbing_out_from_the_main_folder_is_refused(tmp_path: Path) -> None:
    """MuJoCo resolves an include from the including file's folder and from the main file's:
    ``../x.xml`` inside ``parts/`` stays inside from the first, climbs out from the second."""
    root = tmp_path / "upload"
    (root / "parts").mkdir(parents=True)
    (root / "robot.xml").write_text('<mujoco><include file="parts/a.xml"/></mujoco>')
    (root / "parts" / "a.xml").write_text('<mujoco><include file="../b.xml"/></mujoco>')
    with pytest.raises(RobotError, match=r"a\.xml: <include file=\.\.\.>: a path outside"):
        check_mjcf_files(root / "robot.xml", root)


# ------------------------------------------------------------- item 13: replicate via include


def _replicate_package(count: int = 40) -> bytes:
    """``count`` copies of a file that makes ``count`` copies: 1,640 in all for 40, never
    more than 40 in one file."""
    body = '<body name="dot"><geom size=".01"/></body>'
    main = _ARM_MJCF.format(asset="").replace(
        "<worldbody>", f'<worldbody><replicate count="{count}" offset="0 0 .01">'
        '<include file="parts/row.xml"/></replicate>', 1,
    )  # fmt: skip
    row = f'<mujoco><replicate count="{count}" offset=".01 0 0">{body}</replicate></mujoco>'
    return _package({"arm/robot.xml": main.encode(), "arm/parts/row.xml": row.encode()})


def test_replicate_copies_count_across_included_files(tmp_path: Path) -> None:
    package = _replicate_package()
    with zipfile.ZipFile(io.BytesIO(package)) as archive:
        archive.extractall(tmp_path)
    with pytest.raises(RobotError, match=r"1640 copies in all .* expected at most 1000"):
        check_mjcf_files(tmp_path / "arm" / "robot.xml", tmp_path)
    with make_client(tmp_path / "server") as client:
        r = client.post(
            "/api/robots",
            data={"name": "rep", "mjcf_member": "arm/robot.xml"},
            files={"package": ("rep.zip", package)},
        )
        detail = assert_problem(r, 422)["detail"]
        assert "<replicate>" in detail and "at most 1000" in detail, detail
        r = client.post(  # 3 x 3 copies: the same files are fine
            "/api/robots",
            data={"name": "rep", "mjcf_member": "arm/robot.xml"},
            files={"package": ("rep.zip", _replicate_package(3))},
        )
        assert r.status_code == 201, r.text


# ---------------------------------------------------------------- item 8: disk amplification


def test_a_small_zip_unpacking_to_a_gigabyte_is_refused(tmp_path: Path) -> None:
    """1 MB of zip, 1.07 GB unpacked: past the per-upload cap (256 MB), nothing written."""
    package = _package({"robot.urdf": TWO_LINK_URDF.encode(), "padding.bin": 1_070_000_000})
    assert len(package) < 1.5 * MB
    with make_client(tmp_path) as client:
        r = client.post(
            "/api/robots", data={"name": "pad"}, files={"package": ("pad.zip", package)}
        )
        detail = assert_problem(r, 422, file="pad.zip", field="package")["detail"]
        assert "unpacks to 1070000" in detail and f"at most {256 * MB} bytes" in detail, detail
        assert "BIOPLAN_MAX_ROBOT_UNPACKED_MB" in detail, detail
        assert _robots(client) == []
    assert not list((tmp_path / "data").rglob("padding.bin"))


def test_uploads_past_the_data_quota_are_refused_and_health_states_it(tmp_path: Path) -> None:
    package = _package({"robot.urdf": TWO_LINK_URDF.encode(), "padding.bin": 3 * MB})
    with make_client(tmp_path / "a", data_quota_mb=2) as client:
        health = client.get("/api/health").json()
        assert health["disk"]["quota_mb"] == 2 and 0 < health["disk"]["used_mb"] < 2
        r = client.post(
            "/api/robots", data={"name": "pad"}, files={"package": ("pad.zip", package)}
        )
        detail = assert_problem(r, 413, file="pad.zip")["detail"]
        assert "2 MB quota (BIOPLAN_DATA_QUOTA_MB)" in detail, detail
        assert _robots(client) == []
    with make_client(tmp_path / "b", data_quota_mb=64) as client:
        r = client.post(
            "/api/robots", data={"name": "pad"}, files={"package": ("pad.zip", package)}
        )
        assert r.status_code == 201, r.text
        disk = client.get("/api/health").json()["disk"]
        assert disk["quota_mb"] == 64 and disk["used_mb"] >= 3  # the unpacked padding counted


# ---------------------------------------------------------- items 9 and 11: sidecars over HTTP


@pytest.mark.parametrize(
    "text",
    [
        "payload:\n  mass: " + "9" * 5000 + "\n",
        "locks: " + "[" * 10_000 + "]" * 10_000 + "\n",
        laughs(),
    ],
    ids=["5000-digits", "10000-deep", "billion-laughs"],
)  # fmt: skip
def test_a_hostile_sidecar_is_a_422_naming_the_sidecar(tmp_path: Path, text: str) -> None:
    with make_client(tmp_path) as client:
        r = client.post(
            "/api/robots",
            data={"name": "arm"},
            files={"urdf": ("arm.urdf", TWO_LINK_URDF.encode()), "sidecar": ("motors.yaml", text)},
        )
        problem = assert_problem(r, 422, file="motors.yaml", field="sidecar")
        assert problem["detail"].startswith("motors.yaml: ") and len(problem["detail"]) < 300
        assert _robots(client) == []


def test_mesh_limit_errors_survive_the_sandbox() -> None:
    """The refusal crosses the parse sandbox's pipe whole (its cap named)."""
    import pickle

    error = MeshLimitError("x.zip: member 'm.stl' is a mesh", "max_triangles")
    again = pickle.loads(pickle.dumps(error))
    assert isinstance(again, MeshLimitError) and again.limit == "max_triangles"
    assert str(again) == str(error)
