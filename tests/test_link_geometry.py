"""Link geometry has one home (``mission.physics.geometry``): the self-calibrating grid's float32 fast path and
the level/heading-frame helpers agree with the float64 reference ``body_angles`` on random seeded geometry."""

from __future__ import annotations

import numpy as np
import pytest

from mission.cells import Cells
from mission.localize.selfcal import _geometry
from mission.physics.geometry import (
    body_angles,
    elevation,
    enu_to_ned,
    heading_frame_angles,
    horizontal_distance,
    link_delta,
    slant_distance,
)

# float32 keeps ~7 digits: angles of order 2 pi to about 1e-6 rad; the stated tolerances leave a margin of ~10
ANGLE_TOL_RAD = 2e-5
PATH_GAIN_TOL_DB = 1e-4


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angle difference folded into [-pi, pi)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


def _random_geometry(seed: int, k: int = 40, m: int = 300):
    """K candidate transmitters and M cells over a 400 m field (ENU offset like a real origin), random attitude."""
    rng = np.random.default_rng(seed)
    off = rng.uniform(-2000.0, 2000.0, 2)  # large coordinates: float32 must difference after the float64 one
    cand = off + rng.uniform(0.0, 400.0, (k, 2))
    enu = np.column_stack([off + rng.uniform(0.0, 400.0, (m, 2)), rng.uniform(5.0, 60.0, m)])
    att = np.column_stack([rng.uniform(-0.3, 0.3, m), rng.uniform(-0.3, 0.3, m), rng.uniform(-np.pi, np.pi, m)])
    cells = Cells(enu, np.zeros(m), att[:, 2].copy(), np.ones(m, int), 10.0)
    return cand, cells, att, float(rng.uniform(0.5, 5.0))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_selfcal_float32_geometry_matches_float64_body_angles(seed):
    cand, cells, att, h = _random_geometry(seed)
    pg, el, az = _geometry(cand, cells, h)
    assert pg.dtype == el.dtype == az.dtype == np.float32
    tx = np.column_stack([cand, np.full(len(cand), h)])
    u = tx[:, None, :] - cells.enu_m[None, :, :]  # (K, M, 3) ENU, float64
    # selfcal's frame is the heading only (antenna hanging below the body): the reference at roll = pitch = 0
    heading_only = np.column_stack([np.zeros((len(att), 2)), att[:, 2]])
    az_ref, dep_ref = body_angles(enu_to_ned(u), heading_only[None, :, :])
    assert np.max(np.abs(_wrap(az.astype(float) - az_ref))) < ANGLE_TOL_RAD
    assert np.max(np.abs(el.astype(float) + dep_ref)) < ANGLE_TOL_RAD
    d_los = np.linalg.norm(u, axis=-1)
    assert np.max(np.abs(pg.astype(float) + 20.0 * np.log10(d_los))) < PATH_GAIN_TOL_DB
    # with the full attitude the body angles move by at most the tilt: what the heading-only frame leaves out
    az_full, dep_full = body_angles(enu_to_ned(u), att[None, :, :])
    tilt = np.abs(att[:, 0]) + np.abs(att[:, 1])
    assert np.all(np.abs(dep_full - dep_ref) <= tilt[None, :] + 1e-9)
    assert np.max(np.abs(dep_full - dep_ref)) > 0.05  # and the tilts drawn do matter


def test_link_helpers_are_the_closed_forms_and_keep_float32():
    rng = np.random.default_rng(7)
    tx, rx = rng.uniform(-300, 300, (50, 3)), rng.uniform(-300, 300, (50, 3))
    dx, dy, dz = link_delta(tx, rx)
    assert np.allclose(horizontal_distance(dx, dy), np.linalg.norm((tx - rx)[:, :2], axis=1))
    assert np.allclose(slant_distance(dx, dy, dz), np.linalg.norm(tx - rx, axis=1))
    assert np.allclose(elevation(dz, horizontal_distance(dx, dy)),
                       np.arcsin(dz / np.linalg.norm(tx - rx, axis=1)))
    # heading frame at yaw = 0 is the compass frame: az_b = bearing, el = -dep_b of the level body
    el, az = heading_frame_angles(dx, dy, dz, 0.0)
    az_ref, dep_ref = body_angles(enu_to_ned(tx - rx))
    assert np.allclose(_wrap(az - az_ref), 0.0, atol=1e-12) and np.allclose(el, -dep_ref, atol=1e-12)
    f32 = link_delta(tx, rx, np.float32)
    assert all(v.dtype == np.float32 for v in f32)
    assert all(v.dtype == np.float32 for v in heading_frame_angles(*f32, np.float32(0.3)))
