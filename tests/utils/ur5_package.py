"""The UR5 of example-robot-data as an upload: a zip of its URDF with its visual and collision
meshes, laid out as example-robot-data lays them out (``package://`` paths resolve in it)."""

from __future__ import annotations

import io
import zipfile

from tests.utils.example_robots import UR5, robot_file, robots_dir


def ur5_package(*, meshes: tuple[str, ...] = ("visual", "collision")) -> bytes:
    """The zip's bytes; ``meshes`` names the mesh folders of ``meshes/ur5`` it holds."""
    urdf = robot_file(UR5)
    base = robots_dir().parent.parent  # .../share: package://example-robot-data/robots/...
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr(str(urdf.relative_to(base)), urdf.read_bytes())
        for kind in meshes:
            for mesh in (urdf.parents[1] / "meshes" / "ur5" / kind).rglob("*"):
                if mesh.is_file():
                    archive.writestr(str(mesh.relative_to(base)), mesh.read_bytes())
    return buffer.getvalue()
