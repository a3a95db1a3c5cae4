"""Estimates without a posterior carry calibrated error circles
(``mission/localize/error_circles.py``).

Checked on the circles' geometry (their radius, the split-conformal quantile, is checked against its
closed form in ``tests/test_evidence.py``), on the card contract (missing, malformed, stale), on the
shipped calibrations (every shipped network calibrated on the exact file that ships; the classical
methods for both kinds of log) and on the product path (``localize`` on simulated and benchmark logs
returns the circles of the right calibration, and a note instead where none applies).
"""

from __future__ import annotations

import json
import math
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from _localize_helpers import write_synthetic_log
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mission.cli.localize import main as localize
from mission.cli.main import main as rfsl
from mission.errors import InputError
from mission.geo import Area
from mission.localize import Estimate
from mission.localize.api import localize_log, search_area
from mission.localize.error_circles import (
    CIRCLE_METHODS,
    REGIONS_KEY,
    attach_circles,
    card_calibration,
    circle_regions,
    flown_radii,
    method_calibration,
    model_digest,
)
from mission.spec import DEFAULT_MISSION
from mission.workshop.evaluate_suite import region_contains
from mission.workshop.suite import unseen_flight

SHIPPED = (
    "rfsl_default",
    "rfsl_spiral_e2r",
    "rfsl_afar",
    "rfsl_spiral_e2r_ens5",
    "rfsl_spiral_alt",
)


def test_circles_have_their_radius_and_contain_what_they_should():
    regs = circle_regions(100.0, -20.0, {0.9: 30.0, 0.5: 12.0}, "test")
    assert [r.level for r in regs] == [0.5, 0.9]
    for reg in regs:
        ring = np.asarray(reg.polygons[0])
        assert np.allclose(np.hypot(ring[:, 0] - 100.0, ring[:, 1] + 20.0), reg.radius_m, atol=0.1)
        assert reg.area_m2 == pytest.approx(np.pi * reg.radius_m**2)
        assert reg.ellipse.contains(100.0 + 0.99 * reg.radius_m, -20.0)
        assert not reg.ellipse.contains(100.0, -20.0 + 1.01 * reg.radius_m)


def _segment_area(r: float, d: float) -> float:
    """Area of a circle of radius r cut by a straight line at distance d from its centre (the larger
    part)."""
    return math.pi * r * r - (r * r * math.acos(d / r) - d * math.sqrt(r * r - d * d))


@given(r=st.floats(5.0, 300.0), frac=st.floats(0.02, 0.98))
@settings(max_examples=60, deadline=None)
def test_a_circle_across_an_area_edge_keeps_the_closed_form_segment(r, frac):
    """A circle whose centre lies inside a large square, ``frac * r`` from its east edge, is clipped
    to the circle minus the segment beyond that edge (closed form; the 72-gon underestimates the
    circle by < 0.2 %); every clipped vertex lies in the square, and coverage stays the circle's
    (the ellipse is unchanged)."""
    sq = Area(
        "rover area",
        np.array([[-2000.0, -2000.0], [frac * r, -2000.0], [frac * r, 2000.0], [-2000.0, 2000.0]]),
    )
    reg = circle_regions(0.0, 0.0, {0.9: r}, "test", sq)[0]
    assert reg.clipped_to == "rover area" and reg.radius_m == r
    assert reg.area_m2 == pytest.approx(_segment_area(r, frac * r), rel=3e-3)
    ring = np.asarray(reg.polygons[0])
    # rounded to 0.1 m
    assert np.allclose(ring[0], ring[-1]) and (ring[:, 0] <= frac * r + 0.05 + 1e-9).all()
    assert reg.ellipse.contains(0.99 * r * math.cos(2.0), 0.99 * r * math.sin(2.0))


def test_clipping_is_a_no_op_inside_the_area_and_the_whole_area_around_it():
    """Inside the area the circle is untouched; a circle holding a (non-convex, L-shaped) area whole
    clips to that area's own polygon and area; one that misses the area is kept whole."""
    ell = Area(
        "L", np.array([[0, 0], [100, 0], [100, 40], [40, 40], [40, 100], [0, 100]], dtype=float)
    )
    inside = circle_regions(20.0, 20.0, {0.5: 10.0}, "test", ell)[0]
    assert inside.clipped_to is None and inside.area_m2 == pytest.approx(np.pi * 100.0)
    whole = circle_regions(30.0, 30.0, {0.9: 500.0}, "test", ell)[0]
    assert whole.clipped_to == "L" and whole.area_m2 == pytest.approx(100 * 40 + 40 * 60)
    missed = circle_regions(500.0, 500.0, {0.9: 20.0}, "test", ell)[0]
    assert missed.clipped_to is None and missed.area_m2 == pytest.approx(np.pi * 400.0)


