"""Propagation physics against closed forms and limits (SPEC section 3, paper eqs. 1-9)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import brentq

from mission.physics import (
    GroundReflection,
    Isotropic,
    LegShadowing,
    PathGainSlope,
    body_angles,
    enu_to_ned,
    make_model,
)
from mission.physics.constants import SPEED_OF_LIGHT
from mission.physics.geometry import body_from_enu_matrix, body_from_enu_planes
from mission.physics.model import TERMS_KEPT

FC = 3.32e9
LAM = SPEED_OF_LIGHT / FC


def _iso(name: str, **kw):
    return make_model(name, pattern="isotropic", dtype=np.float64, **kw)


def test_free_space_friis_and_20db_per_decade():
    m = _iso("free-space")
    rx = np.array([[10.0, 0, 30], [100.0, 0, 30], [1000.0, 0, 30]])
    p = m.rss_dbm([0, 0, 30], rx)
    assert np.allclose(np.diff(p), -20.0, atol=1e-9)
    friis = 41.0 + 20 * math.log10(LAM / (4 * math.pi * 100.0))
    assert p[1] == pytest.approx(friis, abs=1e-9)
    # dipoles broadside add 2 x 2.15 dBi
    pd = make_model("free-space", dtype=np.float64).rss_dbm([0, 0, 30], rx)
    assert np.allclose(pd - p, 2 * 10 * math.log10(1.641), atol=1e-9)


def test_two_ray_equals_free_space_without_reflection():
    rng = np.random.default_rng(1)
    rx = np.c_[rng.uniform(-300, 300, (500, 2)), rng.uniform(10, 60, 500)]
    tx = [5.0, 7.0, 2.0]
    fs = make_model("free-space", dtype=np.float64).rss_dbm(tx, rx)
    tr = make_model("two-ray", dtype=np.float64)
    assert np.allclose(tr.without("ground_reflection").rss_dbm(tx, rx), fs, atol=1e-12)
    # a matched ground (eps_r = 1) reflects nothing: Gamma = 0 for both polarisations
    for pol in ("V", "H"):
        matched = tr.with_effect(GroundReflection(eps_r=1.0, polarization=pol))
        assert np.allclose(matched.rss_dbm(tx, rx), fs, atol=1e-9)


def test_two_ray_nulls_at_whole_wavelength_path_difference():
    h_t, h_r = 5.0, 30.0
    m = _iso("two-ray", polarization="H")
    fs = _iso("free-space")
    for k in (1, 2, 3):
        # solve d_ref - d_los = k lambda for d
        def f(d, k=k):
            return math.hypot(d, h_r + h_t) - math.hypot(d, h_r - h_t) - k * LAM

        d_k = brentq(f, 1.0, 1e6)
        d = np.linspace(d_k * 0.97, d_k * 1.03, 6001)
        rx = np.c_[d, np.zeros_like(d), np.full_like(d, h_r)]
        p = m.rss_dbm([0, 0, h_t], rx)
        assert abs(d[np.argmin(p)] - d_k) < 1e-4 * d_k  # the 1/d amplitudes move it by millimetres
        p_null = m.rss_dbm([0, 0, h_t], [[d_k, 0, h_r]])[0]
        assert p_null < fs.rss_dbm([0, 0, h_t], [[d_k, 0, h_r]])[0] - 15.0


def test_two_ray_40db_per_decade_beyond_breakpoint():
    h_t, h_r = 5.0, 30.0
    d_c = 4 * h_t * h_r / LAM
    for pol in ("V", "H"):
        m = _iso("two-ray", polarization=pol)
        rx = np.array([[10 * d_c, 0, h_r], [100 * d_c, 0, h_r]])
        p = m.rss_dbm([0, 0, h_t], rx)
        assert p[0] - p[1] == pytest.approx(40.0, abs=1.0)


def test_fresnel_limits():
    for eps in (2.0, 15.0):
        for pol in ("V", "H"):
            g = GroundReflection(eps_r=eps, polarization=pol)
            assert g.gamma(1e-7, FC) == pytest.approx(-1.0, abs=1e-5)  # grazing
            assert abs(g.gamma(math.pi / 2, FC)) == pytest.approx(
                abs((1 - eps**0.5) / (1 + eps**0.5))
            )
        # lossy ground still -> -1 at grazing
        assert GroundReflection(eps_r=eps, sigma_s_m=0.005).gamma(1e-8, FC) == pytest.approx(
            -1.0, abs=1e-5
        )
        psi = np.radians(np.linspace(0.01, 89.99, 20001))
        gv = np.abs(GroundReflection(eps_r=eps, polarization="V").gamma(psi, FC))
        brewster = math.atan(1 / math.sqrt(eps))
        assert abs(psi[np.argmin(gv)] - brewster) < math.radians(0.02)
        assert gv.min() < 1e-3
        gh = np.abs(GroundReflection(eps_r=eps, polarization="H").gamma(psi, FC))
        assert np.all(np.diff(gh) < 0)  # horizontal: monotone, no Brewster angle


def test_reflected_ray_geometry_and_image_source():
    m = make_model("e2r", dtype=np.float64)
    d, h_t, h_r = 80.0, 2.0, 30.0
    e = m.explain([0, 0, h_t], [[d, 0, h_r]], np.zeros((1, 3)))
    assert e["d_ref"][0] == pytest.approx(math.hypot(d, h_r + h_t))
    assert e["el_tx_ref_rad"][0] == pytest.approx(-math.atan2(h_r + h_t, d))  # departs downwards
    # arrives from the image
    assert e["dep_b_ref_rad"][0] == pytest.approx(math.atan2(h_r + h_t, d))
    assert e["dep_b_rad"][0] == pytest.approx(math.atan2(h_r - h_t, d))
    g = m.effect("rx_antenna").pattern.gain_dbi(-math.atan2(h_r + h_t, d), 0.0)
    assert e["g_rx_ref_dbi"][0] == pytest.approx(float(g))


def test_zero_attitude_equals_two_ray():
    rng = np.random.default_rng(2)
    rx = np.c_[rng.uniform(-300, 300, (800, 2)), rng.uniform(10, 60, 800)]
    tx = np.c_[rng.uniform(-300, 300, (5, 2)), np.full(5, 1.5)][:, None, :]
    for pattern in ("dipole", "measured"):
        e2r = make_model("e2r", pattern=pattern, dtype=np.float64)
        tr = make_model("two-ray", pattern=pattern, dtype=np.float64)
        a = e2r.without("leg_shadowing").rss_dbm(tx, rx, np.zeros((800, 3)))
        assert np.allclose(a, tr.rss_dbm(tx, rx), atol=1e-6)
        assert np.allclose(
            e2r.rss_dbm(tx, rx, None), e2r.rss_dbm(tx, rx, np.zeros((800, 3))), atol=1e-6
        )


def test_yaw_rotates_body_azimuth_by_minus_yaw():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(1000, 3))
    yaw = rng.uniform(-np.pi, np.pi, 1000)
    az0, dep0 = body_angles(u)
    az, dep = body_angles(u, np.c_[np.zeros(1000), np.zeros(1000), yaw])
    diff = np.mod(az - (az0 - yaw) + np.pi, 2 * np.pi) - np.pi
    assert np.allclose(diff, 0, atol=1e-9)
    assert np.allclose(dep, dep0, atol=1e-12)
    # nose north, TX due east: az_b = 90 deg (to the right); below: dep_b > 0
    az, dep = body_angles(enu_to_ned([10.0, 0.0, -10.0]))
    assert math.degrees(az) == pytest.approx(90.0) and math.degrees(dep) == pytest.approx(45.0)
    # pitch up 10 deg: a target on the horizon straight ahead appears 10 deg below the body plane
    az, dep = body_angles(enu_to_ned([0.0, 10.0, 0.0]), [0.0, math.radians(10), 0.0])
    assert math.degrees(dep) == pytest.approx(10.0)


def test_180_degree_symmetry():
    """Turning the TX 180 deg about the UAV and the UAV yaw by 180 deg leaves the body geometry
    unchanged."""
    rng = np.random.default_rng(4)
    m = make_model("e2r", tx_pattern="dipole", rx_pattern="measured", dtype=np.float64)
    rx = np.c_[rng.uniform(-200, 200, (300, 2)), rng.uniform(20, 50, 300)]
    att = np.c_[rng.uniform(-0.1, 0.1, (300, 2)), rng.uniform(0, 2 * np.pi, 300)]
    tx = np.c_[rng.uniform(-200, 200, (300, 2)), np.full(300, 1.5)]
    tx2 = tx.copy()
    tx2[:, :2] = 2 * rx[:, :2] - tx[:, :2]
    att2 = att.copy()
    att2[:, 2] += np.pi
    assert np.allclose(m.rss_dbm(tx, rx, att), m.rss_dbm(tx2, rx, att2), atol=1e-6)


def _tx_at(rx, az_deg, dep_deg, r=100.0):
    az, dep = np.radians(az_deg), np.radians(dep_deg)
    return rx + r * np.stack([np.cos(dep) * np.sin(az), np.cos(dep) * np.cos(az), -np.sin(dep)], -1)


def test_leg_shadowing_intervals_threshold_and_upsilon():
    beta = 2.5
    m = make_model("e2r", beta=beta, dtype=np.float64)
    base = m.without("leg_shadowing")
    rx = np.array([[0.0, 0.0, 60.0]])
    att = np.zeros((1, 3))
    cases = []
    for psi in (39.0, 150.0, 270.0):
        for off, inside in ((0.0, True), (4.9, True), (-4.9, True), (5.1, False), (-5.1, False)):
            for dep, below_thr in (
                (5.0, True),
                (-20.0, True),
                (9.9, True),
                (10.1, False),
                (40.0, False),
            ):
                cases.append((psi + off, dep, inside and below_thr))
    for az in (0.0, 90.0, 200.0, 330.0):
        cases.append((az, 0.0, False))
    for az, dep, expect in cases:
        tx = _tx_at(rx[0], az, dep)
        loss = base.rss_dbm(tx, rx, att)[0] - m.rss_dbm(tx, rx, att)[0]
        e = m.explain(tx, rx, att)
        assert bool(e["shadowed"][0]) == expect, (az, dep)
        assert loss == pytest.approx(10 * beta * math.log10(100.0) if expect else 0.0, abs=1e-6)
    # random directions: fast-path mask == reference angles, also under attitude
    rng = np.random.default_rng(5)
    n = 4000
    rxs = np.c_[np.zeros((n, 2)), np.full(n, 60.0)]
    att = np.c_[rng.uniform(-0.2, 0.2, (n, 2)), rng.uniform(0, 2 * np.pi, n)]
    tx = rxs + rng.normal(size=(n, 3)) * [150, 150, 20]
    e = m.explain(tx, rxs, att)
    fast = (base.rss_dbm(tx, rxs, att) - m.rss_dbm(tx, rxs, att)) > 1e-6
    assert np.array_equal(fast, e["shadowed"] & (e["d_los"] > 1.0))
    assert e["shadowed"].any()
    ls = LegShadowing(beta=beta)
    assert np.allclose(e["upsilon_db"], np.where(e["shadowed"], ls.upsilon_db(e["d_los"]), 0))


def test_broadcasting_equals_loop():
    rng = np.random.default_rng(6)
    m = make_model("e2r", pattern="measured")
    N, M = 700, 9
    rx = np.c_[rng.uniform(-200, 200, (N, 2)), rng.uniform(20, 50, N)]
    att = rng.uniform(-0.3, 0.3, (N, 3))
    tx = np.c_[rng.uniform(-200, 200, (M, 2)), np.full(M, 1.5)]
    out = m.rss_dbm(tx[:, None, :], rx, att)
    assert out.shape == (M, N)
    for i in range(M):
        assert np.allclose(out[i], m.rss_dbm(tx[i], rx, att), atol=1e-4)
    # paired: one tx per sample
    txp = np.c_[rng.uniform(-200, 200, (N, 2)), np.full(N, 1.5)]
    pr = m.rss_dbm(txp, rx, att)
    assert pr.shape == (N,)
    idx = rng.choice(N, 20, replace=False)
    loop = [m.rss_dbm(txp[i], rx[i : i + 1], att[i : i + 1])[0] for i in idx]
    assert np.allclose(pr[idx], loop, atol=1e-4)
    # small chunks give the same answer as one block
    assert np.allclose(replace(m, chunk=100).rss_dbm(tx[:, None, :], rx, att), out, atol=1e-4)


@pytest.mark.parametrize("pattern", ["dipole", "measured", "isotropic"])
@pytest.mark.parametrize("name", ["free-space", "two-ray", "e2r"])
def test_float32_fast_path_matches_float64_reference(name, pattern):
    rng = np.random.default_rng(7)
    N = 3000
    rx = np.c_[rng.uniform(0, 400, (N, 2)), rng.uniform(15, 50, N)]
    att = np.c_[rng.uniform(-0.1, 0.1, (N, 2)), rng.uniform(0, 2 * np.pi, N)]
    tx = np.c_[rng.uniform(0, 400, (4, 2)), rng.uniform(1, 5, 4)][:, None, :]
    m = make_model(name, pattern=pattern, eps_r=15, sigma_s_m=0.005)
    fast = m.rss_dbm(tx, rx, att)
    assert fast.dtype == np.float32
    ref = m.explain(tx, rx, att)["rss_dbm"]
    assert np.max(np.abs(fast - ref)) < 0.01
    f64 = make_model(name, pattern=pattern, eps_r=15, sigma_s_m=0.005, dtype=np.float64)
    assert np.max(np.abs(f64.rss_dbm(tx, rx, att) - ref)) < 1e-4


def test_model_composition_api():
    m = make_model("e2r")
    assert m.names == (
        "free_space",
        "tx_antenna",
        "rx_antenna",
        "ground_reflection",
        "attitude",
        "leg_shadowing",
    )
    assert m.effect("leg_shadowing").beta == 2.0
    m2 = m.with_params("leg_shadowing", beta=3.0)
    assert m2.effect("leg_shadowing").beta == 3.0 and m.effect("leg_shadowing").beta == 2.0
    assert "attitude" not in m.without("attitude").names
    m3 = m.with_effect(GroundReflection(eps_r=15, sigma_s_m=0.005))
    assert m3.names == m.names and m3.effect("ground_reflection").eps_r == 15
    m4 = make_model("free-space").with_effect(LegShadowing())
    assert m4.names[-1] == "leg_shadowing"
    with pytest.raises(KeyError):
        m.effect("nope")
    with pytest.raises(KeyError):
        m.without("nope")
    with pytest.raises(ValueError):
        make_model("e2r").without("free_space")
    with pytest.raises(ValueError):
        make_model("three-ray")


def test_custom_additive_effect_plugs_in():
    class Offset:
        name = "offset"

        def rss_term_db(self, link):
            return np.full_like(link.d_los, -3.0)

    m = make_model("two-ray", dtype=np.float64)
    rx = np.array([[50.0, 0, 30], [100, 0, 30]])
    assert np.allclose(
        m.with_effect(Offset()).rss_dbm([0, 0, 2], rx), m.rss_dbm([0, 0, 2], rx) - 3.0
    )
    e = m.with_effect(Offset()).explain([0, 0, 2], rx)
    assert np.allclose(e["offset_db"], -3.0)


def test_isotropic_pattern_is_zero_dbi():
    assert np.all(Isotropic().gain_dbi(np.linspace(-1.5, 1.5, 5), 0.3) == 0)


def test_body_matrix_planes_equal_the_matrix():
    """The fast path's (3, 3, N) layout holds exactly the body-from-ENU matrix of every sample."""
    att = np.random.default_rng(5).uniform(-np.pi, np.pi, (257, 3))
    assert np.allclose(
        body_from_enu_planes(att), body_from_enu_matrix(att).transpose(1, 2, 0), atol=1e-15
    )


