"""Simulated transmitters along one flown track: the training set of the track-matched localizer.

Why: a network trained on other trajectories and altitudes pays for the difference (the paper: 16-18
m on its own spiral, 35 m across trajectories).  Here the track is the flight's own, reduced to
``cell_m`` cells (``selfcal.cell_average``: centre of mass, mean heading, sample count per cell and
cruise altitude), and many transmitters are simulated along it, each under its own draw of a physics
family (``mission.physics.family``: model spec, correlated shadowing, white noise, offset).

Per transmitter j with family draw (spec_j, sigma_j, L_j, n_j, c_j), cell m (``family.simulate_rss``
per cell)::

    P_jm = model_j(tx_j, cell_m, attitude_m) + c_j + S_jm + e_jm,
    S_j ~ N(0, sigma_j^2 rho(|x_m - x_m'|; L_j))
    e_jm ~ N(0, n_j^2 / count_m)              # white noise averaged over the cell

with ``rho`` the Gaussian correlation of ``shadowing.shadowing_field`` (1/e at L).  The field is
drawn from a square-root factor of the cells' correlation (``FieldBasis``), not from
``shadowing_field``'s smoothed grid: one factor serves every transmitter whose correlation length
rounds to it, where the grid would be made per transmitter (20 000 times).  Transmitters share a
model spec in groups of ``group`` (the model build and its geometry are the costly part); every
transmitter has its own field, noise and offset.  The learned input is offset-free: ``centred``
subtracts each vector's mean.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from mission.errors import InputError
from mission.localize.selfcal import ALTITUDE_GAP_M, cell_average
from mission.physics.family import PhysicsFamily, draw_value
from mission.physics.shadowing import correlation, pdist
from mission.samples import FlightSamples

Progress = Callable[[str, int, int], None]


@dataclass
class TrackCells:
    """A flown track in cells: positions (M, 3) m, attitude (M, 3) rad (roll, pitch, yaw), sample
    counts (M,), measured mean RSS per cell (M,) dBm and the cell size."""

    enu_m: np.ndarray
    attitude_rad: np.ndarray
    count: np.ndarray
    rss_dbm: np.ndarray
    cell_m: float

    def __len__(self) -> int:
        return int(self.count.size)


def track_cells(
    f: FlightSamples, cell_m: float, altitude_gap_m: float = ALTITUDE_GAP_M
) -> TrackCells:
    """The flight averaged into cells (``selfcal.cell_average``; roll and pitch averaged the same
    way)."""
    cells = cell_average(f, cell_m, altitude_gap_m)
    roll = pitch = np.zeros(len(cells))
    # same cells, same order: average the angles as if they were the RSS
    if f.attitude_rad is not None:
        roll = cell_average(
            replace(f, rss_dbm=f.attitude_rad[:, 0]), cell_m, altitude_gap_m
        ).rss_dbm
        pitch = cell_average(
            replace(f, rss_dbm=f.attitude_rad[:, 1]), cell_m, altitude_gap_m
        ).rss_dbm
    att = np.column_stack([roll, pitch, cells.yaw_rad])
    return TrackCells(cells.enu_m, att, cells.count.astype(float), cells.rss_dbm, float(cell_m))


def centred(rss: np.ndarray) -> np.ndarray:
    """RSS vectors minus their own mean (last axis): what is left after an unknown receiver
    offset."""
    r = np.asarray(rss, dtype=np.float64)
    return r - r.mean(axis=-1, keepdims=True)


CORR_RATIO = (
    1.06  # correlation lengths are rounded to a geometric grid of this ratio (one factor each)
)


class FieldBasis:
    """Square-root factors of the cells' unit-variance Gaussian shadowing correlation, one per
    correlation length rounded to the ``CORR_RATIO`` grid (at most 3 % off), made once per length
    and flight.

    Factor: the eigenvectors times sqrt(eigenvalue), eigenvalues under 1e-7 of the largest dropped
    (the smooth Gaussian correlation has few that matter), so a field of k transmitters costs one
    (M, r) x (r, k) product.
    """

    def __init__(self, xy: np.ndarray) -> None:
        self.dist = pdist(xy, xy)
        self._factors: dict[int, np.ndarray] = {}

    def factor(self, corr_m: float) -> np.ndarray:
        i = int(round(np.log(max(corr_m, 0.1)) / np.log(CORR_RATIO)))
        if i not in self._factors:
            vals, vecs = np.linalg.eigh(correlation(self.dist, CORR_RATIO**i, "gaussian"))
            keep = vals > 1e-7 * vals[-1]
            self._factors[i] = vecs[:, keep] * np.sqrt(vals[keep])
        return self._factors[i]


def simulate_track(
    track: TrackCells,
    family: PhysicsFamily,
    tx_xy: np.ndarray,
    tx_height_m: float,
    rng: np.random.Generator,
    group: int = 64,
    progress: Progress | None = None,
) -> np.ndarray:
    """Cell RSS (N, M) float32 of N transmitters ``tx_xy`` (N, 2) along ``track`` (module
    docstring)."""
    tx_xy = np.asarray(tx_xy, dtype=float)
    n, m = len(tx_xy), len(track)
    out = np.empty((n, m), dtype=np.float32)
    basis = FieldBasis(track.enu_m[:, :2])
    inv_sqrt_count = 1.0 / np.sqrt(np.maximum(track.count, 1.0))
    tx = np.column_stack([tx_xy, np.full(n, float(tx_height_m))])[:, None, :]
    for g0 in range(0, n, group):
        g1 = min(n, g0 + group)
        k = g1 - g0
        d = family.draw(rng)
        rss = np.asarray(
            d.model().rss_dbm(tx[g0:g1], track.enu_m, track.attitude_rad), dtype=np.float64
        )
        rss += np.array(
            [d.offset_db] + [float(draw_value(family.offset_db, rng)) for _ in range(k - 1)]
        )[:, None]
        if d.shadowing_db > 0:
            fac = basis.factor(d.shadowing_corr_m)
            rss += d.shadowing_db * (fac @ rng.standard_normal((fac.shape[1], k))).T
        rss += d.noise_db * rng.standard_normal((k, m)) * inv_sqrt_count[None, :]
        out[g0:g1] = rss
        if progress is not None:
            progress("simulating transmitters", g1, n)
    return out


def draw_transmitters(
    area, box: tuple[float, float, float, float], n: int, rng: np.random.Generator
) -> np.ndarray:
    """``n`` transmitter positions uniform over the prior: the ``area`` polygon when given, else
    ``box``."""
    if area is not None:
        return area.sample_uniform(n, rng)
    x0, y0, x1, y1 = box
    if not (x1 > x0 and y1 > y0):
        raise InputError(f"empty transmitter area {box}", field="area")
    return rng.uniform([x0, y0], [x1, y1], size=(n, 2))
