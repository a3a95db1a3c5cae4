"""Per-flight evidence over candidates: blocked cross-validated predictive densities and stacking
weights.

Why: which candidate a flight supports must come from the flight's own RSS, scored on parts of the
track the fit did not see, or the candidate that was fitted to the same samples always wins.  The
flight is averaged into cells (``mission.cells``); the cells are grouped into square blocks of
``block_m`` (longer than the shadowing correlation, so it does not leak between blocks: blocked
cross-validation, Roberts et al. 2017).  With the transmitter fixed at candidate k, the per-flight
nuisance is fitted on all blocks but one and the held-out block's cells are scored::

    P_m = c + b * PG_km + G_h(el_km, az_km) + e_m,  PG = -20 log10 d    # free space, UAV antenna h
    (c, b) by ridge least squares (b shrunk to 1 with weight lam),  h = argmin training SSR
    lpd_km = log N(P_m - c - b PG_km - G_h; 0, s^2),  s^2 = training SSR / (n - 2)

A block's log density is its cells' sum tempered to the block's independent cells (``tau``, as
``selfcal``); the stacking weights maximise the held-out blocks' mixture density (Yao, Vehtari,
Simpson and Gelman 2018: stacking of predictive distributions), found by EM on the simplex.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from mission.cells import Cells
from mission.localize.selfcal import _geometry, hypothesis_residuals
from mission.localize.uncertainty import grid_posterior

# block side: above the real flights' shadowing correlation (35 m, mission/data/afar_family.json)
BLOCK_M = 50.0
SLOPE_WEIGHT = (
    200.0  # ridge weight pulling the path-gain slope to free space (cells' PG spread ~ 10 dB)
)


@dataclass(frozen=True)
class BlockedScores:
    """Held-out log densities: ``cell_lpd`` (K, M) per cell, ``block_lpd`` (K, B) per block
    (tempered), the block of each cell (M,), and the temperature ``tau``."""

    cell_lpd: np.ndarray
    block_lpd: np.ndarray
    block: np.ndarray
    tau: float

    @property
    def evidence(self) -> np.ndarray:
        """(K,) summed tempered held-out log density, relative to the best candidate (0 for it)."""
        e = self.block_lpd.sum(axis=1)
        return e - e.max()


def cell_blocks(cells: Cells, block_m: float) -> np.ndarray:
    """(M,) block index of each cell: squares of ``block_m`` in the horizontal plane, numbered
    0..B-1."""
    key = np.floor(cells.enu_m[:, :2] / float(block_m)).astype(np.int64)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    return inv.ravel()


def blocked_scores(
    cells: Cells,
    cand_xy: np.ndarray,
    hyps,
    tx_height_m: float,
    tau: float,
    block_m: float = BLOCK_M,
    slope_weight: float = SLOPE_WEIGHT,
    block: np.ndarray | None = None,
) -> BlockedScores:
    """Blocked cross-validated predictive log densities of every candidate (module docstring),
    vectorised over candidates, blocks and cells; one pass per antenna hypothesis.  ``block``: each
    cell's block 0..B-1 when the caller defines them (e.g. survey and rounds), else squares of
    ``block_m``."""

    block = cell_blocks(cells, block_m) if block is None else np.asarray(block, dtype=np.intp)
    nb = int(block.max()) + 1
    if nb < 2:
        raise ValueError("the flight covers one block: nothing to hold out")
    onehot = np.zeros((len(block), nb))
    onehot[np.arange(len(block)), block] = 1.0
    pg, el, az, el_uav = _geometry(np.asarray(cand_xy, float), cells, tx_height_m)
    pg = pg.astype(np.float64)
    y = cells.rss_dbm.astype(np.float64)
    n = len(block) - onehot.sum(axis=0)  # training cells per fold (B,)

    # (K, M) -> sums over the training cells of each fold (K, B)
    def train(
        v: np.ndarray,
    ) -> np.ndarray:
        s = v @ onehot
        return s.sum(axis=1, keepdims=True) - s

    sp, spp = train(pg), train(pg * pg)
    best_lpd = best_ssr = None
    for g in hypothesis_residuals(
        np.broadcast_to(y, pg.shape), el, az, hyps, el_uav=el_uav
    ):  # y - G_h
        r = np.asarray(g, np.float64)
        sr, srr, srp = train(r), train(r * r), train(r * pg)
        a22 = spp + slope_weight
        det = n * a22 - sp * sp
        c = (a22 * sr - sp * (srp + slope_weight)) / det
        b = (n * (srp + slope_weight) - sp * sr) / det
        ssr = srr - 2 * c * sr - 2 * b * srp + c * c * n + 2 * c * b * sp + b * b * spp
        s2 = np.maximum(ssr / np.maximum(n - 2, 1), 1e-6)
        e = r - c[:, block] - b[:, block] * pg
        lpd = -0.5 * np.log(2 * np.pi * s2[:, block]) - 0.5 * e * e / s2[:, block]
        if best_lpd is None:
            best_lpd, best_ssr = lpd, ssr
        else:
            better = ssr < best_ssr
            best_lpd = np.where(better[:, block], lpd, best_lpd)
            best_ssr = np.where(better, ssr, best_ssr)
    assert best_lpd is not None
    return BlockedScores(best_lpd, float(tau) * (best_lpd @ onehot), block, float(tau))


def stacking_weights(block_lpd: np.ndarray, iters: int = 500, tol: float = 1e-10) -> np.ndarray:
    """(K,) weights on the simplex maximising ``sum_b log sum_k w_k exp(block_lpd[k, b])`` (EM: each
    step cannot lower the objective; uniform start, so candidates with identical scores share
    equally)."""
    lp = np.asarray(block_lpd, float)
    k = lp.shape[0]
    w = np.full(k, 1.0 / k)
    for _ in range(iters):
        lq = np.log(np.maximum(w, 1e-300))[:, None] + lp
        q = np.exp(lq - logsumexp(lq, axis=0, keepdims=True))
        w_new = q.mean(axis=1)
        if np.abs(w_new - w).max() < tol:
            return w_new
        w = w_new
    return w


def geometric_median(
    xy: np.ndarray, weights: np.ndarray | None = None, iters: int = 200, tol_m: float = 1e-6
) -> np.ndarray:
    """The (weighted) geometric median of points (K, 2): the point with the least summed distance to
    them (Weiszfeld's iteration from the weighted mean).  Why: a consensus that a few far candidates
    (ghost modes, a network off its domain) cannot drag, unlike the mean."""
    xy = np.asarray(xy, float)
    w = np.ones(len(xy)) if weights is None else np.asarray(weights, float)
    z = (xy * w[:, None]).sum(axis=0) / w.sum()
    for _ in range(iters):
        d = np.maximum(np.hypot(*(xy - z).T), 1e-9)
        z_new = (xy * (w / d)[:, None]).sum(axis=0) / (w / d).sum()
        if np.hypot(*(z_new - z)) < tol_m:
            return z_new
        z = z_new
    return z


def spread_m(xy: np.ndarray) -> float:
    """How far points (K, 2) disagree: the median distance to their geometric median (m).  A
    flight whose candidates disagree is the flight where all of them may be wrong."""
    xy = np.asarray(xy, float)
    return float(np.median(np.hypot(*(xy - geometric_median(xy)).T)))


def mixture_posterior(
    cand_xy: np.ndarray,
    weights: np.ndarray,
    grid: np.ndarray,
    sigma_m: float,
    background: float = 0.0,
):
    """The candidates' mixture as a grid posterior: isotropic Gaussians of ``sigma_m`` about each
    candidate, weighted by stacking; two surviving candidates far apart give two islands.  With
    ``background`` > 0 that share of the mass is spread evenly over the grid: the hypothesis that
    every candidate is wrong, which on about a tenth of the benchmark's flights is the truth and no
    mixture of candidates covers."""
    pts = grid.reshape(-1, 2)
    d2 = ((pts[None, :, :] - np.asarray(cand_xy, float)[:, None, :]) ** 2).sum(-1)  # (K, G)
    w = np.asarray(weights, float)
    if background > 0:
        w = (1.0 - background) * w / max(w.sum(), 1e-300)
    logp = np.log(np.maximum(w, 1e-300))[:, None] - 0.5 * d2 / sigma_m**2
    if background > 0:  # densities per m^2: each Gaussian's, the background's over the grid
        step = float(np.hypot(*(grid[0, 1] - grid[0, 0]))) if grid.shape[1] > 1 else 1.0
        flat = np.log(background) - np.log(pts.shape[0] * step**2)
        logp = np.vstack([logp - np.log(2 * np.pi * sigma_m**2), np.full((1, len(pts)), flat)])
    post = grid_posterior(logsumexp(logp, axis=0), grid.shape[:2])
    post.grid = grid
    return post
