"""Shared test fixtures (the location of ../shared, real data, skipped cleanly where absent) and the test tiers.

Tiers: a plain ``pytest`` (no paths named) runs the fast tier only, leaving out the tests marked ``slow``
(end-to-end flights, the gap self-test, builds, anything over a few seconds) and ``real`` (reads the real AFAR
flights in ../shared; every test using the ``shared_dir`` fixture is marked so automatically).
``pytest --all`` runs every tier (CI and the README's test command do); naming files or node ids
(``pytest tests/test_x.py``) runs all their tests; ``-m EXPR`` selects by marker as usual.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# MAVLink 2 for every test, fixed before anything imports pymavlink (its dialect module is chosen once,
# at first import, from this variable; mixing versions breaks pymavlink's waypoint loader).
os.environ.setdefault("MAVLINK20", "1")

REPO = Path(__file__).resolve().parents[1]
FULL_TIERS = ("slow", "real")  # left out of a plain `pytest`
_LEFT_OUT = pytest.StashKey[int]()  # how many tests a plain run left out
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


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--all", action="store_true", dest="all_tiers",
                     help="run every test tier: also the slow and real-data tests a plain `pytest` leaves out")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark the tests that read ../shared as ``real``; in a plain run, deselect the slow and real tiers."""
    for item in items:
        if "shared_dir" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.real)
    fast_only = (not config.getoption("all_tiers") and not config.option.markexpr
                 and config.args_source == pytest.Config.ArgsSource.TESTPATHS)
    if not fast_only:
        return
    keep = [it for it in items if not any(it.get_closest_marker(m) for m in FULL_TIERS)]
    left = [it for it in items if it not in set(keep)]
    if left:
        config.hook.pytest_deselected(items=left)
        items[:] = keep
        config.stash[_LEFT_OUT] = len(left)


def pytest_terminal_summary(terminalreporter, config: pytest.Config) -> None:
    n = config.stash.get(_LEFT_OUT, 0)
    if n:
        terminalreporter.write_line(f"fast tier: {n} slow / real-data tests not run (pytest --all runs every tier)")
