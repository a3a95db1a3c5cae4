"""Posterior-predictive checks on synthetic cases with known answers, and the default-changing rule
as written (models/README.md, "Decisions with error bars")."""

from __future__ import annotations

import numpy as np
import pytest

from mission.physics.shadowing import shadowing_field
from mission.workshop.decision import pooled_decision
from mission.workshop.predictive import (
    design_check,
    family_checks,
    predictive_check,
    sample_statistics,
    verdict,
)


def test_predictive_check_band_inside_and_p():
    """Benchmark values 0..1000: band = their 10-90 % quantiles (100, 900); a real mean inside
    passes with the closed-form p, one beyond every benchmark value fails (p = 1), one below all
    fails (p = 0)."""
    sim = np.arange(1001.0)
    mid = predictive_check([400, 450, 500, 550, 600, 120], sim)
    assert mid["band"] == pytest.approx([100.0, 900.0])
    assert mid["inside"] == 6 and mid["n_real"] == 6
    # the mean of 6 uniform(0, 1000) draws is ~normal(500, 288.8 / sqrt 6 = 117.9): p = Phi((436.7 -
    # 500) / 117.9)
    assert mid["p"] == pytest.approx(0.296, abs=0.025) and mid["passes"]
    far = predictive_check([1500.0] * 6, sim)
    assert far["inside"] == 0 and far["p"] == 1.0 and not far["passes"]
    low = predictive_check([50.0] * 6, sim)
    assert low["p"] == 0.0 and not low["passes"]


def _track(n: int = 1500) -> np.ndarray:
    """A lawnmower over 200 x 200 m at 30 m."""
    t = np.linspace(0.0, 1.0, n)
    x = 200.0 * np.abs(((t * 8) % 2) - 1.0)
    y = 200.0 * t
    return np.column_stack([x, y, np.full(n, 30.0)])


def test_design_check_judges_each_flight_against_its_own_copies():
    """Flights of very different difficulty (design): each real value at its own copies' median
    passes with p near 0.5 and every flight inside its own band, although most lie outside the
    pooled band; a real mean above every copy's fails with p 1; NaN copies are dropped; a flight
    without copies is refused."""
    rng = np.random.default_rng(0)
    scale = np.array([5.0, 10.0, 20.0, 40.0, 80.0, 160.0])
    sims = [s * (1 + 0.1 * rng.standard_normal(200)) for s in scale]
    c = design_check(scale, sims)
    assert c["inside"] == 6 and c["passes"] and 0.3 < c["p"] < 0.7
    lo, hi = c["band"]
    assert np.sum((scale >= lo) & (scale <= hi)) < 6  # the pooled band would call some outside
    pooled = predictive_check(scale, np.concatenate(sims))
    assert pooled["inside"] < 6
    far = design_check(scale * 2, sims)
    assert far["p"] == 1.0 and not far["passes"] and far["inside"] == 0
    with_nan = [np.append(x, np.nan) for x in sims]
    assert design_check(scale, with_nan)["p"] == pytest.approx(c["p"])
    with pytest.raises(ValueError):
        design_check(scale, sims[:5])
    with pytest.raises(ValueError):
        design_check(scale, [*sims[:5], np.array([])])


def test_sample_statistics_recover_known_spread_and_residual():
    """RSS = free space + offset + white noise 3 dB: the residual's sill is 3 dB with the nugget
    carrying it; the RSS 5-95 % range is the closed form's; a correlated 10 dB field adds a sill
    near 10 dB and a range of tens of metres."""
    rng = np.random.default_rng(4)
    pos = _track()
    tx = np.array([80.0, 120.0, 1.5])
    d = np.linalg.norm(pos - tx, axis=1)
    clean = -40.0 - 20.0 * np.log10(d)
    white = clean + rng.normal(0.0, 3.0, len(d))
    s = sample_statistics(pos, white, tx, np.random.default_rng(0))
    assert s["resid_sill_db"] == pytest.approx(3.0, abs=0.4)
    assert s["resid_nugget_db"] == pytest.approx(3.0, abs=0.6)
    lo, hi = np.percentile(white, [5, 95])
    assert s["rss_spread_db"] == pytest.approx(hi - lo)
    field = clean + shadowing_field(pos[:, :2], 10.0, 40.0, np.random.default_rng(1))
    f = sample_statistics(pos, field, tx, np.random.default_rng(0))
    assert (
        6.0 < f["resid_sill_db"] < 14.0
        and f["resid_nugget_db"] < 2.0
        and 10.0 < f["resid_range_m"] < 120.0
    )


