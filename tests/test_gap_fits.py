"""Fits that do not miss: a withheld narrow effect is found at full and at small strength, and the
base ranking and the ladder agree on which named effect helps most; near-nadir loss is found or its power
statement says how many samples it needs.  Flights from the independent generator (``tests/_gap_synth``);
the candidates are the withheld effect's competitors (the free-form body map, the other body-fixed effects),
to keep the test cheap."""

from __future__ import annotations

import numpy as np
import pytest
from _gap_synth import make_case

from mission.gap.candidates import select
from mission.gap.fit import FitConfig, ladder
from mission.gap.nadir import power_statement
from mission.gap.pipeline import Pipeline
from mission.gap.structure import identify
from mission.physics import Attitude, make_model
from mission.samples import FlightSamples

BODY = "leg_shadowing,near_nadir,rx_gain_map,ground_reflection"


def _flights(effect: str, seed: int, strength: float) -> tuple[list[FlightSamples], dict]:
    raw, truth = make_case(effect, seed, dt=0.5, strength=strength)
    return [FlightSamples(name=f"s{k}", t_s=f["t"], enu_m=f["pos"], attitude_rad=f["att"], rss_dbm=f["rss"],
                          tx_enu_m=f["tx"]) for k, f in enumerate(raw)], truth


BASE = Pipeline(make_model("two-ray", pattern="dipole").with_effect(Attitude()))
CFG = FitConfig(seed=1, fit_max_samples=800, workers=1, n_boot=200)


@pytest.mark.slow
@pytest.mark.parametrize("strength", [1.0, 0.4])
def test_legs_found_at_full_and_small_strength(strength: float) -> None:
    flights, truth = _flights("legs", 2, strength)
    out = identify(flights, BASE, select(BODY), CFG)
    assert out["named"] == "leg_shadowing", (truth, out["ranking"][:3])
    assert abs(out["params"]["beta"] - truth["beta"]) < 0.15


@pytest.mark.slow
def test_base_ranking_and_ladder_agree_on_the_best_named_effect() -> None:
    flights, _ = _flights("legs", 3, 0.6)
    rungs = ladder(BASE, flights, select(BODY), CFG, max_rungs=2)
    named = [r for r in rungs[0].ranking if r.tier == "named"]
    best = max(named, key=lambda r: r.loss_reduction)
    first_named = next(r.added for r in rungs[1:] if r.added in {x.name for x in named})
    assert best.name == first_named == "leg_shadowing"


@pytest.mark.slow
def test_near_nadir_found_or_power_statement_says_why() -> None:
    flights, truth = _flights("nadir", 1, 1.0)
    out = identify(flights, BASE, select(BODY), CFG)
    dep = [np.rad2deg(np.arcsin(np.clip(_dep_sin(f), -1, 1))) for f in flights]
    ps = power_statement(dep, [f.rss_dbm - np.median(f.rss_dbm) for f in flights], [20] * len(flights))
    if out["named"] != "near_nadir":  # then the data must be too thin to show an 8 dB loss
        assert ps["detectable_db"] > truth["depth_db"], (out["ranking"][:3], ps)
    else:
        assert abs(out["params"]["centre_deg"] - 75.0) < 12.0


def _dep_sin(f: FlightSamples) -> np.ndarray:
    from mission.gap.align import align

    return np.sin(align(f).dep_b)


def test_power_statement_closed_form() -> None:
    """n_eff = n / L samples in the band; detectable = (1.645 + 0.842) s / sqrt(n_eff); one pass: nothing."""
    rng = np.random.default_rng(0)
    r = [rng.normal(0.0, 5.0, 2000)]
    one = power_statement([np.r_[np.full(400, 70.0), np.full(1600, 20.0)]], r, [4])
    assert one["passes"] == 1 and one["detectable_db"] == np.inf and "cannot see" in one["statement"]
    dep = [np.r_[np.full(200, 70.0), np.full(800, 20.0), np.full(200, 70.0), np.full(800, 20.0)]]
    ps = power_statement(dep, r, [4])
    assert ps["samples"] == 400 and ps["passes"] == 2 and ps["effective_samples"] == pytest.approx(100.0)
    assert ps["detectable_db"] == pytest.approx(2.487 * ps["residual_sd_db"] / 10.0, rel=1e-3)
    assert ps["samples_needed"] == pytest.approx((2.487 * ps["residual_sd_db"] / 3.0) ** 2 * 4, rel=0.02)
    assert "samples" in ps["statement"]