def test_planes_made_once_give_the_same_rss_and_belong_to_their_model() -> None:
    """``attitude_planes`` handed back to ``rss_dbm`` (the gap fits' way to skip the rotation per
    call) give the very values of passing the attitude; planes of another attitude effect or sample
    count are refused."""
    rng = np.random.default_rng(5)
    rx = np.column_stack(
        [rng.uniform(0, 300, 400), rng.uniform(0, 300, 400), rng.uniform(20, 50, 400)]
    )
    att = np.radians(rng.uniform(-20, 20, (400, 3)))
    tx = np.array([[120.0, 80.0, 1.5], [10.0, 250.0, 3.0]])[:, None, :]
    m = make_model("e2r", pattern="measured")
    planes = m.attitude_planes(att)
    np.testing.assert_array_equal(m.rss_dbm(tx, rx, planes=planes), m.rss_dbm(tx, rx, att))
    assert not planes.planes.flags.writeable
    yaw_only = m.with_params("attitude", roll_pitch=False)
    with pytest.raises(ValueError, match="another model"):
        yaw_only.rss_dbm(tx, rx, planes=planes)
    with pytest.raises(ValueError, match="another model"):
        m.rss_dbm(tx, rx[:10], planes=planes)


def test_prepared_links_give_the_same_rss_and_keep_geometry_and_terms() -> None:
    """``prepare_links`` (a fit's samples made ready once) gives ``rss_dbm``'s very values over
    several blocks, for models that differ in their effects' parameters (legs, slope, the UAV
    antenna's heading, ground), with the geometry, the antenna amplitudes and the additive terms
    kept per block; links of another attitude effect are refused."""

    rng = np.random.default_rng(7)
    n = 2500
    rx = np.column_stack([rng.uniform(0, 300, n), rng.uniform(0, 300, n), rng.uniform(5, 50, n)])
    att = np.radians(rng.uniform(-20, 20, (n, 3)))
    tx = np.column_stack(
        [np.full(n, 120.0), np.full(n, 80.0), np.where(np.arange(n) < 900, 1.5, 3.0)]
    )
    centre = np.zeros((n, 3))
    centre[:900, :2], centre[900:, :2] = rx[:900, :2].mean(0), rx[900:, :2].mean(0)
    m = replace(make_model("e2r", pattern="measured"), chunk=1000)  # three blocks
    links = m.prepare_links(tx, rx, att, centre=centre)
    assert len(links.spans) == 3
    for beta, heading in ((2.0, 0.0), (3.5, 0.0), (2.0, 0.6), (2.0, 0.0)):
        for slope in (0.0, 0.7):
            mm = m.with_params("leg_shadowing", beta=beta).with_effect(PathGainSlope(slope))
            mm = mm.with_params("rx_antenna", heading_rad=heading)
            want = mm.rss_dbm(tx, rx, att, centre=centre)
            np.testing.assert_array_equal(mm.rss_dbm(tx, rx, links=links), want)
            ground = mm.without("ground_reflection")
            np.testing.assert_array_equal(
                ground.rss_dbm(tx, rx, links=links), ground.rss_dbm(tx, rx, att, centre=centre)
            )
    assert all(g is not None for g in links.geometry)
    assert all(len(t) <= TERMS_KEPT for t in links.terms) and len(links.terms[0]) >= 2
    assert not links.geometry[0][6].flags.writeable  # d_los
    with pytest.raises(ValueError, match="another model"):
        m.with_params("attitude", roll_pitch=False).rss_dbm(tx, rx, links=links)
