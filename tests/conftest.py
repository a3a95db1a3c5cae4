"""Shared test fixtures: the location of ../shared (real data), skipped cleanly where absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# MAVLink 2 for every test, fixed before anything imports pymavlink (its dialect module is chosen once,
# at first import, from this variable; mixing versions breaks pymavlink's waypoint loader).
os.environ.setdefault("MAVLINK20", "1")

REPO = Path(__file__).resolve().parents[1]
SHARED = (REPO / ".." / "shared").resolve()


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The read-only ../shared folder (paper, spec, real AFAR data); skip the test where it is absent."""
    if not (SHARED / "data").is_dir():
        pytest.skip("../shared is absent (real data only on the development machines)")
    return SHARED


@pytest.fixture(scope="session")
def repo_dir() -> Path:
    return REPO