def test_a_circle_across_the_inner_corner_of_a_non_convex_area_has_the_right_area():
    """The L's inner corner at (40, 40): a circle of radius 30 there loses exactly the quarter
    inside the notch (three quarters remain, to the 72-gon's resolution)."""
    ell = Area(
        "L", np.array([[0, 0], [100, 0], [100, 40], [40, 40], [40, 100], [0, 100]], dtype=float)
    )
    reg = circle_regions(40.0, 40.0, {0.9: 30.0}, "test", ell)[0]
    assert reg.area_m2 == pytest.approx(0.75 * np.pi * 900.0, rel=3e-3)


@pytest.fixture()
def net(tmp_path, repo_dir):
    """A copy of a shipped network with a card of our own making."""
    p = tmp_path / "net.onnx"
    shutil.copy(repo_dir / "models" / "rfsl_spiral_e2r.onnx", p)
    return p


def _calibration_record(*args):
    """The record ``benchmarks/calibrate_error_circles.py`` writes into a card."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    # a script, importable once its folder is on sys.path (the line above)
    from calibrate_error_circles import calibration_record  # noqa: PLC0415

    return calibration_record(*args)


def test_card_contract(net):
    assert card_calibration(net, "sim") == (
        None,
        "net.onnx has no model card (net.json, benchmarks/calibrate_error_circles.py)",
    )
    card = net.with_suffix(".json")
    with pytest.raises(ValueError, match="need at least 9"):  # 4 flights cannot promise 90 %
        _calibration_record([1.0, 2.0, 3.0, 4.0], "t", net)
    card.write_text(
        json.dumps({REGIONS_KEY: {"sim": _calibration_record(np.arange(1.0, 21.0), "t", net)}})
    )
    rec, why = card_calibration(net, "sim")
    assert rec["radii_m"] == {0.5: 11.0, 0.9: 19.0} and rec["model_sha256"] == model_digest(net)
    assert (
        card_calibration(net, "real")[0] is None
        and "no 'real' calibration" in card_calibration(net, "real")[1]
    )
    est = Estimate(5.0, 6.0, "onnx")
    assert "no uncertainty region" in attach_circles(est, card_calibration(net, "real"))
    assert "regions" not in est.extras
    assert attach_circles(est, card_calibration(net, "sim")) is None
    assert [r.radius_m for r in est.regions] == [11.0, 19.0]
    assert est.regions[0].ellipse.x_m == 5.0 and est.regions[0].ellipse.y_m == 6.0
    # another model file: the calibration no longer applies
    net.write_bytes(net.read_bytes() + b"\0")
    rec, why = card_calibration(net, "sim")
    assert rec is None and "another version of the model file" in why


def test_circles_refused_by_a_rule_are_said_so_not_offered_for_calibration(net, repo_dir):
    """A card whose circles were calibrated and refused by a rule (``{"refused": why}``) gives no
    circles and says why, instead of pointing at the calibration script; the shipped tilt
    network's card is one (rule 36bdb24)."""
    net.with_suffix(".json").write_text(json.dumps({REGIONS_KEY: {"sim": {"refused": "why"}}}))
    assert card_calibration(net, "sim") == (None, "net.onnx's 'sim' circles were refused: why")
    net.with_suffix(".json").write_text(json.dumps({REGIONS_KEY: {"sim": {"refused": 3}}}))
    with pytest.raises(InputError) as e:
        card_calibration(net, "sim")
    assert "net.json" in str(e.value) and "regions.sim.refused" in str(e.value)
    rec, why = card_calibration(repo_dir / "models" / "rfsl_spiral_tilt.onnx", "sim")
    assert rec is None and "rule 36bdb24" in why and "calibrate_error_circles" not in why


@pytest.mark.parametrize(
    "entry",
    [
        {"radii_m": {"0.9": -1.0}},
        {"radii_m": {"1.5": 3.0}},
        {"radii_m": "x"},
        {},
        {"radii_m": {"0.9": "Infinity"}},
        {"radii_m": {}},
    ],
)
def test_a_malformed_card_entry_names_the_card_and_key(net, entry):
    net.with_suffix(".json").write_text(json.dumps({REGIONS_KEY: {"sim": entry}}))
    with pytest.raises(InputError) as e:
        card_calibration(net, "sim")
    assert "net.json" in str(e.value) and "regions.sim" in str(e.value)


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_network_is_calibrated_on_the_file_that_ships(name, repo_dir):
    """Both calibrations present and measured on this very file; circles grow with the level, and
    the real (benchmark) circles are wider than the simulated ones wherever the network is a
    simulation specialist."""
    model = repo_dir / "models" / f"{name}.onnx"
    sim, real = (card_calibration(model, d) for d in ("sim", "real"))
    assert sim[1] is None and real[1] is None, (sim[1], real[1])
    for rec in (sim[0], real[0]):
        assert rec["radii_m"][0.5] < rec["radii_m"][0.9] < math.inf and rec["n"] >= 400
    if name != "rfsl_afar":
        assert real[0]["radii_m"][0.9] > 2 * sim[0]["radii_m"][0.9]


