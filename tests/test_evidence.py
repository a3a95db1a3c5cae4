"""Bootstrap intervals over flights, the conformal quantile and coverage intervals: closed forms and
limits."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mission.evidence import (
    compare_methods,
    conformal_quantile,
    coverage_interval,
    mean_interval,
    paired_difference,
    replicate_weights,
)


def test_flight_bootstrap_matches_standard_error():
    """For many i.i.d. flights the percentile interval approaches mean +- 1.645 sd / sqrt(n)."""
    e = np.random.default_rng(3).exponential(30.0, size=400)
    iv = mean_interval(e, n_boot=4000, seed=1)
    half = 1.645 * e.std(ddof=0) / np.sqrt(len(e))
    assert iv.value == pytest.approx(e.mean())
    assert (iv.hi - iv.lo) / 2 == pytest.approx(half, rel=0.1)


def test_cluster_bootstrap_is_wider_when_groups_share_errors():
    """Two teams whose flights are alike: resampling teams must give a wider interval than
    flights."""
    e = np.r_[np.full(10, 10.0), np.full(10, 50.0)] + np.random.default_rng(0).normal(0, 1, 20)
    teams = ["a"] * 10 + ["b"] * 10
    flights = mean_interval(e, seed=2)
    by_team = mean_interval(e, teams, seed=2)
    assert by_team.hi - by_team.lo > 2 * (flights.hi - flights.lo)


def test_paired_difference_resolves_a_constant_gain_that_unpaired_spread_hides():
    """b = a + 5 m on every flight: the paired interval is a point at -5 m, never straddling
    zero."""
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


def test_conformal_quantile_small_example():
    """n = 9 scores 1..9: level 0.5 -> the ceil(10 x 0.5) = 5th smallest; 0.9 -> the 9th; 0.95 ->
    none (inf). (np.quantile 'higher' at k / n, the matched localizer's old rule, picked the 6th at
    0.5.)"""
    s = np.array([7.0, 2.0, 9.0, 1.0, 5.0, 3.0, 8.0, 4.0, 6.0])
    assert conformal_quantile(s, 0.5) == 5.0
    assert conformal_quantile(s, 0.9) == 9.0
    assert conformal_quantile(s, 0.95) == math.inf
    assert conformal_quantile(s, 0.05) == 1.0


@pytest.mark.parametrize("n,level", [(19, 0.5), (99, 0.9), (200, 0.9), (40, 0.5)])
def test_conformal_coverage_matches_the_closed_form(n, level):
    """Over many calibration/test draws from one distribution, the circle covers a fresh error with
    probability ceil((n + 1) level) / (n + 1) exactly (rank argument); Rayleigh errors, 4000
    repetitions."""
    rng = np.random.default_rng(0)
    cal = rng.rayleigh(10.0, (4000, n))
    test = rng.rayleigh(10.0, 4000)
    r = np.array([conformal_quantile(c, level) for c in cal])
    want = math.ceil((n + 1) * level) / (n + 1)
    assert np.mean(test <= r) == pytest.approx(want, abs=0.02)


@given(st.lists(st.floats(0.0, 1e4), min_size=1, max_size=60), st.floats(0.05, 0.95))
@settings(max_examples=60, deadline=None)
def test_conformal_quantile_is_an_order_statistic(errors, level):
    r = conformal_quantile(errors, level)
    k = math.ceil((len(errors) + 1) * level)
    if k > len(errors):
        assert r == math.inf  # too few flights to promise the level
    else:
        assert r in errors and sum(e <= r for e in errors) >= k


def test_coverage_interval_closed_forms():
    """Clopper-Pearson: k = 0 gives [0, 1 - (a/2)^(1/n)]; k = n gives [(a/2)^(1/n), 1]; the
    symmetric case is symmetric about 1/2; 95 of 100 at 90 % is about [0.898, 0.980] (tables)."""
    iv = coverage_interval(0, 10)
    assert iv.lo == 0.0 and iv.hi == pytest.approx(1 - 0.05**0.1)
    iv = coverage_interval(10, 10)
    assert iv.hi == 1.0 and iv.lo == pytest.approx(0.05**0.1)
    iv = coverage_interval(12, 24)
    assert iv.value == 0.5 and iv.lo + iv.hi == pytest.approx(1.0)
    iv = coverage_interval(95, 100)
    assert (iv.lo, iv.hi) == pytest.approx((0.8979, 0.9799), abs=2e-3)
    with pytest.raises(ValueError):
        coverage_interval(3, 2)
