"""Where the repository and the shared real recordings are.

Real third-party recordings live in ``../shared/data`` beside the repository (never copied
into it); ``BIOPLAN_SHARED_DATA`` points elsewhere if needed. A test that needs one skips with
a clear reason when it is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]
SHARED_DATA = Path(os.environ.get("BIOPLAN_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))


def shared_file(relative: str) -> Path:
    """A file under the shared data folder; skips the calling test when it is absent."""
    path = SHARED_DATA / relative
    if not path.is_file():
        pytest.skip(f"real test data not found: {path}")
    return path
