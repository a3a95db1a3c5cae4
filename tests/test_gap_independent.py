"""Gap diagnosis against an independent generator (``tests/_gap_synth.py``: formulas written for the
test).

The full confusion table over three seeds is ``python benchmarks/bench_gap.py selftest`` (results in
``benchmarks/README.md``); here a few cases at one seed keep the suite fast.
"""

from __future__ import annotations

import numpy as np
import pytest
from _gap_synth import channel_db, diagnose_case, exp_field, make_case

from mission.errors import InputError
from mission.gap.candidates import pattern_by_name, select
from mission.gap.freeform import (
    KINDS,
    basis_column,
    basis_orders,
    design,
    fit_freeform,
    link_of,
    map_variables,
)
from mission.gap.pipeline import Pipeline, _dipole_db
from mission.gap.spatial import SiteMap, fit_site_map, site_variables, usable_candidates
from mission.gap.structure import RATIO_THRESHOLD, residual_structure
from mission.physics import Attitude, make_model
from mission.physics.antenna import Dipole
from mission.physics.shadowing import fit_variogram
from mission.robust import offset_residual
from mission.samples import FlightSamples


def test_library_two_ray_agrees_with_the_independent_formulas() -> None:
    """mission.physics two-ray + dipoles + attitude (eps 2) equals the generator's own eq. 1 (away
    from nulls)."""
    raw, _ = make_case("none", 4, n_flights=2, duration=120.0)
    model = make_model("two-ray", pattern="dipole", dtype=np.float64).with_effect(Attitude())
    for f in raw:
        ours = channel_db(f["tx"], f["pos"], f["att"])
        lib = np.asarray(model.rss_dbm(f["tx"], f["pos"], f["att"]), dtype=float)
        d = np.abs(ours - lib)
        assert np.median(d) < 1e-3 and np.quantile(d, 0.99) < 0.05, (np.median(d), d.max())


@pytest.mark.parametrize("effect", ["none", "ripple", "timing", "shadowing"])
def test_withheld_effect_named_first(effect: str) -> None:
    """The diagnosis names the withheld effect (nothing for none), with its size in dB and where it
    acts."""
    r = diagnose_case(effect, 1)
    assert r["hit"], (r["named"], r["ranking"][:3], r["structure"]["verdict"])
    if effect == "none":
        assert r["significant"] == [] and r["structure"]["verdict"] == "white noise"
        return
    fp = r["footprint"]
    assert fp["size_db"] > 1.0
    # A cos(3 az): the map's size where it acts is about the amplitude A (2-2.5 dB)
    if effect == "ripple":
        assert 1.2 < fp["size_db"] < 4.0
        # its trough lies in a minimum of cos(3 (az - phi)): phi + 60 deg + k 120 deg
        off = (r["params"]["where"]["trough_body_azimuth_deg"] - r["truth"]["phase_deg"]) % 120.0
        assert abs(off - 60.0) < 20.0, off
    if effect == "timing":
        assert r["params"]["tau_s"] == pytest.approx(r["truth"]["tau_s"], abs=0.1)
    if effect == "shadowing":
        assert 2.0 < r["params"]["sigma_db"] < 6.5 and r["params"]["corr_len_m"] > 5.0


def test_variogram_separates_correlated_shadowing_from_white_noise() -> None:
    """fit_variogram on an exponential field (sigma 4 dB, L 40 m) + 1 dB noise, and on noise
    alone."""
    rng = np.random.default_rng(0)
    xy = rng.uniform(0, 400, (1500, 2))
    field = exp_field(rng, 4.0, 40.0)(xy)
    v = fit_variogram(xy, field + rng.normal(0, 1.0, len(xy)), rng, n_boot=20)
    assert 2.8 < v.sigma_db < 5.5 and 15.0 < v.corr_len < 90.0 and v.nugget_db < 2.0
    assert v.sigma_ci[0] <= v.sigma_db <= v.sigma_ci[1]
    w = fit_variogram(xy, rng.normal(0, 1.0, len(xy)), rng, n_boot=20)
    assert w.sigma_db < 0.5 and w.nugget_db == pytest.approx(1.0, abs=0.15)


