"""Real third-party robots from the ``example-robot-data`` package (a test dependency).

The package ships its URDFs and meshes under ``share/example-robot-data/robots`` of its
install prefix; the files are found through the installed distribution, never by a fixed path.
Tests that need them skip with a clear reason when the package is not installed.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path

import pytest

#: URDFs used by the tests, relative to the ``robots`` folder.
UR5 = "ur_description/urdf/ur5_robot.urdf"
UR10 = "ur_description/urdf/ur10_robot.urdf"
PANDA = "panda_description/urdf/panda.urdf"
#: Panda's fingers, locked half open [m] (finger 2 mimics finger 1 and follows it).
PANDA_LOCKS = {"panda_finger_joint1": 0.02}


def robots_dir() -> Path:
    """The ``robots`` folder of example-robot-data, or a pytest skip saying why."""
    try:
        dist = distribution("example-robot-data")
    except PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (pip install -e '.[test]')")
    for entry in dist.files or ():
        parts = Path(str(entry)).parts
        if "robots" in parts and parts[parts.index("robots") - 1] == "example-robot-data":
            cut = parts.index("robots") + 1
            return Path(str(dist.locate_file(Path(*parts[:cut]))))
    pytest.skip("example-robot-data is installed but ships no robots folder")


def robot_file(relative: str) -> Path:
    """One URDF of example-robot-data (skips when absent)."""
    path = robots_dir() / relative
    if not path.is_file():
        pytest.skip(f"example-robot-data has no {relative}")
    return path
