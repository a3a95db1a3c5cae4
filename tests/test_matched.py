"""Track-matched localizer (``mission.localize.matched``): recovery, regions, offset invariance,
seeds, bad input.

The flight's RSS comes from ``family.simulate_rss`` on the raw samples (shadowing on
``shadowing_field``'s grid), not from the cell-level simulator the localizer trains on, so the test
also checks that the two agree enough.
"""

from __future__ import annotations

import argparse

import numpy as np
import pytest
from _localize_helpers import lawnmower_path
from hypothesis import given, settings
from hypothesis import strategies as st

from mission.cli.localize import add_arguments
from mission.errors import InputError
from mission.localize.api import make_localizer
from mission.localize.matched import MatchedLocalizer, conformal_mass, hpd_level_of, kde_of
from mission.localize.matched_net import Pca
from mission.localize.matched_sim import FieldBasis, centred, track_cells
from mission.physics.family import PhysicsFamily, simulate_rss
from mission.physics.shadowing import correlation, pdist
from mission.samples import FlightSamples

FAMILY = PhysicsFamily.from_dict(
    {
        "schema": 1,
        "name": "test-mild",
        "spec": {
            "base": "free-space",
            "tx_pattern": "isotropic",
            "path_gain_slope": {"dist": "uniform", "lo": 0.0, "hi": 0.3},
        },
        "residual": {
            "shadowing_db": {"dist": "uniform", "lo": 1.0, "hi": 3.0},
            "shadowing_corr_m": 30.0,
            "noise_db": 2.0,
        },
        "offset_db": {"dist": "uniform", "lo": -30.0, "hi": 30.0},
    }
)
BOX = (0.0, 0.0, 240.0, 240.0)
TX = np.array([150.0, 90.0, 1.5])


def _flight(seed: int = 1) -> FlightSamples:
    rng = np.random.default_rng(seed)
    enu = lawnmower_path(n=3000, x0=20, x1=220, y0=20, y1=220, lanes=6)
    att = np.column_stack([np.zeros((len(enu), 2)), rng.uniform(0, 2 * np.pi, len(enu))])
    rss = simulate_rss(FAMILY.draw(rng), TX, enu, att, rng)
    return FlightSamples(enu, rss, att)


def _loc(**kw) -> MatchedLocalizer:
    args = dict(
        area=BOX,
        family=FAMILY,
        n_draws=4000,
        cell_m=10.0,
        epochs=30,
        batch=64,
        whiten=False,
        n_pca=32,
        hidden=(64, 64),
        n_check=60,
        step_m=5.0,
        progress=False,
        seed=3,
    )
    args.update(kw)
    return MatchedLocalizer(**args)


@pytest.fixture(scope="module")
def flight() -> FlightSamples:
    return _flight()


@pytest.fixture(scope="module")
def estimate(flight):
    return _loc().predict(flight)


def test_recovers_the_transmitter(estimate):
    assert np.hypot(estimate.x_m - TX[0], estimate.y_m - TX[1]) < 25.0
    assert estimate.method == "matched"
    assert estimate.extras["n_draws"] == 4000 and estimate.extras["sim_check"]["n"] == 60


def test_regions_are_nested_and_hold_the_estimate(estimate):
    post = estimate.posterior
    r50, r90 = estimate.region(0.5), estimate.region(0.9)
    assert r50.mass < r90.mass and r50.area_m2 < r90.area_m2
    in50 = post.prob >= post.mass_threshold(r50.mass)
    in90 = post.prob >= post.mass_threshold(r90.mass)
    assert in50.any() and not (in50 & ~in90).any()
    assert post.covers(estimate.x_m, estimate.y_m, r90.mass)
    assert abs(post.prob.sum() - 1.0) < 1e-9


def test_offset_invariant(flight, estimate):
    shifted = FlightSamples(flight.enu_m, flight.rss_dbm + 23.7, flight.attitude_rad)
    e = _loc().predict(shifted)
    assert e.x_m == pytest.approx(estimate.x_m, abs=1e-6) and e.y_m == pytest.approx(
        estimate.y_m, abs=1e-6
    )
    np.testing.assert_allclose(e.posterior.prob, estimate.posterior.prob, atol=1e-9)


def test_reproducible_from_its_seed(flight, estimate):
    again = _loc().predict(flight)
    assert (again.x_m, again.y_m) == (estimate.x_m, estimate.y_m)
    other = _loc(seed=4).predict(flight)
    assert (other.x_m, other.y_m) != (estimate.x_m, estimate.y_m)


def test_too_few_cells_is_input_error(flight):
    short = FlightSamples(flight.enu_m[:40], flight.rss_dbm[:40], flight.attitude_rad[:40])
    with pytest.raises(InputError, match="cells"):
        _loc().predict(short)


@settings(max_examples=25, deadline=None)
@given(
    i=st.integers(0, 2999),
    bad=st.sampled_from([np.nan, np.inf, -np.inf]),
    where=st.sampled_from(["rss", "z"]),
)
def test_non_finite_input_is_input_error(flight, i, bad, where):
    rss, enu = flight.rss_dbm.copy(), flight.enu_m.copy()
    if where == "rss":
        rss[i] = bad
    else:
        enu[i, 2] = bad
    with pytest.raises(InputError, match=f"sample {i}"):
        _loc().predict(FlightSamples(enu, rss, flight.attitude_rad))


