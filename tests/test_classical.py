"""Classical localizers find a synthetic / simulated transmitter; smoke tests on real AFAR
flights."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _localize_helpers import LogDistance, synthetic_flight

from mission.importers.afar import import_afar_mat
from mission.localize.api import localize_log
from mission.localize.classical import (
    ModelGridSearch,
    StrongestSample,
    WeightedCentroid,
    as_flight,
    block_average,
)
from mission.localize.preprocess import cruise_mask

SHARED = Path(__file__).parents[1] / ".." / "shared" / "data" / "afar2023" / "mat"
TX = (150.0, 120.0, 1.5)


@pytest.mark.parametrize("est,tol", [(StrongestSample(), 15.0), (WeightedCentroid(), 15.0)])
def test_simple_estimators_find_synthetic_tx(est, tol):
    enu, rss, att = synthetic_flight(TX)
    e = est.predict((enu, rss, att))
    assert np.hypot(e.x_m - TX[0], e.y_m - TX[1]) < tol
    e2 = est.predict((enu, rss + 55.0, att))  # offset invariant
    assert (e2.x_m, e2.y_m) == pytest.approx((e.x_m, e.y_m))


def test_grid_search_offset_invariant_and_accurate():
    enu, rss, att = synthetic_flight(TX, noise=2.0)
    g = ModelGridSearch(model=LogDistance(p0=0.0), tx_height_m=1.5, step_m=10.0, max_points=800)
    e = g.predict((enu, rss - 80.0, att))
    assert np.hypot(e.x_m - TX[0], e.y_m - TX[1]) < 3.0
    assert e.extras["offset_db"] == pytest.approx(30.0 - 80.0, abs=1.0)
    assert e.method == "grid" and e.model == "log-distance"


def test_grid_search_with_physics_on_simulated_flight():
    physics = pytest.importorskip("mission.physics")
    model = physics.make_model("e2r", pattern="dipole")
    rng = np.random.default_rng(5)
    enu, _, _ = synthetic_flight(TX, n=8000)
    att = np.column_stack([rng.uniform(-0.08, 0.08, (len(enu), 2)), np.zeros(len(enu))])
    rss = (
        np.asarray(model.rss_dbm(np.asarray(TX), enu, att), dtype=float)
        + rng.normal(0, 1, len(enu))
        - 20.0
    )
    e = ModelGridSearch("e2r", {"pattern": "dipole"}, tx_height_m=1.5, max_points=800).predict(
        (enu, rss, att)
    )
    assert np.hypot(e.x_m - TX[0], e.y_m - TX[1]) < 5.0


def test_block_average_and_cruise():
    enu, rss, att = synthetic_flight(n=1000)
    f = block_average(as_flight((enu, rss, att)), 100)
    assert (
        f.rss_dbm.shape == (100,) and f.enu_m.shape == (100, 3) and f.attitude_rad.shape == (100, 3)
    )
    h = np.concatenate([np.linspace(0, 30, 100), np.full(800, 30.0), np.linspace(30, 0, 100)])
    sel = cruise_mask(h)
    assert 800 <= sel.n_kept < 900 and sel.cruise_alt_m == pytest.approx(30.0)
    assert cruise_mask(np.zeros(50)).n_kept == 50


@pytest.mark.real
@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared real data absent")
def test_real_flight_smoke(tmp_path):
    res = import_afar_mat(
        SHARED / "results_useful_ori_exp_328_loc_2.mat", tmp_path, truth=(35.72911779, -78.69918128)
    )
    for method in ("strongest", "centroid"):
        e = localize_log(res.out_path, method=method)
        assert e.error_m is not None and e.error_m < 60.0
