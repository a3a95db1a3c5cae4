"""Antenna patterns: dipole formula, tabulated interpolation, CSV format, measured AERPAW
patterns."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mission.errors import InputError
from mission.physics import (
    Dipole,
    Mounted,
    TabulatedPattern,
    load_aerpaw_pattern,
    load_pattern,
    load_pattern_csv,
    mount_angles,
    rm_wb1_dn,
    save_pattern_csv,
)

SHARED = Path(__file__).resolve().parents[1] / ".." / "shared"
ANT = SHARED / "data" / "antenna"


def _need_shared() -> Path:
    if not (ANT / "RM-WB1-DN-BLK_right_side_up_F3300.txt").is_file():
        pytest.skip("../shared/data/antenna is absent")
    return ANT


def test_dipole_formula():
    d = Dipole()
    # G = 1.641 (cos(pi/2 sin el) / cos el)^2 worked by hand
    assert d.gain_dbi(0.0) == pytest.approx(2.1511, abs=1e-3)
    assert d.gain_dbi(math.radians(30)) == pytest.approx(
        10 * math.log10(1.641 * (0.70711 / 0.86603) ** 2), abs=1e-3
    )
    s60 = math.sin(math.radians(60))
    g60 = 1.641 * (math.cos(math.pi / 2 * s60) / 0.5) ** 2
    assert d.gain_dbi(math.radians(60)) == pytest.approx(10 * math.log10(g60), abs=1e-9)
    assert d.gain_dbi(math.radians(60)) == pytest.approx(-5.43, abs=0.01)
    assert d.gain_dbi(math.radians(90)) == pytest.approx(-40.0)  # axial null, floored
    assert d.gain_dbi(math.radians(-30)) == pytest.approx(d.gain_dbi(math.radians(30)))
    el = np.radians(np.linspace(-89, 89, 301)).astype(np.float32)
    fast = 20 * np.log10(d.amplitude(np.sin(el), np.cos(el), None))
    assert np.allclose(fast, d.gain_dbi(el.astype(float)), atol=1e-3)


def _grid() -> TabulatedPattern:
    el = np.array([-90.0, -30, 0, 30, 90])
    az = np.arange(0.0, 360.0, 90.0)
    rng = np.random.default_rng(0)
    return TabulatedPattern(el, az, rng.uniform(-10, 5, (el.size, az.size)))


def test_tabulated_exact_at_nodes_bilinear_and_periodic():
    p = _grid()
    E, A = np.meshgrid(p.el_deg, p.az_deg, indexing="ij")
    assert np.allclose(p.gain_dbi(np.radians(E), np.radians(A)), p.gain)
    assert np.allclose(p.gain_dbi(np.radians(E), np.radians(A + 360)), p.gain)
    assert np.allclose(p.gain_dbi(np.radians(E), np.radians(A - 720)), p.gain)
    # cell centre = mean of its 4 corners; the wrap cell joins az 270 and 360 = 0
    g = p.gain
    assert p.gain_dbi(math.radians(15), math.radians(45)) == pytest.approx(g[2:4, 0:2].mean())
    wrap = (g[2, 3] + g[2, 0] + g[3, 3] + g[3, 0]) / 4
    assert p.gain_dbi(math.radians(15), math.radians(315)) == pytest.approx(wrap)
    # fast path (float32, uniform grid) agrees
    rng = np.random.default_rng(1)
    el, az = rng.uniform(-1.5, 1.5, 500), rng.uniform(-7, 7, 500)
    q = TabulatedPattern(
        np.arange(-90.0, 91, 30), np.arange(0.0, 360, 45), rng.uniform(-10, 5, (7, 8))
    )
    fast = 20 * np.log10(q.amplitude_at(el.astype(np.float32), az.astype(np.float32)))
    assert np.allclose(fast, q.gain_dbi(el, az), atol=2e-3)


def test_csv_round_trip_and_errors(tmp_path):
    p = _grid()
    f = tmp_path / "pat.csv"
    save_pattern_csv(p, f, comments=("test pattern",))
    q = load_pattern_csv(f)
    assert np.allclose(q.gain, np.round(p.gain, 2)) and np.array_equal(q.az_deg, p.az_deg)
    assert isinstance(load_pattern(f), TabulatedPattern)
    bad = tmp_path / "bad.csv"
    bad.write_text("# c\nel\\az,0,90\n-90,1,2\n0,1,x\n")
    with pytest.raises(InputError, match=r"bad.csv, row 4"):
        load_pattern_csv(bad)
    bad.write_text("el\\az,0,90\n-90,1,2\n0,1\n")
    with pytest.raises(InputError, match="row 3"):
        load_pattern_csv(bad)
    bad.write_text("el\\az,0,90\n10,1,2\n0,1,2\n")
    with pytest.raises(InputError, match="ascending"):
        load_pattern_csv(bad)
    with pytest.raises(InputError, match="not found"):
        load_pattern(tmp_path / "missing.csv")


def test_mounting_heading_and_flip():
    el, az = mount_angles(0.3, math.radians(100), heading_rad=math.radians(40))
    # -(100 - 40) mod 360
    assert el == pytest.approx(0.3) and az == pytest.approx(math.radians(300))
    el, az = mount_angles(0.3, math.radians(100), heading_rad=math.radians(40), flipped=True)
    assert el == pytest.approx(-0.3) and az == pytest.approx(math.radians(60))
    p = _grid()
    m = Mounted(p, heading_rad=0.0, flipped=True)
    assert m.gain_dbi(math.radians(30), 0.0) == pytest.approx(p.gain_dbi(math.radians(-30), 0.0))


def _fibonacci_sphere(n: int) -> tuple[np.ndarray, np.ndarray]:
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    az = np.mod(math.pi * (1 + 5**0.5) * k, 2 * math.pi)
    return np.arcsin(z), az


def test_shipped_pattern_is_normalised_directivity():
    p = rm_wb1_dn()
    assert p.gain.shape == (61, 120)
    assert p.total_power_ratio() == pytest.approx(1.0, abs=0.01)
    el, az = _fibonacci_sphere(200_000)  # independent quadrature of the interpolated pattern
    assert np.mean(10 ** (p.gain_dbi(el, az) / 10)) == pytest.approx(1.0, abs=0.03)
    assert 4.0 < p.peak_dbi() < 8.0
    # not a donut: strongest towards its axis (up), weakest below
    up, down = p.gain_dbi(math.radians(90), 0.0), p.gain_dbi(math.radians(-90), 0.0)
    assert up > 4.0 and down < -3.0
    # the pole is one point: every azimuth gives the same value
    assert np.ptp(p.gain[-1]) < 0.02 and np.ptp(p.gain[0]) < 0.02


@pytest.mark.real
def test_measured_file_matches_shipped_and_flip_relation():
    ant = _need_shared()
    rsu = load_aerpaw_pattern(ant / "RM-WB1-DN-BLK_right_side_up_F3300.txt")
    assert np.allclose(rsu.gain, rm_wb1_dn().gain, atol=0.006)
    assert rsu.total_power_ratio() == pytest.approx(1.0, abs=1e-9)
    ud = load_aerpaw_pattern(ant / "RM-WB1-DN-BLK_upside_down_F3300.txt")
    el, az = _fibonacci_sphere(20_000)
    w = np.ones_like(el)

    def rms(a, b):
        d = a - b
        d -= np.average(d, weights=w)
        return float(np.sqrt(np.mean(d**2)))

    flipped = Mounted(rsu, flipped=True)  # mount_angles with az_p = -az_a, i.e. a turn about x_a
    g_ud = ud.gain_dbi(el, az)
    r_flip = rms(flipped.gain_dbi(el, np.mod(-az, 2 * math.pi)), g_ud)
    r_same = rms(rsu.gain_dbi(el, az), g_ud)
    assert r_flip < 3.0 < r_same
    # the dipole-like SA-1400-5900 has its deep null near its axis (|el| > 60 deg)
    sa = load_aerpaw_pattern(ant / "SA-1400-5900_F3300.txt")
    i, _ = np.unravel_index(np.argmin(sa.gain), sa.gain.shape)
    assert abs(sa.el_deg[i]) > 60


def test_load_aerpaw_errors(tmp_path):
    f = tmp_path / "x.txt"
    f.write_text("nothing here\n1 2 3\n")
    with pytest.raises(InputError, match="not an AERPAW"):
        load_aerpaw_pattern(f)
    f.write_text("Phi Theta E\n0 0 1\n0 bad 2\n")
    with pytest.raises(InputError, match="row 3"):
        load_aerpaw_pattern(f)
