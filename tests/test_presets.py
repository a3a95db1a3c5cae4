"""Physics presets (mission.physics.presets), the PathGainSlope effect, yaw-only attitude, the grid
default.

The real-data test reads ../shared/data/afar2023 and skips when it is absent (a fresh clone has no
../shared).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _localize_helpers import write_synthetic_log

from mission.errors import InputError
from mission.flightlog import FlightLog, make_meta, write_flight_log
from mission.gap.align import flight_from_log
from mission.gap.fit import offset_residual
from mission.geo import afar_field
from mission.importers.afar import convert_afar_mat
from mission.localize import api
from mission.localize.api import _default_physics, default_model_path, localize_log, make_localizer
from mission.localize.card import ModelCard, TrainingDomain
from mission.localize.preprocess import cruise_mask
from mission.physics import Attitude, PathGainSlope, make_model
from mission.physics.presets import build_model, load_calibration, load_preset, preset_model
from mission.simulate import SimConfig, simulate_flight
from mission.spec import load_mission

SHARED = Path(__file__).parents[1] / ".." / "shared"
MAT = SHARED / "data" / "afar2023" / "mat"
TRUTH = {1: (35.72806709, -78.69730398), 2: (35.72911779, -78.69918128)}


def _geometry(n: int = 200, seed: int = 0):
    rng = np.random.default_rng(seed)
    rx = np.column_stack(
        [rng.uniform(-300, 300, n), rng.uniform(-300, 300, n), rng.uniform(10, 60, n)]
    )
    att = np.column_stack(
        [rng.normal(0, 0.1, n), rng.normal(0, 0.1, n), rng.uniform(0, 2 * np.pi, n)]
    )
    return np.array([12.0, -30.0, 1.5]), rx, att


def test_preset_loads_and_builds_a_model():
    spec = load_preset("afar")
    assert spec["base"] in ("free-space", "two-ray", "e2r")
    rec = load_calibration("afar")
    for key in ("fitted_on", "command", "date", "folds", "model"):
        assert key in rec
    assert "288-loc3" not in rec["fitted_on"]
    m = preset_model("afar")
    assert m.name == "afar-calibrated" and m.has("free_space")
    tx, rx, att = _geometry()
    rss = m.rss_dbm(tx, rx, att)
    assert rss.shape == (len(rx),) and np.all(np.isfinite(rss))
    # the spec is the whole story: rebuilding it gives the same predictions
    np.testing.assert_allclose(build_model(spec).rss_dbm(tx, rx, att), rss)
    # fold models (used by the held-out test) build too
    for fold in rec["folds"].values():
        assert np.all(np.isfinite(build_model(fold["model"]).rss_dbm(tx, rx, att)))


def test_preset_folds_by_name():
    """``afar:FOLD`` is the fold's own spec (fitted without the other team's flights), named
    apart."""
    rec = load_calibration("afar")
    for name, fold in rec["folds"].items():
        assert load_preset(f"afar:{name}") == fold["model"]
        # held out means held out
        assert fold["fitted_on"] and not set(fold["fitted_on"]) & set(fold["tested_on"])
        assert preset_model(f"afar:{name}").name == f"afar-{name}-calibrated"
    assert load_preset("afar:fit328") != load_preset("afar:fit288")
    with pytest.raises(InputError, match="no fold"):
        load_preset("afar:fit999")


def test_preset_errors():
    with pytest.raises(InputError):
        load_preset("nowhere")
    with pytest.raises(ValueError, match="unknown model spec keys"):
        build_model({"base": "free-space", "colour": "red"})


def test_build_model_effects():
    m = build_model(
        {
            "base": "e2r",
            "ground": None,
            "leg_shadowing_beta": None,
            "attitude": "yaw",
            "path_gain_slope": 0.5,
            "rx_pattern": "measured",
            "rx_flipped": True,
            "rx_heading_deg": 30,
        }
    )
    assert set(m.names) == {"free_space", "tx_antenna", "rx_antenna", "attitude", "path_gain_slope"}
    assert m.effect("attitude").roll_pitch is False and m.effect("rx_antenna").flipped
    assert m.effect("rx_antenna").heading_rad == pytest.approx(np.radians(30))
    m2 = build_model(
        {
            "base": "free-space",
            "ground": {"eps_r": 15, "sigma_s_m": 0.005},
            "leg_shadowing_beta": 1.0,
        }
    )
    assert m2.effect("ground_reflection").eps_r == 15 and m2.effect("leg_shadowing").beta == 1.0


@pytest.mark.parametrize("base", ["free-space", "e2r"])
@pytest.mark.parametrize("n_extra", [0.7, -0.3, 2.0])
def test_path_gain_slope_closed_form(base, n_extra):
    """With the slope the RSS is exactly -10 n log10(d_los / d_ref) below the model without it."""
    tx, rx, att = _geometry()
    m0 = make_model(base, pattern="dipole", dtype=np.float64)
    d_ref = 7.0
    m1 = m0.with_effect(PathGainSlope(n_extra=n_extra, d_ref_m=d_ref))
    d_los = np.linalg.norm(rx - tx, axis=1)
    want = -10.0 * n_extra * np.log10(d_los / d_ref)
    np.testing.assert_allclose(m1.rss_dbm(tx, rx, att) - m0.rss_dbm(tx, rx, att), want, atol=1e-9)
    np.testing.assert_allclose(
        m1.explain(tx, rx, att)["rss_dbm"] - m0.explain(tx, rx, att)["rss_dbm"], want, atol=1e-9
    )
    # float32 fast path agrees with the float64 reference
    m32 = make_model(base, pattern="dipole").with_effect(
        PathGainSlope(n_extra=n_extra, d_ref_m=d_ref)
    )
    np.testing.assert_allclose(
        m32.rss_dbm(tx, rx, att), m1.explain(tx, rx, att)["rss_dbm"], atol=2e-3
    )


def test_yaw_only_attitude_equals_level_body_with_the_logged_yaw():
    tx, rx, att = _geometry()
    m = make_model("e2r", pattern="measured", rx_flipped=True, rx_heading_rad=1.0, dtype=np.float64)
    my = m.with_effect(Attitude(roll_pitch=False))
    yaw_only = att * np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(my.rss_dbm(tx, rx, att), m.rss_dbm(tx, rx, yaw_only), atol=1e-9)
    np.testing.assert_allclose(
        my.explain(tx, rx, att)["rss_dbm"], m.explain(tx, rx, yaw_only)["rss_dbm"], atol=1e-9
    )
    assert not np.allclose(m.rss_dbm(tx, rx, att), m.rss_dbm(tx, rx, yaw_only))


def test_grid_localizer_with_preset():
    loc = make_localizer("grid", physics_preset="afar")
    assert loc.model_name == "afar-calibrated"
    with pytest.raises(InputError):
        make_localizer("grid", physics_preset="afar", physics_params={"colour": 1})


def test_localize_log_default_physics_is_the_preset(tmp_path):
    p = write_synthetic_log(tmp_path / "f.csv", n=1500)
    est = localize_log(p, method="grid")
    assert est.model == "afar-calibrated"
    assert localize_log(p, method="grid", physics_model="free-space").model.startswith("free-space")
    with pytest.raises(InputError):
        localize_log(p, method="grid", physics_model="e2r", physics_preset="afar")


def _cruise_flight(team: int, loc: int):
    res = convert_afar_mat(MAT / f"results_useful_ori_exp_{team}_loc_{loc}.mat", TRUTH[loc])
    f = flight_from_log(res.log, name=f"{team}-loc{loc}")
    f = f.select(f.enu_m[:, 2] > 10.0)
    return f.select(cruise_mask(f.enu_m[:, 2]).mask)


@pytest.mark.real
@pytest.mark.skipif(not MAT.is_dir(), reason="../shared (real AFAR data) not present")
def test_calibrated_model_beats_free_space_on_held_out_team_288():
    """The fold fitted on team 328 only, scored on team 288 locations 1-2 (never seen by that
    fit)."""
    rec = json.loads(
        (Path(__file__).parents[1] / "mission" / "data" / "afar_calibration.json").read_text()
    )
    fold = rec["folds"]["fit328"]
    assert all(n.startswith("328") for n in fold["fitted_on"])
    cal = build_model(fold["model"])
    fs = make_model("free-space", pattern="isotropic")
    r_cal, r_fs = [], []
    for loc in (1, 2):
        f = _cruise_flight(288, loc)
        for m, out in ((cal, r_cal), (fs, r_fs)):
            p = np.asarray(m.rss_dbm(f.tx_enu_m, f.enu_m, f.attitude_rad), dtype=float)
            out.append(np.abs(offset_residual(f.rss_dbm, p, loss="soft_l1")))
    a_cal, a_fs = np.concatenate(r_cal), np.concatenate(r_fs)
    assert np.quantile(a_cal, 0.9) < np.quantile(a_fs, 0.9) - 1.0
    assert np.median(a_cal) < np.median(a_fs)


def test_default_grid_physics_follows_the_log_source():
    """A simulated log is searched with its own simulation model; a real receiver's with the afar
    preset."""
    cols = {"t_s": np.zeros(1)}
    sim = FlightLog(
        cols, {"rss_source": {"kind": "sim", "model": "two-ray", "model_params": {"eps_r": 5}}}
    )
    assert _default_physics(sim) == ("two-ray", {"eps_r": 5}, None)
    real = FlightLog(cols, {"rss_source": {"kind": "real", "calibrated": False}})
    assert _default_physics(real) == (None, None, "afar")
    assert _default_physics(FlightLog(cols, {})) == (None, None, "afar")


def test_default_method_on_a_real_receiver_log_is_the_calibrated_grid(tmp_path):
    """Without --method, a real receiver's log gets the fused self-calibrating + network estimate
    (the rule in models/README.md), a simulated one the network (or its own model), and it says
    why."""
    spec = load_mission()
    origin = afar_field().origin
    tx = np.array([120.0, 200.0, 1.5])
    f = simulate_flight(
        spec.waypoints_enu()[:6],
        tx,
        make_model("free-space"),
        SimConfig(),
        np.random.default_rng(0),
    )
    cols = f.log_columns(origin)
    real = write_flight_log(tmp_path / "real.csv", cols, make_meta(origin, {"kind": "aerpaw-fifo"}))
    est = localize_log(real)
    assert est.method == "fusion" and "real receiver log" in est.extras["method_choice"]
    comp = est.extras["components"]  # the plain mean of its two components, each a real estimate
    assert set(comp) == {"selfcal", "rfsl_spiral_e2r.onnx"}
    mean = np.mean(list(comp.values()), axis=0)
    assert (est.x_m, est.y_m) == pytest.approx(tuple(mean))
    assert [r.level for r in est.regions] == [0.5, 0.9]
    # the fused point's place in its own regions, and the note on it
    q = est.extras["fused_point_hpd_level"]
    assert q == pytest.approx(est.posterior.hpd_level(est.x_m, est.y_m)) and 0.0 <= q <= 1.0
    assert ("outside the 90 % region" in est.extras.get("note", "")) == (q >= est.regions[1].mass)
    sim = write_flight_log(
        tmp_path / "sim.csv", cols, make_meta(origin, {"kind": "sim", "model": "free-space"})
    )
    est = localize_log(sim)
    assert default_model_path() is not None, "the repository ships models/rfsl_default.onnx"
    assert est.method == "onnx" and est.model == default_model_path().name


def test_fusion_says_when_its_point_leaves_its_regions(tmp_path, monkeypatch) -> None:
    """When the network lands far from a sharp self-calibrating posterior, the fused point falls
    outside the 90 % region (which is the search's alone) and the estimate says so instead of
    drawing a region beside it."""
    spec = load_mission()
    origin = afar_field().origin
    tx = np.array([120.0, 200.0, 1.5])
    f = simulate_flight(
        spec.waypoints_enu(), tx, make_model("free-space"), SimConfig(), np.random.default_rng(1)
    )
    real = write_flight_log(
        tmp_path / "real.csv", f.log_columns(origin), make_meta(origin, {"kind": "aerpaw-fifo"})
    )
    make = api.make_localizer

    # a network answer 300 m east of the truth (what a net off its training domain can do)
    class FarNetwork:
        path = tmp_path / "far.onnx"
        model_name = "far.onnx"
        # no card beside it: no training domain (no altitude or attitude claim), no calibrated
        # circles
        card = ModelCard(
            path, "clustering", None, None, origin, None, TrainingDomain(), None, "", {}
        )
        cfg = type("Cfg", (), {"to_dict": lambda self: {}})()

        def predict(self, part):
            lat, lon, _ = origin.to_geodetic(np.array([tx[0] + 300.0, tx[1], 0.0]))
            return api.Estimate(0.0, 0.0, "onnx", "far", float(lat), float(lon))

    monkeypatch.setattr(
        api, "make_localizer", lambda m, *a, **k: FarNetwork() if m == "onnx" else make(m, *a, **k)
    )
    monkeypatch.setattr(api, "fusion_model_path", lambda: FarNetwork.path)
    est = api.localize_log(real)
    assert est.extras["component_distance_m"] > 250.0
    assert est.extras["fused_point_hpd_level"] >= est.regions[1].mass
    assert "outside the 90 % region" in est.extras["note"]
