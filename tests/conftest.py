"""Shared test fixtures (the location of ../shared, real data, skipped cleanly where absent) and the
test tiers.

Tiers: a plain ``pytest`` (no paths named) runs the fast tier only, leaving out the tests marked
``slow`` (end-to-end flights, the gap self-test, builds, anything over a few seconds) and ``real``
(reads the real AFAR flights in ../shared; every test using the ``shared_dir`` fixture is marked so
automatically). ``pytest --all`` runs every tier (CI and the README's test command do); naming files
or node ids (``pytest tests/test_x.py``) runs all their tests; ``-m EXPR`` selects by marker as
usual. Parallel runs (``pytest -n auto``, pytest-xdist) are safe: temporary paths are per test, the
simulated vehicles and ArduPilot SITL take ports the OS hands out (or checks free), and every worker
starts its slow tests first.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# MAVLink 2 for every test, fixed before anything imports pymavlink (its dialect module is chosen
# once, at first import, from this variable; mixing versions breaks pymavlink's waypoint loader).
os.environ.setdefault("MAVLINK20", "1")
# One BLAS/OpenMP thread per test process (and the fly-mission / vehicle subprocesses, which inherit
# it), set before numpy or torch is imported: on a busy 2-core machine (parallel test workers, other
# jobs) their default pools of spinning threads slow small matrix work by 10-100x (a tiny network's
# backward pass: 16 ms alone, 1.7 s contended).
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# Property tests draw their examples from a fixed seed under CI (every random result reproducible; a
# red CI is then a failure anyone can rerun); locally they keep exploring new examples.
from hypothesis import settings as _hsettings  # noqa: E402

_hsettings.register_profile("ci", derandomize=True, database=None)
if os.environ.get("CI"):
    _hsettings.load_profile("ci")

REPO = Path(__file__).resolve().parents[1]
FULL_TIERS = ("slow", "real")  # left out of a plain `pytest`
# Slow tests in files that other work was editing when the tiers were introduced, marked here
# instead of in the file (a test file's own ``@pytest.mark.slow`` / ``pytestmark`` is the usual
# place; move them there in time): whole files (the gap self-test on the independent generator,
# network training) and single tests (file::name, every parametrisation), each over ~3 s on a quiet
# 2-core machine.
SLOW_FILES = ("test_gap_independent.py", "test_train.py")
SLOW_TESTS = (
    "test_altitude_scale.py::test_training_flag_writes_the_metadata_that_inference_obeys",
    "test_gap_diagnosis.py::test_cli_gap_on_a_simulated_log",
    "test_gap_diagnosis.py::test_cli_gap_json_prints_the_summary",
    "test_preview.py::test_preview_accuracy_png",
    "test_dataset.py::test_same_seed_same_bytes_any_workers_and_chunks",
)
_LEFT_OUT = pytest.StashKey[int]()  # how many tests a plain run left out
SHARED = (REPO / ".." / "shared").resolve()


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The read-only ../shared folder (paper, spec, real AFAR data); skip the test where it is
    absent."""
    if not (SHARED / "data").is_dir():
        pytest.skip("../shared is absent (real data only on the development machines)")
    return SHARED


@pytest.fixture(scope="session")
def repo_dir() -> Path:
    return REPO


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--all",
        action="store_true",
        dest="all_tiers",
        help="run every test tier: also the slow and real-data tests a plain `pytest` leaves out",
    )
    parser.addoption(
        "--px4",
        action="store_true",
        dest="px4_only",
        help="run only the PX4 SITL flights, one at a time (each SITL takes a whole core: run "
        "beside "
        "other tests or each other they starve the flights)",
    )


def pytest_configure(config: pytest.Config) -> None:
    """With ``-n`` (pytest-xdist, default ``--dist load``) and no ``--maxschedchunk`` given: hand
    the workers one test at a time.  xdist's default first hands each worker a block of about an
    eighth of the suite in order, so one worker got every slow test (sorted first below) while the
    other ran short ones and then waited."""
    if (
        getattr(config.option, "numprocesses", None)
        and getattr(config.option, "maxschedchunk", 0) is None
    ):
        config.option.maxschedchunk = 1


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark the tests that read ../shared as ``real`` and the listed slow ones ``slow``; in a plain
    run, deselect the slow and real tiers."""
    for item in items:
        if "shared_dir" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.real)
        where = f"{item.path.name}::{getattr(item, 'originalname', item.name)}"
        if item.path.name in SLOW_FILES or where in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)
    px4 = [it for it in items if it.get_closest_marker("px4")]
    if config.getoption("px4_only") or px4:  # --px4: those alone; any other run: all but those
        drop = [it for it in items if (it in set(px4)) != bool(config.getoption("px4_only"))]
        if drop:
            config.hook.pytest_deselected(items=drop)
            items[:] = [it for it in items if it not in set(drop)]
    if os.environ.get("PYTEST_XDIST_WORKER"):
        # parallel workers (pytest -n): the slow tests first (stable otherwise), so that the long
        # ones start early and the short ones fill the end instead of one worker finishing a flight
        # while the others wait
        items.sort(key=lambda it: it.get_closest_marker("slow") is None)
    fast_only = (
        not config.getoption("all_tiers")
        and not config.getoption("px4_only")
        and not config.option.markexpr
        and config.args_source == pytest.Config.ArgsSource.TESTPATHS
    )
    if not fast_only:
        return
    keep = [it for it in items if not any(it.get_closest_marker(m) for m in FULL_TIERS)]
    left = [it for it in items if it not in set(keep)]
    if left:
        config.hook.pytest_deselected(items=left)
        items[:] = keep
        config.stash[_LEFT_OUT] = len(left)
        if hasattr(config, "workeroutput"):  # an xdist worker: the controller prints the line
            config.workeroutput["fast_tier_left_out"] = len(left)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error) -> None:
    """xdist controller: every worker collected the same tests, so any worker's count of left-out
    tests is it."""
    n = getattr(node, "workeroutput", {}).get("fast_tier_left_out")
    if n:
        node.config.stash[_LEFT_OUT] = n


def pytest_terminal_summary(terminalreporter, config: pytest.Config) -> None:
    n = config.stash.get(_LEFT_OUT, 0)
    if n:
        terminalreporter.write_line(
            f"fast tier: {n} slow / real-data tests not run (pytest --all runs every tier)"
        )