def test_localize_gives_a_network_its_circles_on_simulated_and_benchmark_logs(tmp_path, repo_dir):
    """On a simulated spiral the default network answers with its 'sim' circles; on a benchmark log
    (a real receiver's kind) ``--model`` answers with its 'real' ones; both centred on the estimate,
    in the log frame."""
    assert rfsl(["simulate", str(DEFAULT_MISSION), "--seed", "7101", "--out", str(tmp_path)]) == 0
    est = localize_log(next(tmp_path.glob("*.csv")))
    model = est.extras["model_path"]
    # sized for the flight
    want, _ = flown_radii(card_calibration(model, "sim")[0], est.extras["track_coverage"])
    assert est.extras["track_coverage"] > 0.95
    assert [(r.level, r.radius_m) for r in est.regions] == sorted(want.items())
    assert all(r.ellipse.x_m == est.x_m and r.ellipse.y_m == est.y_m for r in est.regions)
    log, truth, _ = unseen_flight(2027, 3)
    est = localize_log(log, model_path=model)
    assert [r.radius_m for r in est.regions] == sorted(
        card_calibration(model, "real")[0]["radii_m"].values()
    )
    # the 'real' 90 % circle (~160 m) overhangs the AFAR rover area: the region is its part inside
    # that area
    ra = search_area(log)
    outer = est.outer_region
    ring = np.asarray(outer.polygons[0])
    assert outer.clipped_to == ra.name and outer.area_m2 < np.pi * outer.radius_m**2
    assert (ra.contains(ring) | (ra.edge_distance(ring) < 0.1)).all()
    assert outer.ellipse.contains(est.x_m, est.y_m)
    # what the benchmark reads from a composer's own layout says the same of the JSON form
    assert region_contains(est.extras["regions"][-1], (est.x_m, est.y_m))


_BAD_ENTRY = st.one_of(
    st.none().map(lambda _: {}),
    st.dictionaries(st.text(max_size=4), st.floats(allow_nan=True), max_size=3).map(
        lambda d: {"radii_m": d}
    ),
    st.floats(-1e3, 0.0).map(lambda r: {"radii_m": {"0.5": r, "0.9": 10.0}}),
    st.floats(1.0, 5.0).map(lambda lv: {"radii_m": {f"{lv}": 10.0}}),
    st.text(max_size=5).map(lambda t: {"radii_m": t}),
)


@given(entry=_BAD_ENTRY)
@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
def test_localize_refuses_a_malformed_card_with_one_line_and_exit_2(entry, net, tmp_path, capsys):
    """``localize --model`` with a card whose calibration is malformed: one line naming the card and
    the key, exit 2, never a traceback or a circle of made-up size."""
    log = tmp_path / "f.csv"
    if not log.exists():
        write_synthetic_log(log, (150.0, 150.0, 1.5))
    net.with_suffix(".json").write_text(json.dumps({REGIONS_KEY: {"sim": entry, "real": entry}}))
    capsys.readouterr()
    assert localize([str(log), "--model", str(net)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        len(err) == 1
        and err[0].startswith("error:")
        and "net.json" in err[0]
        and "regions." in err[0]
    ), err


@pytest.mark.parametrize("method", CIRCLE_METHODS)
def test_every_classical_method_is_calibrated_for_both_kinds_of_log(method):
    """The grid with the simulated log's own physics is near-exact (sub-metre circles); on the
    benchmark every method's circles are tens of metres, wider than on simulated logs."""
    (sim, why_s), (real, why_r) = (
        method_calibration(method, "sim"),
        method_calibration(method, "real"),
    )
    assert why_s is None and why_r is None
    for rec in (sim, real):
        assert rec["radii_m"][0.5] < rec["radii_m"][0.9] < math.inf and rec["n"] >= 300
    assert real["radii_m"][0.9] > sim["radii_m"][0.9]
    assert (sim["radii_m"][0.9] < 5.0) == (method == "grid")


def test_a_malformed_method_calibration_names_file_and_key(tmp_path):
    p = tmp_path / "circles.json"
    assert method_calibration("grid", "sim", p)[0] is None  # no file: no circles, a reason
    p.write_text(json.dumps({"grid": {"sim": {"radii_m": {"0.9": 0}}}}))
    with pytest.raises(InputError, match=r"circles.json.*grid\.sim\.radii_m"):
        method_calibration("grid", "sim", p)
    p.write_text(json.dumps({"grid": [1, 2]}))
    with pytest.raises(InputError, match=r"circles.json"):
        method_calibration("grid", "sim", p)


def test_classical_methods_get_circles_only_in_their_calibrated_configuration(tmp_path):
    assert rfsl(["simulate", str(DEFAULT_MISSION), "--seed", "7102", "--out", str(tmp_path)]) == 0
    log = next(tmp_path.glob("*.csv"))
    for method in CIRCLE_METHODS:
        est = localize_log(log, method=method)
        want = method_calibration(method, "sim")[0]["radii_m"]
        assert [(r.level, r.radius_m) for r in est.regions] == sorted(want.items()), method
    # not the calibrated configuration
    est = localize_log(log, method="grid", physics_model="free-space")
    assert (
        "regions" not in est.extras and "calibrated for its default physics" in est.extras["note"]
    )
    est = localize_log(log, method="strongest", cruise=False)
    assert "regions" not in est.extras and "sample selection" in est.extras["note"]
