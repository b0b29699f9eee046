"""Shared fixtures, and the tiny robot models tests use, written inline.

Helpers live in ``tests/utils/`` (import them from there, never from another test module).
Real third-party recordings live in ``../shared/data`` beside the repository (never copied
into it); tests that need them skip with a clear reason when that folder is absent.
``BIOPLAN_SHARED_DATA`` points elsewhere if needed.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.utils.data import REPO_ROOT, SHARED_DATA, shared_file

__all__ = ["REPO_ROOT", "SHARED_DATA", "TWO_LINK_URDF", "shared_file"]

#: A planar two-link arm (shoulder and elbow pitch about y, hanging down): masses, inertias and
#: limits that the planning package accepts and a test can check against the XML.
TWO_LINK_URDF = """<?xml version="1.0"?>
<robot name="two_link">
  <link name="base"/>
  <link name="upper"><inertial><origin xyz="0 0 -0.15"/><mass value="2.0"/>
    <inertia ixx="0.02" iyy="0.02" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="fore"><inertial><origin xyz="0 0 -0.12"/><mass value="1.5"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <axis xyz="0 1 0"/><limit lower="-1.0" upper="2.5" effort="80" velocity="3.0"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/>
    <origin xyz="0 0 -0.3"/><axis xyz="0 1 0"/>
    <limit lower="0.0" upper="2.6" effort="40" velocity="5.0"/></joint>
</robot>
"""


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Root of the shared real-data folder; skips the test when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real test data not found at {SHARED_DATA} (set BIOPLAN_SHARED_DATA)")
    return SHARED_DATA


@pytest.fixture
def two_link_urdf() -> str:
    """:data:`TWO_LINK_URDF`."""
    return TWO_LINK_URDF
