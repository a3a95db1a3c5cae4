"""Spatially correlated shadowing as a gap candidate: kriging of training residuals (a generic smoother).

Why here and not in ``mission.physics.shadowing``: kriging is a *predictor* fitted on a flight's residuals
around its own transmitter (it cannot be used to localize an unknown one); the covariance model it uses and
the random fields of the self-test are the physics module's (``COVARIANCE`` = exponential, Gudmundson's
model of measured shadowing).  In the ranking it is a *smoother* (``mission.gap.fit.TIERS``): it absorbs any
smooth misfit, so it must beat the explanations by a stated margin to come first.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mission.gap.candidate import TIER_SMOOTHER, Candidate
from mission.gap.pipeline import Pipeline
from mission.physics.shadowing import correlation, pdist
from mission.samples import FlightSamples

COVARIANCE = "exponential"


def tx_key(tx: np.ndarray) -> tuple[float, float]:
    """Flights share a shadowing field when their transmitters are within ~2 m."""
    return (round(float(tx[0]) / 2.0), round(float(tx[1]) / 2.0))


@dataclass(frozen=True, eq=False)
class KrigedShadowing:
    """Fitted spatial shadowing: simple kriging (exponential covariance + nugget) of training residuals.

    Training residuals are averaged in square cells of ``cell_m`` first (the samples of one pass are not
    independent anyway); one set of points per transmitter position (``tx_key``).
    """

    sigma_db: float
    corr_len_m: float
    nugget_db: float
    points: dict[tuple[float, float], tuple[np.ndarray, np.ndarray, np.ndarray]]  # key -> (xy, mean, count)

    def field_db(self, flight: FlightSamples, rx_xy: np.ndarray) -> np.ndarray:
        key = tx_key(flight.tx_enu_m)
        pts = self.points.get(key)
        if pts is None or self.sigma_db <= 0:
            return np.zeros(len(rx_xy))
        return _memo(self, rx_xy, lambda: self._predict(key, rx_xy), extra=key)

    def _predict(self, key: tuple[float, float], rx_xy: np.ndarray) -> np.ndarray:
        xy, r, cnt = self.points[key]
        s2, n2 = self.sigma_db ** 2, self.nugget_db ** 2
        alphas: dict = self.__dict__.setdefault("_alpha", {})  # one solve per transmitter, not per query
        if key not in alphas:
            K = s2 * correlation(pdist(xy, xy), self.corr_len_m, COVARIANCE)
            K += np.diag(n2 / np.minimum(cnt, 20.0) + 1e-6 * s2)
            alphas[key] = np.linalg.solve(K, r)
        alpha = alphas[key]
        out = np.empty(len(rx_xy))
        for s in range(0, len(rx_xy), 4096):
            k = s2 * correlation(pdist(rx_xy[s: s + 4096], xy), self.corr_len_m, COVARIANCE)
            out[s: s + 4096] = k @ alpha
        return out


def _memo(obj: object, xy: np.ndarray, compute: Callable[[], np.ndarray], extra: object = None) -> np.ndarray:
    """Per-object cache of field values by the query positions (fits evaluate the same samples many times)."""
    cache: dict = obj.__dict__.setdefault("_cache", {})
    key = (extra, xy.shape, hash(np.ascontiguousarray(xy).tobytes()))
    if key not in cache:
        if len(cache) > 64:
            cache.clear()
        cache[key] = compute()
    return cache[key]


def cell_means(xy: np.ndarray, r: np.ndarray, cell_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Average residuals in square cells: (cell centroid xy, mean residual, count)."""
    ij = np.floor(xy / cell_m).astype(np.int64)
    _, inv, cnt = np.unique(ij, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    sx = np.bincount(inv, weights=xy[:, 0]) / cnt
    sy = np.bincount(inv, weights=xy[:, 1]) / cnt
    m = np.bincount(inv, weights=r) / cnt
    return np.column_stack([sx, sy]), m, cnt.astype(float)


KRIGING_CELL_M = 5.0
MAX_CELLS = 300  # per transmitter position; cells grow beyond this (many or long flights)
KRIGING_LENGTHS_M = (10.0, 20.0, 35.0, 60.0, 100.0, 170.0)
KRIGING_NUGGET_FRACTIONS = (0.1, 0.3, 0.6)


def _group_cells(flights: Sequence[FlightSamples], idx: Sequence[np.ndarray], resid: Sequence[np.ndarray],
                 cell_m: float) -> dict[tuple[float, float], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    groups: dict[tuple[float, float], list[tuple[np.ndarray, np.ndarray]]] = {}
    for f, i, rr in zip(flights, idx, resid, strict=True):
        if len(i):
            groups.setdefault(tx_key(f.tx_enu_m), []).append((f.enu_m[i, :2], rr))
    out = {}
    for k, v in groups.items():
        xy, r = np.concatenate([a for a, _ in v]), np.concatenate([b for _, b in v])
        pts = cell_means(xy, r, cell_m)
        if len(pts[1]) > MAX_CELLS:  # coarser cells: the kriging solve is cubic in the number of cells
            pts = cell_means(xy, r, cell_m * float(np.sqrt(len(pts[1]) / MAX_CELLS)) * 1.05)
        out[k] = pts
    return out


def choose_kriging(flights: Sequence[FlightSamples], idx: Sequence[np.ndarray], resid: Sequence[np.ndarray],
                   period_s: float = 30.0) -> tuple[float, float, float]:
    """(sigma_db, corr_len_m, nugget_db) by inner two-fold cross-validation on the training samples.

    The training samples are split again into alternating ``period_s`` stretches of flight; each grid point
    (correlation length x nugget fraction, sigma^2 + nugget^2 = residual variance) krigs one half from the
    other; the pair with the smallest prediction error wins.  Chosen this way because the variogram of a
    30 Hz track is dominated by along-track pairs and underestimates the across-track correlation length.
    """
    r_all = np.concatenate(list(resid)) if resid else np.zeros(0)
    var = float(np.var(r_all)) if r_all.size else 0.0
    halves = []
    for f, i in zip(flights, idx, strict=True):
        h = (np.floor(f.t_s[i] / period_s).astype(int) % 2) if len(i) else np.zeros(0, int)
        halves.append(h)
    best = (np.inf, 0.0, 30.0, float(np.sqrt(var)))
    for L in KRIGING_LENGTHS_M:
        for frac in KRIGING_NUGGET_FRACTIONS:
            s, n = float(np.sqrt(var * (1 - frac))), float(np.sqrt(var * frac))
            err, cnt = 0.0, 0
            for a in (0, 1):
                tr = [i[h != a] for i, h in zip(idx, halves, strict=True)]
                rt = [r[h != a] for r, h in zip(resid, halves, strict=True)]
                kr = KrigedShadowing(s, L, n, _group_cells(flights, tr, rt, KRIGING_CELL_M))
                for f, i, r, h in zip(flights, idx, resid, halves, strict=True):
                    te = h == a
                    if te.any():
                        pred = kr.field_db(f, f.enu_m[i[te], :2])
                        d = r[te] - r[te].mean() - (pred - pred.mean())
                        err += float(np.sum(d * d))
                        cnt += int(te.sum())
            mse = err / max(cnt, 1)
            if mse < best[0]:
                best = (mse, s, L, n)
    return best[1], best[2], best[3]


def spatial_candidate() -> Candidate:
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:  # only via direct_fit
        return p

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(spatial=None)

    def direct_fit(p: Pipeline, flights: Sequence[FlightSamples], idx: Sequence[np.ndarray],
                   resid: Sequence[np.ndarray],
                   rng: np.random.Generator, cfg: Any = None) -> tuple[Pipeline, dict[str, Any]]:
        sigma, L, nug = choose_kriging(flights, idx, resid)
        pts = _group_cells(flights, idx, resid, KRIGING_CELL_M)
        field_ = KrigedShadowing(sigma, L, nug, pts)
        return p.replace(spatial=field_), {"sigma_db": sigma, "corr_len_m": L, "nugget_db": nug}

    return Candidate("spatial_shadowing", "spatially correlated shadowing (kriging of training residuals)", (),
                     build, lambda p: p.spatial is None, withhold, direct_fit=direct_fit, tier=TIER_SMOOTHER)


