"""Trajectory generators: the spiral covers the overlap and fits the budget; all respect the
fence."""

from __future__ import annotations

import numpy as np
import pytest

from mission.errors import InputError
from mission.geo import afar_field
from mission.preview import _dist_to_polyline
from mission.simulate import fly_path
from mission.spec import load_mission
from mission.trajectory.generators import (
    GENERATORS,
    coverage_radius,
    generate,
    overlap_area,
    spiral,
)
from mission.trajectory.kinematics import Kinematics, plan_profile


@pytest.fixture(scope="module")
def field():
    return afar_field()


def _overlap_grid(field, step=1.0):
    ov = overlap_area(field)
    x0, y0, x1, y1 = ov.bounds
    xs, ys = np.arange(x0, x1 + 1e-9, step), np.arange(y0, y1 + 1e-9, step)
    g = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    return g[ov.contains(g) | (ov.edge_distance(g) < 1e-6)]


def test_overlap_is_the_afar_box_intersection(field):
    x0, y0, x1, y1 = overlap_area(field).bounds
    assert (x0, x1) == pytest.approx((0.0, 256.78), abs=0.02)
    assert (y0, y1) == pytest.approx((95.73, 269.42), abs=0.02)


@pytest.mark.parametrize("spacing", [15.0, 22.0, 30.0])
def test_spiral_inside_flight_area_and_covers_overlap(field, spacing):
    w = spiral(field, 30.0, spacing_m=spacing, margin_m=5.0)
    assert np.all(w[:, 2] == 30.0)
    assert np.all(field.flight_area.contains(w, margin_m=5.0 - 1e-6))
    # consecutive legs alternate east-west / north-south (a rectangular spiral), each ring inside
    # the last
    d = np.diff(w[:, :2], axis=0)
    assert np.all((np.abs(d[:, 0]) < 1e-9) ^ (np.abs(d[:, 1]) < 1e-9))
    g = _overlap_grid(field)
    dist = _dist_to_polyline(g, w)
    # half a ring spacing everywhere except the small triangles outside inner ring corners, which
    # are bounded by the exact corner geometry (see generators.coverage_radius)
    assert np.mean(dist <= spacing / 2 + 1e-6) > 0.98
    assert dist.max() <= coverage_radius(spacing) + 1e-6


def test_default_spiral_fits_ten_minutes(field):
    spec = load_mission()  # missions/spiral.yaml
    prof = plan_profile(spec.flight_path_enu(), spec.kinematics())
    assert spec.altitude_m == 30.0 and spec.trajectory.generator == "spiral"
    assert 8 * 60 <= prof.duration_s <= 9.5 * 60 < 600
    # the same number from the simulator's own path sampling
    t, _, _, _ = fly_path(spec.flight_path_enu(), spec.sim_config(), np.random.default_rng(0))
    assert t[-1] <= 600.0 and len(t) > 15000


@pytest.mark.parametrize("name", sorted(GENERATORS))
@pytest.mark.parametrize("region", ["overlap", "flight"])
def test_every_generator_respects_the_fence(field, name, region):
    w = generate(name, field, 30.0, margin_m=4.0, region=region)
    assert w.shape[1] == 3 and len(w) >= 2
    # waypoints and densely sampled legs stay inside with the margin
    s = np.linspace(0, 1, 200)[:, None, None]
    pts = (w[:-1, :2][None] + s * (w[1:, :2] - w[:-1, :2])[None]).reshape(-1, 2)
    assert np.all(field.flight_area.signed_distance(pts) >= 4.0 - 1e-6), name
    prof = plan_profile(w, Kinematics())
    assert prof.duration_s > 0


def test_random_waypoints_seeded(field):
    a = generate("random_waypoints", field, 30.0, seed=3)
    b = generate("random_waypoints", field, 30.0, seed=3)
    c = generate("random_waypoints", field, 30.0, seed=4)
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_edge_sweep_starts_with_bottom_then_left_edge(field):
    w = generate("edge_sweep", field, 30.0, margin_m=5.0)
    x0, y0, x1, y1 = overlap_area(field).bounds
    assert w[0, :2] == pytest.approx([x1 - 5, y0 + 5], abs=0.02)
    assert w[1, :2] == pytest.approx([x0 + 5, y0 + 5], abs=0.02)
    assert w[2, :2] == pytest.approx([x0 + 5, y1 - 5], abs=0.02)


def test_bad_generator_arguments(field):
    with pytest.raises(InputError, match="unknown generator"):
        generate("zigzag", field, 30.0)
    with pytest.raises(InputError, match="spacing_m"):
        generate("spiral", field, 30.0, spacing_m=-1)
    with pytest.raises(InputError, match="unknown parameter 'spacing'"):
        generate("spiral", field, 30.0, spacing=20)
