"""Geodesy and areas: ENU round trips, known distances, point-in-polygon and margins."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mission.errors import InputError
from mission.geo import AFAR_GEOMETRY, Area, Origin, afar_field, clip_polygon, polygon_area_m2


def test_enu_round_trip_to_a_millimetre():
    o = Origin(35.72688, -78.69954, 100.0)
    rng = np.random.default_rng(1)
    enu = rng.uniform([-500, -500, 0], [500, 500, 120], size=(200, 3))
    lat, lon, alt = o.to_geodetic(enu)
    back = o.to_enu(lat, lon, alt)
    assert np.max(np.abs(back - enu)) < 1e-3


def test_enu_known_distances():
    o = Origin(35.7, -78.7, 0.0)
    # one arc-minute of latitude is about 1849 m at 35.7 deg (WGS84 meridian radius of curvature)
    n = o.to_enu(35.7 + 1 / 60, -78.7)
    assert n[0] == pytest.approx(0.0, abs=1e-6)
    assert n[1] == pytest.approx(1849.4, abs=1.0)
    # east distance shrinks with cos(latitude)
    e = o.to_enu(35.7, -78.7 + 1 / 60)
    assert e[0] == pytest.approx(1855.3 * np.cos(np.deg2rad(35.7)), rel=2e-3)
    assert o.to_enu(35.7, -78.7, 30.0)[2] == pytest.approx(30.0, abs=1e-6)


def test_area_contains_and_margin():
    a = Area("square", np.array([[0, 0], [100, 0], [100, 100], [0, 100]]))
    pts = np.array([[50, 50], [-1, 50], [99.5, 50], [150, 150]])
    assert a.contains(pts).tolist() == [True, False, True, False]
    assert a.contains(pts, margin_m=1.0).tolist() == [True, False, False, False]
    assert a.edge_distance(np.array([[50, 50]]))[0] == pytest.approx(50.0)
    assert a.signed_distance(np.array([[-3, 50]]))[0] == pytest.approx(-3.0)


def test_area_concave_polygon():
    # an L shape: the notch (75, 75) is outside
    a = Area("L", np.array([[0, 0], [100, 0], [100, 50], [50, 50], [50, 100], [0, 100]]))
    assert a.contains(np.array([[75, 75], [25, 75], [75, 25]])).tolist() == [False, True, True]


def test_area_rejects_degenerate():
    with pytest.raises(InputError, match="at least 3"):
        Area("bad", np.array([[0, 0], [1, 1]]))


def test_uniform_sampling_is_inside_and_seeded():
    f = afar_field()
    a = f.rover_area.sample_uniform(500, np.random.default_rng(3))
    b = f.rover_area.sample_uniform(500, np.random.default_rng(3))
    assert np.array_equal(a, b)
    assert f.rover_area.contains(a).all()


def test_afar_field_matches_shared_geometry(shared_dir):
    g = json.loads((shared_dir / "afar_geometry.json").read_text())
    for key in ("flight_area", "rover_area"):
        for k in ("lat_min", "lat_max", "lon_min", "lon_max"):
            assert AFAR_GEOMETRY[key][k] == g[key][k]
    f = afar_field(shared_dir / "afar_geometry.json")
    xmin, ymin, xmax, ymax = f.flight_area.bounds
    # the flight area is about 300 m x 270 m, origin at its south-west corner
    assert abs(xmin) < 0.5 and abs(ymin) < 0.5
    assert 290 < xmax < 310 and 260 < ymax < 280


def test_clipping_a_non_convex_area_keeps_every_part_and_its_area():
    """An L-shaped subject clipped by a square (closed forms), and a U clipped by a band across its
    arms: two parts, each inside both polygons."""
    ell = np.array([[0, 0], [100, 0], [100, 40], [40, 40], [40, 100], [0, 100.0]])
    parts = clip_polygon(ell, np.array([[20, 20], [80, 20], [80, 80], [20, 80.0]]))
    assert len(parts) == 1 and polygon_area_m2(parts[0]) == pytest.approx(60 * 60 - 40 * 40)
    u = np.array(
        [[0, 0], [100, 0], [100, 100], [70, 100], [70, 30], [30, 30], [30, 100], [0, 100.0]]
    )
    band = np.array([[-10, 50], [110, 50], [110, 80], [-10, 80.0]])
    parts = clip_polygon(u, band)
    assert sorted(polygon_area_m2(p) for p in parts) == pytest.approx([30 * 30, 30 * 30])
    for p in parts:
        assert Area("u", u).contains(p.mean(axis=0)) and Area("b", band).contains(p.mean(axis=0))
    assert clip_polygon(u, band + [500.0, 0.0]) == []  # apart: nothing
