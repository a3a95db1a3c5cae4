"""Features: grouping and smoothing closed forms, offset invariance, determinism, ordering,
shapes."""

from __future__ import annotations

import numpy as np
import pytest
from _localize_helpers import synthetic_flight

from mission.errors import InputError
from mission.localize.features import (
    LATER_KEYS,
    FeatureConfig,
    cluster_details,
    cluster_features,
    cluster_features_batch,
    gaussian_kernel,
    gaussian_smooth,
    grouping,
    normalised_rss,
    preprocess,
    resample_by_arc,
    summarise_clusters,
)


def test_kernel_closed_form():
    for sigma in (1.0, 5.0, 20.0):
        k = gaussian_kernel(sigma)
        assert k.size == 6 * int(sigma) + 1
        assert k.sum() == pytest.approx(1.0, abs=1e-12)
        assert np.argmax(k) == k.size // 2
        np.testing.assert_allclose(k, k[::-1])


def test_grouping_and_smoothing():
    v = np.arange(11.0)
    np.testing.assert_allclose(grouping(v, 2), [0.5, 2.5, 4.5, 6.5, 8.5])
    np.testing.assert_allclose(grouping(np.vstack([v, 2 * v]), 2)[1], 2 * grouping(v, 2))
    c = np.full(500, -42.0)
    np.testing.assert_allclose(gaussian_smooth(c, 20.0), c)  # a constant stays constant
    lin = np.linspace(0, 10, 500)
    # linear kept inside
    np.testing.assert_allclose(gaussian_smooth(lin, 5.0)[50:-50], lin[50:-50], atol=1e-9)


def test_shape_offset_invariance_and_determinism():
    enu, rss, _ = synthetic_flight()
    cfg = FeatureConfig()
    v = cluster_features(enu[:, 0], enu[:, 1], rss, cfg)
    assert v.shape == (3 * cfg.c_k,)
    np.testing.assert_allclose(
        cluster_features(enu[:, 0], enu[:, 1], rss + 37.5, cfg), v, atol=1e-9
    )
    np.testing.assert_array_equal(cluster_features(enu[:, 0], enu[:, 1], rss, cfg), v)
    p = v[0::3]
    assert np.all(np.diff(p) <= 0)  # ordered by relative RSS, descending
    assert p.max() <= 0  # relative dB


def test_order_independent_of_label_numbering():
    enu, rss, _ = synthetic_flight(n=4000)
    cfg = FeatureConfig(c_k=8, n_t=10)
    gx, gy, gp = preprocess(enu[:, 0], enu[:, 1], rss, cfg)
    labels = np.arange(gx.size) * 8 // gx.size
    perm = np.random.default_rng(3).permutation(8)
    a = summarise_clusters(gx, gy, gp, labels, cfg)
    b = summarise_clusters(gx, gy, gp, perm[labels], cfg)
    np.testing.assert_array_equal(a.vector, b.vector)
    np.testing.assert_array_equal(a.labels, b.labels)


def test_small_clusters_use_all_samples_and_top_n():
    cfg = FeatureConfig(n_g=1, sigma=0, c_k=2, n_t=3)
    x = np.array([0.0, 1, 2, 100, 101])
    p = np.array([-1.0, -2, -3, -10, -20])
    r = summarise_clusters(x, np.zeros(5), p, np.array([0, 0, 0, 1, 1]), cfg)
    np.testing.assert_allclose(r.vector, [-2 - (-1), 1, 0, -15 - (-1), 100.5, 0])
    cfg2 = FeatureConfig(n_g=1, sigma=0, c_k=1, n_t=2)
    r2 = summarise_clusters(x, np.zeros(5), p, np.zeros(5, int), cfg2)
    np.testing.assert_allclose(r2.vector, [-0.5, 0.5, 0])
    assert r2.top.tolist() == [True, True, False, False, False]


def test_batch_matches_single_and_handles_shared_xy():
    enu, _, _ = synthetic_flight(n=3000)
    rng = np.random.default_rng(1)
    rss = np.stack(
        [
            synthetic_flight(tx=t, n=3000, seed=i)[1]
            for i, t in enumerate([(100, 100, 1.5), (200, 60, 1.5), (50, 240, 1.5)])
        ]
    )
    cfg = FeatureConfig(c_k=10, n_t=20)
    batch = cluster_features_batch(enu[:, :2], rss, cfg)
    per = cluster_features_batch(np.broadcast_to(enu[:, :2], (3, 3000, 2)), rss, cfg)
    assert batch.shape == (3, 30)
    np.testing.assert_allclose(batch, per)
    for i in range(3):
        np.testing.assert_allclose(
            batch[i], cluster_features(enu[:, 0], enu[:, 1], rss[i], cfg), atol=1e-9
        )
    del rng


