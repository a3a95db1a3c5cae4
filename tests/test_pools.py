"""The package's process pools spawn their workers (``mission.threads.pool_context``), never fork.

Why it matters: a forked child inherits the locks of the parent's OpenMP and onnxruntime threads
without the threads, and can wait on them forever. The default start method gets fixed to ``fork``
by anything that merely uses it (``ProcessPoolExecutor()`` with no context does), after which the
dataset's pool used to fork; a test worker's pool so forked hung until it was killed (313 s).
"""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys

import numpy as np
import pytest

from mission.threads import pool_context
from mission.workshop.dataset import DatasetConfig, iter_rows
from mission.workshop.suite_cache import _map


@pytest.fixture
def fork_forbidden(monkeypatch):
    """The default start method fixed (as ``ProcessPoolExecutor()`` fixes it) and ``os.fork``
    failing: a pool that forks fails the test instead of passing on luck."""
    multiprocessing.get_start_method()

    def no_fork():
        raise AssertionError("a process pool forked")

    monkeypatch.setattr(os, "fork", no_fork)


def test_the_pool_context_is_spawn():
    assert pool_context().get_start_method() == "spawn"


@pytest.mark.slow
def test_dataset_pool_spawns_and_gives_the_one_process_rows(fork_forbidden, repo_dir):
    cfg = DatasetConfig(str(repo_dir / "missions" / "spiral.yaml"), 2, seed=5)
    pooled = list(iter_rows(cfg, workers=2))
    alone = list(iter_rows(cfg, workers=1))
    assert len(pooled) == 2
    for a, b in zip(pooled, alone, strict=True):
        assert a.keys() == b.keys()
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])


def test_suite_cache_pool_spawns(fork_forbidden):
    assert list(_map(abs, [-3, -1, -2], 2)) == [3, 1, 2]


def test_the_gap_fits_forked_pool_ends_under_a_parent_signal_handler(tmp_path):
    """``gap.fit._map`` forks (its closures cannot be pickled). A parent with a Python SIGTERM
    handler (a test's, a CLI's) gave it to the workers, the pool's terminate could not end a
    worker waiting on the task-queue lock, and a CI run hung in its join. In a child process with
    such a handler, the map must return its results within the timeout."""
    code = (
        "import signal\n"
        "signal.signal(signal.SIGTERM, lambda *a: None)\n"
        "from mission.gap.fit import _map\n"
        "for _ in range(5):\n"
        "    out = _map(lambda x: x * x, list(range(6)), workers=1, processes=2)\n"
        "print(out)\n"
    )
    r = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path
    )
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip() == "[0, 1, 4, 9, 16, 25]"
