"""Samples binned and averaged per bin: square horizontal cells (one set per cruise altitude) or
path bins.

Why one home: the self-calibrating grid and the matched localizer average a flight into cells so
that a slow pass or a hover does not count its spot many times; the features average it into
arc-length bins for the same reason; the gap's kriging averages residuals into cells.  All are "an
integer key per sample, then the mean of each quantity per distinct key", done here with
``np.bincount`` (sums in sample order, so every caller rounds the same way).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mission.physics.geometry import body_from_enu_planes
from mission.samples import FlightSamples

# Heights further apart than this are separate cruise altitudes when cells are averaged
# (altitude_index)
ALTITUDE_GAP_M = 5.0


def bin_index(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(bin of each sample (N,), samples per bin (M,)) for integer keys (N,) or (N, k): one bin per
    distinct key (row), bins in sorted key order."""
    _, inv, cnt = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    return inv.ravel(), cnt


def bin_means(inv: np.ndarray, cnt: np.ndarray, *values: np.ndarray) -> list[np.ndarray]:
    """The mean (M,) of each value array (N,) per bin of ``bin_index``."""
    return [np.bincount(inv, v, cnt.size) / cnt for v in values]


def cell_keys(xy: np.ndarray, cell_m: float) -> np.ndarray:
    """Integer (i, j) of the ``cell_m`` square cell holding each position (N, 2) (cells from the ENU
    origin)."""
    return np.floor(xy / cell_m).astype(np.int64)


def altitude_index(z: np.ndarray, gap_m: float = ALTITUDE_GAP_M) -> np.ndarray:
    """Cruise altitude index per sample (N,): heights split wherever sorted heights leave a gap over
    ``gap_m``.

    Why: a flight surveyed at two altitudes (``preprocess.cruise_mask`` keeps both) must not average
    a cell's samples at 25 m and 45 m into one point at 35 m; one altitude (any noise within it)
    gives all zeros.
    """
    zs = np.sort(z)
    cuts = zs[1:][np.diff(zs) > gap_m]
    return np.searchsorted(cuts, z, side="right")


@dataclass
class Cells:
    """A flight averaged into horizontal cells: centres of mass (M, 3) m, mean RSS (M,) dBm, mean
    yaw (M,) rad, sample counts (M,), the cell size (m) and, where the flight has an attitude,
    the mean direction of the body's up axis (M, 3) ENU unit vectors (``axis_enu``): a tilted
    body tilts an antenna fixed to it (the self-calibrating search's dipoles)."""

    enu_m: np.ndarray
    rss_dbm: np.ndarray
    yaw_rad: np.ndarray
    count: np.ndarray
    cell_m: float
    n_columns: int | None = (
        None  # distinct horizontal cells (one flown at two altitudes counts once); None: len
    )
    axis_enu: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.rss_dbm.size)

    @property
    def area_m2(self) -> float:
        """Horizontal area the flight covered: the occupied horizontal cells times their area."""
        n = len(self) if self.n_columns is None else self.n_columns
        return n * self.cell_m * self.cell_m


def concat_cells(parts: list[Cells]) -> Cells:
    """Cells of several sample sets side by side (same cell size), in order; their horizontal
    columns are counted per set."""
    return Cells(
        np.concatenate([c.enu_m for c in parts]),
        np.concatenate([c.rss_dbm for c in parts]),
        np.concatenate([c.yaw_rad for c in parts]),
        np.concatenate([c.count for c in parts]),
        parts[0].cell_m,
        sum(len(c) if c.n_columns is None else c.n_columns for c in parts),
        None
        if any(c.axis_enu is None for c in parts)
        else np.concatenate([c.axis_enu for c in parts]),
    )


def cell_average(f: FlightSamples, cell_m: float, altitude_gap_m: float = ALTITUDE_GAP_M) -> Cells:
    """Average a flight's samples into ``cell_m`` square horizontal cells, one set per cruise
    altitude (vectorised; yaw averaged on the circle).

    Without attitude the yaw is taken as 0 (nose north) and the body's axis is unknown (None);
    ``altitude_gap_m`` = inf merges the altitudes.
    """
    xy = cell_keys(f.enu_m[:, :2], cell_m)
    inv, cnt = bin_index(np.column_stack([xy, altitude_index(f.enu_m[:, 2], altitude_gap_m)]))
    *pos, rss = bin_means(inv, cnt, f.enu_m[:, 0], f.enu_m[:, 1], f.enu_m[:, 2], f.rss_dbm)
    yaw_s = np.zeros(f.rss_dbm.size) if f.attitude_rad is None else f.attitude_rad[:, 2]
    m = cnt.size
    yaw = np.arctan2(np.bincount(inv, np.sin(yaw_s), m), np.bincount(inv, np.cos(yaw_s), m))
    axis = None
    if f.attitude_rad is not None:
        # the body's up axis in ENU: minus the FRD z row of u_b = C u_enu, averaged, renormalised
        up = -body_from_enu_planes(f.attitude_rad)[2]
        axis = np.stack(bin_means(inv, cnt, *up), axis=1)
        axis /= np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-12)
    return Cells(
        np.stack(pos, axis=1), rss, yaw, cnt, float(cell_m), len(np.unique(xy, axis=0)), axis
    )
