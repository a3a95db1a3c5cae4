"""Bootstrap intervals over flights: closed forms and limits."""

import numpy as np
import pytest

from mission.evidence import compare_methods, mean_interval, paired_difference, replicate_weights


def test_flight_bootstrap_matches_standard_error():
    """For many i.i.d. flights the percentile interval approaches mean +- 1.645 sd / sqrt(n)."""
    e = np.random.default_rng(3).exponential(30.0, size=400)
    iv = mean_interval(e, n_boot=4000, seed=1)
    half = 1.645 * e.std(ddof=0) / np.sqrt(len(e))
    assert iv.value == pytest.approx(e.mean())
    assert (iv.hi - iv.lo) / 2 == pytest.approx(half, rel=0.1)


def test_cluster_bootstrap_is_wider_when_groups_share_errors():
    """Two teams whose flights are alike: resampling teams must give a wider interval than flights."""
    e = np.r_[np.full(10, 10.0), np.full(10, 50.0)] + np.random.default_rng(0).normal(0, 1, 20)
    teams = ["a"] * 10 + ["b"] * 10
    flights = mean_interval(e, seed=2)
    by_team = mean_interval(e, teams, seed=2)
    assert by_team.hi - by_team.lo > 2 * (flights.hi - flights.lo)


def test_paired_difference_resolves_a_constant_gain_that_unpaired_spread_hides():
    """b = a + 5 m on every flight: the paired interval is a point at -5 m, never straddling zero."""
    a = np.random.default_rng(1).uniform(5, 250, size=6)
    d = paired_difference(a, a + 5.0, seed=0)
    assert d.value == pytest.approx(-5.0)
    assert d.lo == pytest.approx(-5.0) and d.hi == pytest.approx(-5.0)
    assert d.excludes_zero()
    same = paired_difference(a, a[::-1], seed=0)
    assert not same.excludes_zero()


def test_replicates_are_reproducible_and_count_every_flight_once_on_average():
    w1 = replicate_weights(7, seed=5)
    assert np.array_equal(w1, replicate_weights(7, seed=5))
    assert np.allclose(w1.sum(axis=1), 7)
    assert w1.mean() == pytest.approx(1.0, abs=0.02)
    wg = replicate_weights(6, groups=["x", "x", "y", "y", "y", "z"], seed=5)
    assert np.all(wg[:, 0] == wg[:, 1]) and np.all(wg[:, 2] == wg[:, 4])


def test_compare_methods_reference_difference_is_zero_and_shapes_are_checked():
    errs = {"ref": [10.0, 20.0, 30.0], "other": [12.0, 18.0, 40.0]}
    out = compare_methods(errs, "ref", seed=0)
    assert out["ref"]["diff"].value == 0.0 and out["ref"]["diff"].hi == 0.0
    assert out["other"]["mean"].value == pytest.approx(70.0 / 3)
    with pytest.raises(ValueError):
        compare_methods({"ref": [1.0, 2.0], "x": [1.0]}, "ref")
