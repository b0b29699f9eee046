"""Shared fixtures, and the tiny robot models tests use, written inline.

Helpers live in ``tests/utils/`` (import them from there, never from another test module).
Real third-party recordings live in ``../shared/data`` beside the repository (never copied
into it); tests that need them skip with a clear reason when that folder is absent.
``BIOPLAN_SHARED_DATA`` points elsewhere if needed.
"""

from __future__ import annotations

import os
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


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """With ``BIOPLAN_TEST_TIMINGS=FILE``, append each test phase's seconds to FILE as it ends
    (``seconds phase nodeid``): where a run's time goes, even from a run that is cut short."""
    path = os.environ.get("BIOPLAN_TEST_TIMINGS")
    # Under pytest-xdist the controller hears every worker's report again (``report.node``).
    if path and getattr(report, "node", None) is None:
        with open(path, "a", encoding="utf-8") as f:
            f.write(f"{report.duration:.2f} {report.when} {report.nodeid}\n")


#: The files that take longest (from a ``BIOPLAN_TEST_TIMINGS`` run of the whole suite on two
#: workers, 2026-11-27), longest first. They are collected first, and ``make test`` runs
#: ``--dist loadfile --no-loadscope-reorder`` (xdist otherwise orders files by their number of
#: tests), which hands a worker the next file whenever it runs dry: the long files start first
#: and the short ones fill in behind them, where a long file started last would hold up the
#: end of the run while the other worker idles. Refresh it from a timings run when it drifts.
LONGEST_FIRST = (
    "tests/test_readme.py",
    "tests/api/test_security.py",
    "tests/api/test_plans_api.py",
    "tests/api/test_recordings.py",
    "tests/api/test_robots_api.py",
    "tests/api/test_analyses_options.py",
    "tests/frontend/test_browser.py",
    "tests/test_cli_front.py",
    "tests/frontend/test_compare_page.py",
    "tests/api/test_fronts_api.py",
    "tests/frontend/test_recording_pages.py",
    "tests/api/test_schemathesis.py",
    "tests/api/test_cohorts_api.py",
    "tests/api/test_dashboard.py",
    "tests/frontend/test_stream_reconnect.py",
    "tests/test_cli.py",
    "tests/api/test_robot_upload_bombs.py",
    "tests/planning/test_front.py",
    "tests/test_cli_analyze.py",
)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """:data:`LONGEST_FIRST` files first (a stable sort: the order inside each file stays)."""
    rank = {path: i for i, path in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))
