"""Link geometry has one home (``mission.physics.geometry``): the self-calibrating grid's float32
fast path and the level/heading-frame helpers agree with the float64 reference ``body_angles`` on
random seeded geometry."""

from __future__ import annotations

import numpy as np
import pytest

from mission.cells import Cells
from mission.gap.align import align
from mission.localize.selfcal import _geometry
from mission.physics import make_model
from mission.physics.geometry import (
    bearing,
    body_angles,
    body_azimuth,
    body_from_enu_matrix,
    body_vectors,
    depression,
    elevation,
    enu_to_ned,
    heading_frame_angles,
    horizontal_distance,
    link_delta,
    sin_depression,
    sin_elevation,
    slant_distance,
)
from mission.samples import FlightSamples

# float32 keeps ~7 digits: angles of order 2 pi to about 1e-6 rad; the stated tolerances leave a
# margin of ~10
ANGLE_TOL_RAD = 2e-5
PATH_GAIN_TOL_DB = 1e-4


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angle difference folded into [-pi, pi)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


def _random_geometry(seed: int, k: int = 40, m: int = 300):
    """K candidate transmitters and M cells over a 400 m field (ENU offset like a real origin),
    random attitude."""
    rng = np.random.default_rng(seed)
    # large coordinates: float32 must difference after the float64 one
    off = rng.uniform(-2000.0, 2000.0, 2)
    cand = off + rng.uniform(0.0, 400.0, (k, 2))
    enu = np.column_stack([off + rng.uniform(0.0, 400.0, (m, 2)), rng.uniform(5.0, 60.0, m)])
    att = np.column_stack(
        [rng.uniform(-0.3, 0.3, m), rng.uniform(-0.3, 0.3, m), rng.uniform(-np.pi, np.pi, m)]
    )
    cells = Cells(enu, np.zeros(m), att[:, 2].copy(), np.ones(m, int), 10.0)
    return cand, cells, att, float(rng.uniform(0.5, 5.0))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_selfcal_float32_geometry_matches_float64_body_angles(seed):
    cand, cells, att, h = _random_geometry(seed)
    pg, el, az, el_uav = _geometry(cand, cells, h)
    assert el_uav is el  # cells without a body axis are level
    assert pg.dtype == el.dtype == az.dtype == np.float32
    tx = np.column_stack([cand, np.full(len(cand), h)])
    u = tx[:, None, :] - cells.enu_m[None, :, :]  # (K, M, 3) ENU, float64
    # selfcal's frame is the heading only (antenna hanging below the body): the reference at roll =
    # pitch = 0
    heading_only = np.column_stack([np.zeros((len(att), 2)), att[:, 2]])
    az_ref, dep_ref = body_angles(enu_to_ned(u), heading_only[None, :, :])
    assert np.max(np.abs(_wrap(az.astype(float) - az_ref))) < ANGLE_TOL_RAD
    assert np.max(np.abs(el.astype(float) + dep_ref)) < ANGLE_TOL_RAD
    d_los = np.linalg.norm(u, axis=-1)
    assert np.max(np.abs(pg.astype(float) + 20.0 * np.log10(d_los))) < PATH_GAIN_TOL_DB
    # with the full attitude the body angles move by at most the tilt: what the heading-only frame
    # leaves out
    az_full, dep_full = body_angles(enu_to_ned(u), att[None, :, :])
    tilt = np.abs(att[:, 0]) + np.abs(att[:, 1])
    assert np.all(np.abs(dep_full - dep_ref) <= tilt[None, :] + 1e-9)
    assert np.max(np.abs(dep_full - dep_ref)) > 0.05  # and the tilts drawn do matter


@pytest.mark.parametrize("seed", [0, 1])
def test_the_tilted_dipoles_elevation_is_minus_the_full_attitudes_depression(seed):
    """With each cell's body axis from the full attitude, the dipoles' UAV-side elevation is the
    float64 reference's -dep_b at that attitude (roll and pitch included), not the level one."""
    cand, cells, att, h = _random_geometry(seed)
    c = body_from_enu_matrix(att)  # u_b = C u_enu; the body's up axis is -C[2, :]
    cells.axis_enu = -c[:, 2, :]
    _, el, _, el_uav = _geometry(cand, cells, h)
    u = np.column_stack([cand, np.full(len(cand), h)])[:, None, :] - cells.enu_m[None, :, :]
    _, dep_full = body_angles(enu_to_ned(u), att[None, :, :])
    assert np.max(np.abs(el_uav.astype(float) + dep_full)) < ANGLE_TOL_RAD
    assert np.max(np.abs(el_uav - el)) > 0.05  # the tilts drawn do move it