def test_field_basis_reproduces_the_gaussian_correlation():
    rng = np.random.default_rng(0)
    xy = rng.uniform(0, 200, size=(120, 2))
    b = FieldBasis(xy)
    f = b.factor(40.0)
    corr_used = 1.06 ** round(np.log(40.0) / np.log(1.06))
    np.testing.assert_allclose(
        f @ f.T, correlation(pdist(xy, xy), corr_used, "gaussian"), atol=1e-5
    )
    assert b.factor(40.3) is f  # rounds to the same length: one factor


def test_cells_centring_and_conformal_mass(flight):
    tr = track_cells(flight, 10.0)
    assert tr.attitude_rad.shape == (len(tr), 3) and tr.count.sum() == len(flight.rss_dbm)
    assert np.allclose(centred(tr.rss_dbm + 5.0), centred(tr.rss_dbm))
    lev = np.linspace(0.0, 1.0, 101)[:-1]  # uniform HPD levels: a calibrated posterior
    # the ceil(101 x 0.9) = 91st smallest, not the 92nd
    assert conformal_mass(lev, 0.9) == pytest.approx(0.9)


def test_wired_into_localize():
    p = argparse.ArgumentParser()
    add_arguments(p)
    assert p.parse_args(["x.csv", "--method", "matched"]).method == "matched"
    loc = make_localizer("matched", area=BOX, tx_height_m=2.0)
    assert isinstance(loc, MatchedLocalizer) and loc.area == BOX and loc.tx_height_m == 2.0
    # the shipped family, read through load_family
    assert loc.n_draws >= 20000 and loc.family is None


def test_self_check_localizes_held_out_draws_with_every_fold():
    """The held-out draws are localized as the flight is: the union of every fold's ABC draws.  Here
    fold 0's net summarises a held-out draw at its truth and fold 1's 30 m east of it, so the
    union's mean errs ~15 m (a check through one net alone would err ~0 m and calibrate too narrow a
    region for the flight's union)."""
    rng = np.random.default_rng(0)
    tx = rng.uniform(0.0, 300.0, (2000, 2))
    cal = np.arange(1800, 2000)
    fold = np.where(np.arange(2000) < 1800, np.arange(2000) % 2, -1)
    s_ref = np.where(fold[:, None] >= 0, tx, np.nan)
    s_cal = np.stack([tx[cal], tx[cal] + [30.0, 0.0]])
    check = _loc(step_m=2.0)._self_check(tx, s_ref, s_cal, cal, fold, k=20)
    assert check["n"] == 200 and 12.0 < check["median_error_m"] < 18.0
    assert 0.0 <= check["hpd_levels"].min() and check["hpd_levels"].max() <= 1.0


def test_kernel_density_follows_the_draws_and_keeps_its_floor():
    """``kde_of`` (scipy's weighted ``gaussian_kde``): draws spread 40 m along x and 4 m along y
    give a kernel elongated along x, its narrow axis lifted to the floor; the HPD level of a point
    grows with its distance from the draws' centre, 0 at the densest draw and 1 far outside."""
    rng = np.random.default_rng(3)
    pts = rng.standard_normal((400, 2)) * [40.0, 4.0]
    w = rng.uniform(0.5, 1.0, 400)
    k = kde_of(pts, w, floor_m=5.0)
    sd = np.sqrt(np.linalg.eigvalsh(k.covariance))
    assert sd[1] > 3 * sd[0] and sd[0] == pytest.approx(5.0, rel=1e-6)
    assert np.sqrt(np.linalg.eigvalsh(kde_of(pts, w, floor_m=0.1).covariance))[0] < 5.0
    levels = [hpd_level_of(np.array([r, 0.0]), k, pts, w) for r in (0.0, 30.0, 60.0, 300.0)]
    assert levels[0] < 0.05 and levels[-1] == 1.0 and np.all(np.diff(levels) > 0)
    # across the narrow axis the density falls far faster than along the long one
    assert hpd_level_of(np.array([0.0, 20.0]), k, pts, w) > levels[2]


def test_principal_axes_match_the_closed_form():
    """``Pca`` (scikit-learn's ``PCA``) projects onto the data's leading eigenvectors: whitened,
    each projected axis has unit variance; unwhitened, the axes keep their variance ratios, the
    first at unit spread."""
    rng = np.random.default_rng(4)
    x = rng.standard_normal((500, 6)) @ np.diag([9.0, 5.0, 2.0, 1.0, 0.5, 0.1])
    z = Pca(x, 3, whiten=True).transform(x)
    assert z.dtype == np.float32 and z.shape == (500, 3)
    np.testing.assert_allclose(z.var(axis=0, ddof=1), 1.0, rtol=1e-4)
    vals = np.linalg.eigvalsh(np.cov(x.T))[::-1][:3]
    u = Pca(x, 3, whiten=False).transform(x)
    np.testing.assert_allclose(u.var(axis=0, ddof=1), vals / vals[0], rtol=1e-4)