def test_family_checks_verdict():
    sim = [
        {
            "rss_spread_db": v,
            "resid_sill_db": v / 4,
            "resid_range_m": 50.0 + v,
            "resid_nugget_db": 2.0,
        }
        for v in np.linspace(20, 60, 41)
    ]
    real = [
        {
            "rss_spread_db": 40.0,
            "resid_sill_db": 10.0,
            "resid_range_m": 90.0,
            "resid_nugget_db": 2.0,
        }
    ] * 6
    ok = family_checks(real, sim, {"a": [40.0] * 6}, {"a": list(np.linspace(20, 60, 41))})
    assert set(ok) == {
        "rss_spread_db",
        "resid_sill_db",
        "resid_range_m",
        "resid_nugget_db",
        "error m: a",
    }
    assert verdict(ok).startswith("the family passes all 5")
    bad = family_checks([{**r, "rss_spread_db": 90.0} for r in real], sim)
    assert "fails 1 of 4" in verdict(bad) and "rss_spread_db" in verdict(bad)


TEAMS = ["288"] * 3 + ["328"] * 3


def _errors(seed: int, n: int, scale: float) -> np.ndarray:
    return np.random.default_rng(seed).gamma(2.0, scale / 2.0, n)


def test_rule_adopts_a_clear_win():
    """A candidate that errs 40 % less on every real flight and every benchmark flight wins and is
    chosen."""
    inc_r, inc_b = _errors(1, 6, 40.0), _errors(2, 200, 70.0)
    out = pooled_decision(
        {"inc": inc_r, "new": 0.6 * inc_r}, TEAMS, {"inc": inc_b, "new": 0.6 * inc_b}, "inc"
    )
    assert out["changed"] and out["choice"] == "new"
    assert out["methods"]["new"]["pooled"].value == pytest.approx(-0.4)
    assert out["methods"]["new"]["pooled"].hi < 0


def test_rule_keeps_the_incumbent_on_a_win_inside_the_interval():
    """A candidate better on average but not beyond its interval: 30 % better on one team, 20 %
    worse on the other; on the benchmark 2 % better on average with per-flight ratios 0.4-1.56: the
    pooled interval reaches zero, the incumbent stays."""
    rng = np.random.default_rng(3)
    inc_r, inc_b = _errors(1, 6, 40.0), _errors(2, 200, 70.0)
    new_r = inc_r * np.array([0.7, 0.7, 0.7, 1.2, 1.2, 1.2])
    new_b = inc_b * rng.uniform(0.4, 1.56, 200)
    out = pooled_decision({"inc": inc_r, "new": new_r}, TEAMS, {"inc": inc_b, "new": new_b}, "inc")
    d = out["methods"]["new"]
    assert d["pooled"].value < 0 and d["pooled"].hi >= 0
    assert not out["changed"] and out["choice"] == "inc" and not d["wins"]


def test_rule_refuses_a_pooled_win_that_loses_on_one_source():
    """Much better on the benchmark, clearly worse on both real teams: pooled below zero, yet
    refused."""
    inc_r, inc_b = _errors(1, 6, 40.0), _errors(2, 200, 70.0)
    out = pooled_decision(
        {"inc": inc_r, "new": 1.1 * inc_r}, TEAMS, {"inc": inc_b, "new": 0.3 * inc_b}, "inc"
    )
    d = out["methods"]["new"]
    assert d["pooled"].hi < 0 and d["real"].lo > 0
    assert not out["changed"] and "worse beyond its interval on real" in d["reason"]


def test_rule_reports_but_does_not_adopt_a_winner_with_poor_coverage():
    inc_r, inc_b = _errors(1, 6, 40.0), _errors(2, 200, 70.0)
    out = pooled_decision(
        {"inc": inc_r, "new": 0.6 * inc_r},
        TEAMS,
        {"inc": inc_b, "new": 0.6 * inc_b},
        "inc",
        coverage_90={"new": 0.6},
    )
    assert out["methods"]["new"]["wins"] and not out["changed"]