def test_details_and_config_roundtrip():
    enu, rss, _ = synthetic_flight(n=3000)
    cfg = FeatureConfig(c_k=5)
    d = cluster_details(enu[:, 0], enu[:, 1], rss, cfg)
    assert set(np.unique(d.labels)) == set(range(5))
    assert d.top.sum() == 5 * cfg.n_t
    assert FeatureConfig.from_dict(cfg.to_dict()) == cfg
    assert cfg.mismatch(FeatureConfig(c_k=6)) == "c_k"
    with pytest.raises(InputError, match="bogus"):
        FeatureConfig.from_dict({**cfg.to_dict(), "bogus": 1})
    with pytest.raises(InputError):
        cluster_features(enu[:8, 0], enu[:8, 1], rss[:8], cfg)
    with pytest.raises(InputError):
        cluster_features(enu[:, 0], enu[:, 1], np.where(np.arange(3000) == 5, np.nan, rss), cfg)


def test_normalised_rss():
    _, rss, _ = synthetic_flight(n=3000)
    cfg = FeatureConfig(rss_length=1000)
    a = normalised_rss(rss, cfg)
    assert a.shape == (1000,) and -0.1 < a.max() <= 0.0
    np.testing.assert_allclose(normalised_rss(rss + 12.0, cfg), a, atol=1e-12)
    b = normalised_rss(np.stack([rss, rss - 3]), cfg)
    np.testing.assert_allclose(b[0], a)
    np.testing.assert_allclose(b[1], a, atol=1e-12)


def test_arc_resampling_collapses_hovers_and_ignores_speed():
    """``resample_by_arc``: a hover becomes one averaged point, a path flown at 1 m/s or 5 m/s gives
    the same points, GPS jitter while hovering adds no path, and features with ``arc_step_m`` see
    the same flight at any speed."""
    rng = np.random.default_rng(0)
    dt = 0.03

    def leg(speed, hover_s=0.0, jitter=0.0):
        t = np.arange(0, 100.0 / speed, dt)
        x = speed * t
        if hover_s:
            x = np.concatenate(
                [x[: len(x) // 2], np.full(int(hover_s / dt), x[len(x) // 2]), x[len(x) // 2 :]]
            )
        y = np.zeros_like(x) + rng.normal(0, jitter, x.size)
        rss = -40.0 - 0.2 * x
        return x, y, rss

    fast = resample_by_arc(*leg(5.0), 0.15)
    slow = resample_by_arc(*leg(1.0), 0.15)
    hover = resample_by_arc(*leg(5.0, hover_s=60.0, jitter=0.05), 0.15)
    n = len(slow[0])
    assert n == pytest.approx(100 / 0.15, rel=0.01)
    assert len(fast[0]) == pytest.approx(n, rel=0.03) and len(hover[0]) == pytest.approx(
        n, rel=0.05
    )
    assert np.diff(slow[0]).mean() == pytest.approx(0.15, rel=0.01)
    np.testing.assert_allclose(np.interp(fast[0], slow[0], slow[2]), fast[2], atol=0.05)
    assert resample_by_arc(*leg(5.0), 0.0)[0].size == leg(5.0)[0].size  # off: untouched

    cfg = FeatureConfig(arc_step_m=0.15, c_k=6, n_t=10)
    xs = np.linspace(0, 200, 3000)
    path_x = np.concatenate([xs, xs[::-1]])
    path_y = np.concatenate([np.zeros(3000), np.full(3000, 30.0)])
    rss = -40.0 - 0.1 * np.hypot(path_x - 120, path_y - 10)
    # the same path, crept over at a fifth of the speed on its first leg (as AFAR team 288 did in
    # places)
    slow_idx = np.repeat(np.arange(6000), np.where(np.arange(6000) < 3000, 5, 1))
    a = cluster_features(path_x, path_y, rss, cfg).reshape(-1, 3)
    b = cluster_features(path_x[slow_idx], path_y[slow_idx], rss[slow_idx], cfg).reshape(-1, 3)
    np.testing.assert_allclose(a[:, 0], b[:, 0], atol=0.3)
    np.testing.assert_allclose(a[:, 1:], b[:, 1:], atol=3.0)
    plain = FeatureConfig(c_k=6, n_t=10)
    pa = cluster_features(path_x, path_y, rss, plain).reshape(-1, 3)
    pb = cluster_features(path_x[slow_idx], path_y[slow_idx], rss[slow_idx], plain).reshape(-1, 3)
    # without resampling the crept leg takes more clusters
    assert np.abs(pa[:, 1:] - pb[:, 1:]).max() > 10.0


def test_configs_written_before_a_later_key_still_match():
    old = {k: v for k, v in FeatureConfig().to_dict().items() if k not in LATER_KEYS}
    assert FeatureConfig.normalised(old) == FeatureConfig().to_dict()
    assert FeatureConfig.normalised(FeatureConfig(arc_step_m=0.2).to_dict())["arc_step_m"] == 0.2
    with pytest.raises(ValueError):
        FeatureConfig(arc_step_m=-1.0)