def test_link_helpers_are_the_closed_forms_and_keep_float32():
    rng = np.random.default_rng(7)
    tx, rx = rng.uniform(-300, 300, (50, 3)), rng.uniform(-300, 300, (50, 3))
    dx, dy, dz = link_delta(tx, rx)
    assert np.allclose(horizontal_distance(dx, dy), np.linalg.norm((tx - rx)[:, :2], axis=1))
    assert np.allclose(slant_distance(dx, dy, dz), np.linalg.norm(tx - rx, axis=1))
    assert np.allclose(
        elevation(dz, horizontal_distance(dx, dy)), np.arcsin(dz / np.linalg.norm(tx - rx, axis=1))
    )
    # heading frame at yaw = 0 is the compass frame: az_b = bearing, el = -dep_b of the level body
    el, az = heading_frame_angles(dx, dy, dz, 0.0)
    az_ref, dep_ref = body_angles(enu_to_ned(tx - rx))
    assert np.allclose(_wrap(az - az_ref), 0.0, atol=1e-12) and np.allclose(
        el, -dep_ref, atol=1e-12
    )
    f32 = link_delta(tx, rx, np.float32)
    assert all(v.dtype == np.float32 for v in f32)
    assert all(v.dtype == np.float32 for v in heading_frame_angles(*f32, np.float32(0.3)))


def test_depression_sines_and_signed_azimuths_are_the_closed_forms_and_keep_float32():
    rng = np.random.default_rng(11)
    u = rng.normal(size=(400, 3)) * rng.uniform(0.1, 300.0, (400, 1))  # NED, any length
    att = rng.uniform(-0.5, 0.5, (400, 3))
    ub = body_vectors(u, att)
    r = np.linalg.norm(ub, axis=1)
    az_ref, dep_ref = body_angles(u, att)
    assert np.array_equal(depression(ub[:, 2], r), dep_ref)  # body_angles' dep_b is this function
    assert np.allclose(sin_depression(ub[:, 2], r), np.sin(dep_ref), atol=1e-12)
    # clipped, not NaN
    assert np.array_equal(sin_depression(np.array([2.0, -2.0]), 1.0), [1.0, -1.0])
    # sin el = dz / d_los: the sine of the level-frame elevation atan2(dz, d_2D)
    dx, dy, dz = u[:, 1], u[:, 0], -u[:, 2]
    assert np.allclose(
        sin_elevation(dz, slant_distance(dx, dy, dz)),
        np.sin(elevation(dz, horizontal_distance(dx, dy))),
        atol=1e-12,
    )
    # signed: (-pi, pi], the same direction as the [0, 2 pi) value and that value exactly once
    # wrapped
    for f, args in ((bearing, (dx, dy)), (body_azimuth, (ub[:, 0], ub[:, 1]))):
        s_, w = f(*args, signed=True), f(*args)
        assert np.all((s_ > -np.pi) & (s_ <= np.pi)) and np.all((w >= 0.0) & (w < 2 * np.pi))
        assert np.array_equal(np.mod(s_, 2 * np.pi), w) and s_.min() < -1.0
    f32 = [np.asarray(v, np.float32) for v in (ub[:, 0], ub[:, 1], ub[:, 2], r)]
    assert depression(f32[2], f32[3]).dtype == sin_elevation(f32[2], f32[3]).dtype == np.float32
    assert (
        bearing(f32[0], f32[1], signed=True).dtype
        == body_azimuth(f32[0], f32[1]).dtype
        == np.float32
    )


def test_gap_alignment_is_the_physics_models_own_geometry():
    """The gap's per-sample geometry and the propagation model's float64 explanation agree (one
    home)."""
    rng = np.random.default_rng(5)
    n = 300
    enu = np.column_stack([rng.uniform(-200, 200, (n, 2)), rng.uniform(10.0, 60.0, n)])
    att = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
    tx = np.array([30.0, -40.0, 1.5])
    f = FlightSamples(enu, np.zeros(n), att, np.arange(n) * 0.2, tx_enu_m=tx)
    a = align(f)
    ex = make_model("e2r").explain(tx, enu, att)
    for mine, ref in (
        (a.d_h, "d_2d"),
        (a.d_3d, "d_los"),
        (a.grazing, "grazing_rad"),
        (a.az_world, "az_tx_rad"),
        (a.elev, "el_tx_dir_rad"),
        (a.dep_b, "dep_b_rad"),
    ):
        assert np.allclose(mine, np.ravel(ex[ref]), rtol=1e-12, atol=1e-12), ref
    assert np.allclose(_wrap(a.az_b - np.ravel(ex["az_b_rad"])), 0.0, atol=1e-12)
