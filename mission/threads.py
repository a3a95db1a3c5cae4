"""Thread limits for the numerical libraries' pools (OpenMP: k-means; BLAS; onnxruntime's own), one
policy in one place: ``$RFSL_THREADS`` (``compute_threads``, default 1) applied by the
``thread_limits`` context manager where a command starts (``mission.cli.main.run_guarded``) and
around k-means, and by ``limit_worker`` as the entry of each worker process a command's pool starts.

Why 1: per flight k-means and the networks run for milliseconds, and on a busy 2-core machine their
thread pools spin-wait against each other (k-means 0.38 s with the default threads vs 0.02 s with
one; ``benchmarks/bench_localize.py``); a pool's workers already fill the cores.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
from collections.abc import Iterator
from multiprocessing.context import BaseContext

from threadpoolctl import ThreadpoolController

from mission.errors import InputError

THREADS_ENV = "RFSL_THREADS"


def pool_context() -> BaseContext:
    """The start method of the package's process pools: ``spawn``, whatever the platform's default.

    Why: a forked child inherits the locks of the parent's threads (OpenMP's k-means pool,
    onnxruntime's) but not the threads, and can wait on them forever: a test worker's dataset pool,
    forked after another test had fixed the default start method to ``fork``, hung until killed.
    A spawned worker costs its imports once (about a second) and shares nothing it did not ask for.
    """
    return multiprocessing.get_context("spawn")


def compute_threads() -> int:
    """Threads for k-means (OpenMP), BLAS and onnxruntime: ``$RFSL_THREADS`` (default 1; 0 = the
    libraries' own choice)."""
    raw = os.environ.get(THREADS_ENV, "").strip()
    if not raw:
        return 1
    try:
        n = int(raw)
    except ValueError:
        raise InputError(f"{THREADS_ENV} must be a whole number of threads, got {raw!r}") from None
    if n < 0:
        raise InputError(f"{THREADS_ENV} must be >= 0, got {n}")
    return n


@contextlib.contextmanager
def thread_limits(
    n: int | None = None, controller=None, user_api: str | None = None
) -> Iterator[None]:
    """Limit the thread pools of the libraries loaded now to ``n`` threads (None:
    ``compute_threads()``; 0: no limit) for the ``with`` block, then restore them.  ``controller``:
    a ``threadpoolctl.ThreadpoolController`` made once by the caller (making one scans the loaded
    libraries: ~10 ms); ``user_api``: "openmp" or "blas" only."""
    n = compute_threads() if n is None else int(n)
    if n <= 0:
        yield
        return
    if controller is None:
        controller = ThreadpoolController()
    with controller.limit(limits=n, user_api=user_api):
        yield


def limit_worker() -> None:
    """A pool worker's entry (``ProcessPoolExecutor(initializer=limit_worker)``): the worker runs
    its whole life with one OpenMP/BLAS thread (scikit-learn's OpenMP runtime loaded first so that
    the limit reaches it; ``OMP_NUM_THREADS`` for runtimes loaded later); never restored, the worker
    ends with it."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    # lazy on purpose (noqa): loaded after OMP_NUM_THREADS is set, so its OpenMP runtime starts
    # with one thread
    import sklearn.cluster  # noqa: F401, PLC0415

    ThreadpoolController().limit(limits=1)
