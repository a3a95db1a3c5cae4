"""The unseen-flight benchmark: deterministic flights in the real-log form, every axis drawn, no
truth leak."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mission.errors import InputError
from mission.geo import afar_field
from mission.localize.api import localize_log
from mission.workshop.dataset import DatasetConfig, generate_dataset, load_dataset
from mission.workshop.evaluate import Row
from mission.workshop.evaluate_suite import breakdown, evaluate_suite, region_contains, suite_method
from mission.workshop.suite import (
    HABITS,
    SHADOWING,
    draw_flight,
    simulate_draw,
    unseen_flight,
    unseen_flights,
)
from mission.workshop.suite_cache import read_suite, write_suite


def test_flights_are_deterministic_per_index():
    a = unseen_flights(3, seed=7)[2]
    b = unseen_flight(7, 2)
    for k, v in a.log.columns.items():
        np.testing.assert_array_equal(v, b.log.columns[k])
    assert a.draw == b.draw
    assert not np.array_equal(unseen_flight(8, 2).log["rss_dbm"][:50], b.log["rss_dbm"][:50])


def test_log_looks_like_a_real_import_without_truth():
    log, truth, draw = unseen_flight(7, 0)
    assert log.meta["rss_source"]["kind"] not in ("sim",)
    assert "truth" not in log.meta and log.truth_enu is None
    assert "physics" not in json.dumps(log.meta) and "tx_xy" not in json.dumps(log.meta)
    assert len(log.meta["rover_area"]) >= 4
    json.dumps(draw)  # the draw is JSON-able (it goes into suite.json)
    assert np.allclose(truth, draw["tx_xy"])
    h = log.enu()[:, 2]
    # take-off + cruise in the log
    assert h.min() < 1.0 and abs(np.percentile(h, 90) - draw["altitude_m"]) < 2.0

    est = localize_log(log)  # a real log's default path (not the simulated-log network)
    assert "real receiver" in est.extras["method_choice"]


def test_axes_span_the_family():
    ds = [draw_flight(11, i)[0] for i in range(80)]
    assert {d["heading_habit"] for d in ds} == set(HABITS)
    assert len({d["trajectory"] for d in ds}) == 5
    out = np.mean([d["tx_outside_flight_area"] for d in ds])
    assert 0.15 < out < 0.65
    alt = [d["altitude_m"] for d in ds]
    assert 15 <= min(alt) < 25 and 50 < max(alt) <= 60
    ants = {d["physics"]["rx_antenna"] for d in ds}
    assert ants == {"preset", "flipped", "upright", "dipole"}
    assert {d["physics"]["spec"]["ground"] is None for d in ds} == {True, False}
    generic = [draw_flight(11, i, family="generic")[0]["physics"]["rx_antenna"] for i in range(30)]
    assert "preset" not in generic


def _flight_with(habit: str):
    for i in range(60):
        d, rng = draw_flight(3, i)
        if d["heading_habit"] == habit:
            return d, simulate_draw(d, rng)
    raise AssertionError(habit)


def test_heading_habits():
    d, (cols, pos, cruise) = _flight_with("slow_rotation")
    yaw = np.unwrap(np.deg2rad(cols["yaw_deg"][cruise]))
    t = cols["t_s"][cruise]
    rate = np.polyfit(t, np.rad2deg(yaw), 1)[0]
    assert rate == pytest.approx(d["rotation_dps"], abs=0.3)
    d, (cols, pos, cruise) = _flight_with("fixed")
    dev = (cols["yaw_deg"][cruise] - d["fixed_heading_deg"] + 180) % 360 - 180
    assert np.abs(dev).max() <= d["attitude_perturbation_deg"] + 0.5
    d, (cols, pos, cruise) = _flight_with("hover_turn")
    v = np.linalg.norm(np.diff(pos[:, :2], axis=0), axis=1) / np.diff(cols["t_s"])
    still = cruise[1:] & (v < 0.05)
    yaw = np.unwrap(np.deg2rad(cols["yaw_deg"]))
    turned = np.abs(np.diff(yaw))[still].sum()
    assert turned > 2 * np.pi  # it turns while hovering


def test_time_offset_shifts_telemetry():
    d, rng = draw_flight(5, 1)
    d = {**d, "time_offset_s": 0.4}
    cols, pos, _ = simulate_draw(d, rng)

    logged = afar_field().origin.to_enu(cols["lat_deg"], cols["lon_deg"], cols["alt_m"])
    t = cols["t_s"]
    k = len(t) // 2
    truth_later = np.array([np.interp(t[k] + 0.4, t, pos[:, j]) for j in range(3)])
    assert np.allclose(logged[k], truth_later, atol=0.05)


def test_cache_roundtrip_and_workers(tmp_path):
    write_suite(tmp_path / "s", 3, seed=9, workers=2)
    cs = read_suite(tmp_path / "s")
    assert len(cs) == 3
    f = cs.load(1)
    live = unseen_flight(9, 1)
    np.testing.assert_allclose(f.log["rss_dbm"], live.log["rss_dbm"], atol=1e-4)
    np.testing.assert_allclose(f.truth_xy, live.truth_xy)
    r1, _ = evaluate_suite(["strongest", "centroid"], 3, seed=9, workers=1)
    r2, _ = evaluate_suite(["strongest", "centroid"], 3, seed=9, workers=2)
    r3, _ = evaluate_suite(["strongest", "centroid"], 3, suite_dir=tmp_path / "s", workers=1)
    assert [r.errors for r in r1] == [r.errors for r in r2]
    np.testing.assert_allclose(r1[0].errors, r3[0].errors, atol=0.05)
    assert r1[0].summary()["n"] == 3


def test_methods_and_regions():
    assert suite_method("default") == {}
    assert suite_method("grid:preset:afar:fit328") == {
        "method": "grid",
        "physics_preset": "afar:fit328",
    }
    assert suite_method("grid:two-ray") == {"method": "grid", "physics_model": "two-ray"}
    for bad in ("gird", "onnx:/no/such.onnx"):
        with pytest.raises(InputError):
            suite_method(bad)
    # long axis north
    ell = {
        "center_m": [10.0, 0.0],
        "semi_axes_m": [20.0, 5.0],
        "angle_deg": 90.0,
    }
    assert region_contains(ell, (10.0, 18.0)) and not region_contains(ell, (28.0, 0.0))
    assert region_contains({"polygon": [[0, 0], [10, 0], [10, 10], [0, 10]]}, (5, 5))
    assert not region_contains(
        {"center_m": [0, 0], "cov_m2": [[4, 0], [0, 1]], "chi2": 1.0}, (0, 1.5)
    )


def test_training_dataset_from_the_family(tmp_path):
    with pytest.raises(InputError, match="benchmark"):
        generate_dataset(
            DatasetConfig(None, 2, seed=2026, suite="unseen", features=("clustering",)),
            tmp_path / "x",
        )
    generate_dataset(
        DatasetConfig(None, 2, seed=4, suite="unseen", features=("clustering",)), tmp_path / "d"
    )
    arrays, m = load_dataset(tmp_path / "d")
    assert arrays["clustering"].shape == (2, 60) and np.isfinite(arrays["clustering"]).all()
    assert np.allclose(arrays["tx_enu"][1, :2], unseen_flight(4, 1).truth_xy)
    assert m["config"]["suite"] == "unseen"


def test_breakdown_by_axis():
    draws = [
        {"habit": h, "alt": a, "physics": {"ant": p}}
        for h, a, p in (
            ("fixed", 20.0, "dipole"),
            ("fixed", 30.0, "flipped"),
            ("rot", 50.0, "dipole"),
            ("rot", 60.0, "x"),
        )
    ]
    rows = [Row("t", "m1", None, None, [10.0, 20.0, 30.0, 50.0])]
    assert breakdown(rows, draws, "habit") == {
        "fixed": {"n": 2, "m1": 15.0},
        "rot": {"n": 2, "m1": 40.0},
    }
    assert breakdown(rows, draws, "physics.ant")["dipole"]["m1"] == 20.0
    by_alt = breakdown(rows, draws, "alt", bins=2)
    assert [d["n"] for d in by_alt.values()] == [2, 2] and list(by_alt.values())[1]["m1"] == 40.0
    with pytest.raises(InputError, match="no axis"):
        breakdown(rows, draws, "speed")


def test_heavy_family_changes_only_the_shadowing():
    """``afar-heavy`` draws the same flights as ``afar`` (same generator sequence) with the
    real-measured shadowing: wider and longer-correlated, so its logs spread more in dB."""
    (s_lo, s_hi), (l_lo, l_hi) = SHADOWING["afar-heavy"]
    spreads = {"afar": [], "afar-heavy": []}
    for i in range(12):
        a, h = draw_flight(5, i)[0], draw_flight(5, i, family="afar-heavy")[0]
        assert s_lo <= h["shadowing_db"] <= s_hi and l_lo <= h["shadowing_corr_m"] <= l_hi
        same = {k for k in a if k not in ("family", "shadowing_db", "shadowing_corr_m")}
        assert {k: a[k] for k in same} == {k: h[k] for k in same}
        for fam in spreads:
            rss = unseen_flight(5, i, fam).log["rss_dbm"]
            spreads[fam].append(np.ptp(np.percentile(rss[np.isfinite(rss)], [5, 95])))
    assert np.median(spreads["afar-heavy"]) > np.median(spreads["afar"]) + 3.0


def test_unknown_family_is_one_line_naming_the_families():
    with pytest.raises(InputError, match="afar-heavy"):
        draw_flight(5, 0, family="heavy")