def test_freeform_body_map_recovers_a_ripple_closed_form() -> None:
    """A pure 3-lobe ripple in body azimuth is drawn back by rx_gain_map (corr > 0.95, amplitude
    within 20 %)."""
    raw, _ = make_case("none", 6, n_flights=1, duration=300.0)
    f0 = raw[0]
    fl = FlightSamples(
        f0["pos"], np.zeros(len(f0["t"])), f0["att"], f0["t"], tx_enu_m=f0["tx"], name="x"
    )
    pipe = Pipeline(make_model("two-ray", pattern="dipole").with_effect(Attitude()))
    az, _ = map_variables("rx_gain_map", link_of(pipe, fl, np.arange(len(fl))))
    truth = 2.0 * np.cos(3 * (az - 1.0))
    r = truth - truth.mean() + np.random.default_rng(1).normal(0, 0.5, len(az))
    new, params = fit_freeform("rx_gain_map", pipe, [fl], [np.arange(len(fl))], [r])
    term = new.model.effect("rx_gain_map").rss_term_db(link_of(pipe, fl, np.arange(len(fl))))
    assert np.corrcoef(term, truth)[0, 1] > 0.95
    assert np.std(term) == pytest.approx(np.std(truth), rel=0.2)
    assert len(params["shape"]["gain_db"]) == len(params["shape"]["elevation_deg"])
    # the fast basis (Bonnet recurrence) equals numpy's Legendre series, column by column
    rng = np.random.default_rng(2)
    a, b = rng.uniform(-3.0, 3.0, 40), rng.uniform(-1.0, 1.0, 40)
    for kind in KINDS:
        ref = np.column_stack([basis_column(fn, m, p, a, b) for fn, m, p in basis_orders(kind)])
        assert np.allclose(design(kind, a, b), ref)


def test_one_home_rules() -> None:
    """Unknown pattern names are refused; the tilt term uses the library dipole (zero tilt: zero
    term)."""
    with pytest.raises(InputError):
        pattern_by_name("mesured")
    s = np.linspace(-1.0, 1.0, 41)
    assert np.allclose(_dipole_db(s), Dipole().gain_dbi(np.arcsin(s)))


@pytest.mark.parametrize(
    ("effect", "noise_db", "correlated"),
    [
        ("none", 1.0, False),
        ("none", 4.0, False),
        ("timing", 1.0, False),
        ("shadowing", 1.0, True),
        ("shadowing", 4.0, True),
    ],
)
def test_white_or_correlated_decision_on_the_independent_generator(
    effect: str, noise_db: float, correlated: bool
) -> None:
    """The verdict rests on the near/all-pair semivariance ratio (bootstrap bound), not on the
    fitted L: white noise (1 or 4 dB, or a withheld time offset) gives ratio ~ 1, a 4 dB exponential
    field ratio < 0.8."""
    base = Pipeline(make_model("two-ray", pattern="dipole").with_effect(Attitude()))
    for seed in (1, 2):
        raw, _ = make_case(effect, seed, noise_db=noise_db, dt=0.5)
        fl = [
            FlightSamples(f["pos"], f["rss"], f["att"], f["t"], tx_enu_m=f["tx"], name=f"s{k}")
            for k, f in enumerate(raw)
        ]
        s = residual_structure(
            fl,
            [offset_residual(f.rss_dbm, base.predict(f)) for f in fl],
            np.random.default_rng(seed),
        )
        t = s["test"]
        assert (s["verdict"] == "correlated shadowing") is correlated, (effect, noise_db, seed, t)
        assert t["ratio_ci"][0] <= t["ratio"] <= t["ratio_ci"][1] and t["n_near_pairs"] > 1000
        if correlated:
            assert t["ratio_ci"][1] < RATIO_THRESHOLD and 2.0 < t["correlated_std_db"] < 6.0
        else:
            assert t["ratio_ci"][1] > 0.95 and t["correlated_std_db"] < 1.0


def test_site_map_carries_a_transmitters_surroundings_to_another_flight() -> None:
    """A loss over compass azimuth around one transmitter, learned from one flight, predicts it on
    another flight at the same transmitter (corr > 0.9) and adds nothing around a transmitter it has
    not seen."""
    raw, _ = make_case("none", 3, n_flights=3, dt=0.5)
    # mid-field: the spiral (flight 1) sees it from every azimuth
    tx = np.array([180.0, 180.0, 1.5])
    fl = [
        FlightSamples(
            f["pos"],
            np.zeros(len(f["t"])),
            f["att"],
            f["t"],
            tx_enu_m=tx if k < 2 else f["tx"],
            name=f"s{k}",
        )
        for k, f in enumerate(raw)
    ]

    def site(f: FlightSamples) -> np.ndarray:
        az, _ = site_variables(f.tx_enu_m, f.enu_m[:, :2])
        return 6.0 * np.cos(2.0 * az - 1.0) + 3.0 * np.sin(3.0 * az)

    rng = np.random.default_rng(0)
    r1 = site(fl[1]) + rng.normal(0.0, 2.0, len(fl[1]))
    sm, params = fit_site_map([fl[1]], [np.arange(len(fl[1]))], [r1 - r1.mean()], loss="soft_l1")
    assert isinstance(sm, SiteMap) and params["sites"] == 1 and params["size_db"] > 8.0
    # the lawnmower: learned from the spiral
    pred, truth = (
        sm.field_db(fl[0], fl[0].enu_m[:, :2]),
        site(fl[0]),
    )
    assert np.corrcoef(pred, truth)[0, 1] > 0.9
    assert np.std(pred - truth) < 0.4 * np.std(truth)
    assert not np.any(sm.field_db(fl[2], fl[2].enu_m[:, :2]))

    names = [c.name for c in usable_candidates(select("all"), fl[:2])]
    assert "site_map" in names and "site_map" not in [
        c.name for c in usable_candidates(select("all"), fl[1:])
    ]
