"""Shared synthetic flights for the localizer tests (no physics package needed)."""

from __future__ import annotations

import numpy as np

from mission.flightlog import make_meta, write_flight_log
from mission.geo import afar_field


class LogDistance:
    """RSS = P - 10 n log10(d_3d): a free-space-like field, broadcasting like mission.physics
    models."""

    name = "log-distance"

    def __init__(self, p0: float = 30.0, n: float = 2.0) -> None:
        self.p0, self.n = p0, n

    def rss_dbm(self, tx, rx, attitude=None):
        d = np.linalg.norm(np.asarray(tx)[..., :] - np.asarray(rx), axis=-1)
        return self.p0 - 10 * self.n * np.log10(np.maximum(d, 1.0))


def lawnmower_path(
    n: int = 12000,
    x0: float = 20,
    x1: float = 260,
    y0: float = 20,
    y1: float = 260,
    lanes: int = 8,
    alt: float = 30.0,
) -> np.ndarray:
    """(n, 3) ENU positions along a lawnmower pattern."""
    s = np.linspace(0, lanes, n, endpoint=False)
    lane = np.floor(s).astype(int)
    frac = s - lane
    x = np.where(lane % 2 == 0, x0 + frac * (x1 - x0), x1 - frac * (x1 - x0))
    y = y0 + (y1 - y0) * (lane + frac * 0.0) / max(lanes - 1, 1)
    return np.column_stack([x, y, np.full(n, alt)])


def synthetic_flight(
    tx=(150.0, 120.0, 1.5),
    n: int = 12000,
    seed: int = 0,
    offset: float = 0.0,
    noise: float = 1.0,
    alt: float = 30.0,
):
    """(enu, rss, attitude) of a lawnmower flight at ``alt`` m over a log-distance field with
    noise."""
    rng = np.random.default_rng(seed)
    enu = lawnmower_path(n, alt=alt)
    rss = LogDistance().rss_dbm(np.asarray(tx, dtype=float), enu) + offset + rng.normal(0, noise, n)
    att = np.zeros((n, 3))
    return enu, rss, att


def write_synthetic_log(
    path,
    tx=(150.0, 120.0, 1.5),
    n: int = 6000,
    seed: int = 0,
    truth: bool = True,
    alt: float = 30.0,
):
    """A flight log (CSV + sidecar) in the AFAR field frame at ``alt`` m, with take-off and landing
    ramps."""
    origin = afar_field().origin
    enu, rss, att = synthetic_flight(tx, n, seed, alt=alt)
    ramp = np.linspace(0, alt, 300)
    up = np.column_stack([np.full(300, enu[0, 0]), np.full(300, enu[0, 1]), ramp])
    down = np.column_stack([np.full(300, enu[-1, 0]), np.full(300, enu[-1, 1]), ramp[::-1]])
    enu = np.vstack([up, enu, down])
    rss = np.concatenate([np.full(300, rss[0]), rss, np.full(300, rss[-1])])
    lat, lon, alt = origin.to_geodetic(enu)
    m = len(enu)
    cols = {
        "t_s": np.arange(m) * 0.03,
        "lat_deg": lat,
        "lon_deg": lon,
        "alt_m": alt,
        "rel_alt_m": enu[:, 2],
        "roll_deg": np.zeros(m),
        "pitch_deg": np.zeros(m),
        "yaw_deg": np.zeros(m),
        "rss_dbm": rss,
    }
    tlat, tlon, _ = origin.to_geodetic(np.asarray(tx, dtype=float))
    tr = (
        {"lat_deg": float(tlat), "lon_deg": float(tlon), "height_m": float(tx[2])}
        if truth
        else None
    )
    meta = make_meta(origin, {"kind": "sim", "model": "log-distance", "seed": seed}, tr)
    return write_flight_log(path, cols, meta)
