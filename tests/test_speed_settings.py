"""Speed settings change no result: thread limits are applied (onnxruntime session, k-means' OpenMP)
and the self-calibrating grid's pre-rotated gain tables equal the per-sample index formula."""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from sklearn.cluster import KMeans
from threadpoolctl import threadpool_info, threadpool_limits

from mission import threads
from mission.cli.main import run_guarded
from mission.errors import InputError
from mission.localize.features import FeatureConfig, cluster_features
from mission.localize.onnx_model import OnnxLocalizer
from mission.localize.selfcal import GainLookup
from mission.physics.antenna import rm_wb1_dn
from mission.threads import compute_threads, limit_worker

MODEL = Path(__file__).resolve().parents[1] / "models" / "rfsl_spiral_e2r.onnx"


def _flight(n: int = 3000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    t = np.linspace(0, 6 * np.pi, n)
    x, y = 100 + t * 8 * np.cos(t), 120 + t * 8 * np.sin(t)
    rss = -20 * np.log10(np.hypot(x - 90, y - 140) + 5) + rng.normal(0, 2, n)
    return x, y, rss


def test_thread_count_from_environment(monkeypatch) -> None:
    monkeypatch.delenv(threads.THREADS_ENV, raising=False)
    assert compute_threads() == 1
    monkeypatch.setenv(threads.THREADS_ENV, "3")
    assert compute_threads() == 3
    for bad in ("two", "-1"):
        monkeypatch.setenv(threads.THREADS_ENV, bad)
        with pytest.raises(InputError, match=threads.THREADS_ENV):
            compute_threads()


@pytest.mark.skipif(not MODEL.is_file(), reason="shipped model absent")
def test_onnx_session_thread_options(monkeypatch) -> None:
    monkeypatch.delenv(threads.THREADS_ENV, raising=False)
    opts = OnnxLocalizer(MODEL).session.get_session_options()
    assert (opts.intra_op_num_threads, opts.inter_op_num_threads) == (1, 1)
    assert opts.get_session_config_entry("session.intra_op.allow_spinning") == "0"
    monkeypatch.setenv(threads.THREADS_ENV, "2")
    assert OnnxLocalizer(MODEL).session.get_session_options().intra_op_num_threads == 2
    # ort default
    assert OnnxLocalizer(MODEL, threads=0).session.get_session_options().intra_op_num_threads == 0
    one, dflt = OnnxLocalizer(MODEL, threads=1), OnnxLocalizer(MODEL, threads=0)
    f = np.random.default_rng(0).normal(size=(4, one.n_features))
    np.testing.assert_array_equal(one.predict_features(f), dflt.predict_features(f))


def test_kmeans_runs_under_the_openmp_limit(monkeypatch) -> None:
    seen: list[list[int]] = []
    orig = KMeans.fit_predict

    def spy(self, *a, **k):
        seen.append([i["num_threads"] for i in threadpool_info() if i["user_api"] == "openmp"])
        return orig(self, *a, **k)

    monkeypatch.setattr(KMeans, "fit_predict", spy)
    x, y, rss = _flight()
    cfg = FeatureConfig(c_k=8)
    monkeypatch.delenv(threads.THREADS_ENV, raising=False)
    one = cluster_features(x, y, rss, cfg)
    assert seen and all(n == 1 for n in seen[-1])
    monkeypatch.setenv(threads.THREADS_ENV, "0")  # the libraries' own choice: same features
    np.testing.assert_array_equal(cluster_features(x, y, rss, cfg), one)


def test_mounted_gain_tables_equal_the_index_formula() -> None:
    look = GainLookup(rm_wb1_dn())
    rng = np.random.default_rng(1)
    i_el, i_az = rng.integers(0, 181, 5000), rng.integers(0, 360, 5000)
    flat = i_el * 360 + i_az
    up, fl = look.upright.ravel(), look.flipped.ravel()
    for head in (0, 30, 62, 330):
        np.testing.assert_array_equal(
            look.gain_db(flat, head, True), fl[i_el * 360 + np.mod(i_az - head, 360)]
        )
        np.testing.assert_array_equal(
            look.gain_db(flat, head, False), up[i_el * 360 + np.mod(head - i_az, 360)]
        )


def _pool_threads() -> list[int]:
    return sorted({i["num_threads"] for i in threadpool_info()})


def test_commands_and_pool_workers_run_under_the_limit(monkeypatch) -> None:
    """A command body (``run_guarded``) runs with ``$RFSL_THREADS`` threads and the process is
    restored after; a pool worker started with ``limit_worker`` runs its whole life with one (OpenMP
    included)."""
    seen: list[list[int]] = []
    with threadpool_limits(limits=2):
        monkeypatch.setenv(threads.THREADS_ENV, "1")
        assert run_guarded(lambda: seen.append(_pool_threads())) == 0
        assert seen == [[1]] and _pool_threads() == [2]
        monkeypatch.setenv(threads.THREADS_ENV, "x")
        # bad value: one line
        assert run_guarded(lambda: seen.append(_pool_threads())) == 2 and len(seen) == 1
    with ProcessPoolExecutor(1, initializer=limit_worker) as ex:
        assert ex.submit(_pool_threads).result() == [1]
