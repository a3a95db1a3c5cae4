"""Spatially correlated shadowing as gap candidates: kriging of training residuals and a site map
(smoothers).

Why here and not in ``mission.physics.shadowing``: kriging is a *predictor* fitted on a flight's
residuals around its own transmitter (it cannot be used to localize an unknown one); the covariance
model it uses and the random fields of the self-test are the physics module's (``COVARIANCE`` =
exponential, Gudmundson's model of measured shadowing).  In the ranking it is a *smoother*
(``mission.gap.fit.TIERS``): it absorbs any smooth misfit, so it must beat the explanations by a
stated margin to come first.

``site_map`` is the site-specific version for flights that share a transmitter position (the same
rover location flown by several teams): a smooth map over the compass azimuth of the UAV seen from
the transmitter x log horizontal distance, one per transmitter position (``tx_key``), fitted on the
training flights there. Held out by flight, it carries what the *environment around the transmitter*
does (a building blocking a sector, trees at some range) from one flight to another; a transmitter
with no training flight gets no map.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from mission.cells import bin_index, bin_means, cell_keys
from mission.gap.candidate import TIER_SMOOTHER, Candidate
from mission.gap.freeform import (
    fourier_legendre_columns,
    fourier_legendre_orders,
    ridge_cv,
    ridge_penalty,
)
from mission.gap.pipeline import Pipeline, memo
from mission.gap.temporal import NAME, usable_in
from mission.physics.family import log_distance_unit
from mission.physics.geometry import bearing, horizontal_distance
from mission.physics.shadowing import correlation, pdist
from mission.samples import FlightSamples

COVARIANCE = "exponential"


def tx_key(tx: np.ndarray) -> tuple[float, float]:
    """Flights share a shadowing field when their transmitters are within ~2 m."""
    return (round(float(tx[0]) / 2.0), round(float(tx[1]) / 2.0))


@dataclass(frozen=True, eq=False)
class KrigedShadowing:
    """Fitted spatial shadowing: simple kriging (exponential covariance + nugget) of training
    residuals.

    Training residuals are averaged in square cells of ``cell_m`` first (the samples of one pass are
    not independent anyway); one set of points per transmitter position (``tx_key``).
    """

    sigma_db: float
    corr_len_m: float
    nugget_db: float
    # key -> (xy, mean, count)
    points: dict[tuple[float, float], tuple[np.ndarray, np.ndarray, np.ndarray]]

    def field_db(self, flight: FlightSamples, rx_xy: np.ndarray) -> np.ndarray:
        key = tx_key(flight.tx_enu_m)
        pts = self.points.get(key)
        if pts is None or self.sigma_db <= 0:
            return np.zeros(len(rx_xy))
        return memo(self, (rx_xy,), lambda: self._predict(key, rx_xy), extra=key)

    def _predict(self, key: tuple[float, float], rx_xy: np.ndarray) -> np.ndarray:
        xy, r, cnt = self.points[key]
        s2, n2 = self.sigma_db**2, self.nugget_db**2
        # one solve per transmitter, not per query
        alphas: dict = self.__dict__.setdefault("_alpha", {})
        if key not in alphas:
            K = s2 * correlation(pdist(xy, xy), self.corr_len_m, COVARIANCE)
            K += np.diag(n2 / np.minimum(cnt, 20.0) + 1e-6 * s2)
            alphas[key] = np.linalg.solve(K, r)
        alpha = alphas[key]
        out = np.empty(len(rx_xy))
        for s in range(0, len(rx_xy), 4096):
            k = s2 * correlation(pdist(rx_xy[s : s + 4096], xy), self.corr_len_m, COVARIANCE)
            out[s : s + 4096] = k @ alpha
        return out


def cell_means(
    xy: np.ndarray, r: np.ndarray, cell_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Average residuals in square cells: (cell centroid xy, mean residual, count)."""
    inv, cnt = bin_index(cell_keys(xy, cell_m))
    sx, sy, m = bin_means(inv, cnt, xy[:, 0], xy[:, 1], r)
    return np.column_stack([sx, sy]), m, cnt.astype(float)


KRIGING_CELL_M = 5.0
MAX_CELLS = 300  # per transmitter position; cells grow beyond this (many or long flights)
KRIGING_LENGTHS_M = (10.0, 20.0, 35.0, 60.0, 100.0, 170.0)
KRIGING_NUGGET_FRACTIONS = (0.1, 0.3, 0.6)


def _group_cells(
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    resid: Sequence[np.ndarray],
    cell_m: float,
) -> dict[tuple[float, float], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    groups: dict[tuple[float, float], list[tuple[np.ndarray, np.ndarray]]] = {}
    for f, i, rr in zip(flights, idx, resid, strict=True):
        if len(i):
            groups.setdefault(tx_key(f.tx_enu_m), []).append((f.enu_m[i, :2], rr))
    out = {}
    for k, v in groups.items():
        xy, r = np.concatenate([a for a, _ in v]), np.concatenate([b for _, b in v])
        pts = cell_means(xy, r, cell_m)
        # coarser cells: the kriging solve is cubic in the number of cells
        if len(pts[1]) > MAX_CELLS:
            pts = cell_means(xy, r, cell_m * float(np.sqrt(len(pts[1]) / MAX_CELLS)) * 1.05)
        out[k] = pts
    return out


def choose_kriging(
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    resid: Sequence[np.ndarray],
    period_s: float = 30.0,
) -> tuple[float, float, float]:
    """(sigma_db, corr_len_m, nugget_db) by inner two-fold cross-validation on the training samples.

    The training samples are split again into alternating ``period_s`` stretches of flight; each
    grid point (correlation length x nugget fraction, sigma^2 + nugget^2 = residual variance) krigs
    one half from the other (``KrigedShadowing``'s predictor); the pair with the smallest prediction
    error wins.  Chosen this way because the variogram of a 30 Hz track is dominated by along-track
    pairs and underestimates the across-track correlation length.  The cells and distances of each
    half are computed once for the whole grid, the correlations once per length, and each system is
    solved by Cholesky (it is a covariance).
    """
    r_all = np.concatenate(list(resid)) if resid else np.zeros(0)
    var = float(np.var(r_all)) if r_all.size else 0.0
    halves = []
    for f, i in zip(flights, idx, strict=True):
        h = (np.floor(f.t_s[i] / period_s).astype(int) % 2) if len(i) else np.zeros(0, int)
        halves.append(h)
    # per half: cells per transmitter (xy distances, mean, count) and the test samples against them
    parts = []
    for a in (0, 1):
        tr = [i[h != a] for i, h in zip(idx, halves, strict=True)]
        rt = [r[h != a] for r, h in zip(resid, halves, strict=True)]
        grouped = _group_cells(flights, tr, rt, KRIGING_CELL_M)
        cells = {k: (pdist(xy, xy), m, cnt) for k, (xy, m, cnt) in grouped.items()}
        tests = []
        for f, i, r, h in zip(flights, idx, resid, halves, strict=True):
            te = h == a
            if te.any():
                key = tx_key(f.tx_enu_m)
                d = pdist(f.enu_m[i[te], :2], grouped[key][0]) if key in grouped else None
                tests.append((key, r[te] - r[te].mean(), d))
        parts.append((cells, tests))
    best = (np.inf, 0.0, 30.0, float(np.sqrt(var)))
    for L in KRIGING_LENGTHS_M:
        corr = [
            (
                {k: correlation(D, L, COVARIANCE) for k, (D, _, _) in cells.items()},
                [None if d is None else correlation(d, L, COVARIANCE) for _, _, d in tests],
            )
            for cells, tests in parts
        ]
        for frac in KRIGING_NUGGET_FRACTIONS:
            s2, n2 = var * (1 - frac), var * frac
            err, cnt = 0.0, 0
            for (cells, tests), (ck, cx) in zip(parts, corr, strict=True):
                alpha = {}
                if s2 > 0:
                    for k, (_, m, c) in cells.items():
                        K = s2 * ck[k] + np.diag(n2 / np.minimum(c, 20.0) + 1e-6 * s2)
                        alpha[k] = cho_solve(
                            cho_factor(K, lower=True, check_finite=False), m, check_finite=False
                        )
                for (key, r0, _), x in zip(tests, cx, strict=True):
                    pred = (
                        s2 * (x @ alpha[key])
                        if x is not None and key in alpha
                        else np.zeros(len(r0))
                    )
                    d = r0 - (pred - pred.mean())
                    err += float(np.sum(d * d))
                    cnt += len(d)
            mse = err / max(cnt, 1)
            if mse < best[0]:
                best = (mse, float(np.sqrt(s2)), L, float(np.sqrt(n2)))
    return best[1], best[2], best[3]


SITE_M, SITE_P = 8, 2  # Fourier order in azimuth, Legendre order in log distance
SITE_LAMBDAS = tuple(np.geomspace(1e-4, 1e1, 11))


def site_variables(tx: np.ndarray, rx_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(compass azimuth of the UAV from the transmitter (rad), log distance scaled to [-1, 1] over
    10-500 m)."""
    d = rx_xy - np.asarray(tx, dtype=float)[None, :2]
    az = bearing(d[:, 0], d[:, 1], signed=True)
    return az, log_distance_unit(horizontal_distance(d[:, 0], d[:, 1]))


def site_design(az: np.ndarray, ld: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Design matrix (N, K) Fourier(az, SITE_M) x Legendre(ld, SITE_P), no constant, and its ridge
    penalty: the free-form maps' basis (``freeform.fourier_legendre_columns``) over the site
    variables."""
    return (
        np.column_stack(fourier_legendre_columns(az, ld, SITE_M, SITE_P)),
        ridge_penalty(fourier_legendre_orders(SITE_M, SITE_P)),
    )


@dataclass(frozen=True, eq=False)
class SiteMap:
    """Fitted site-specific shadowing: per transmitter position, ridge coefficients of
    ``site_design``."""

    coef: dict[tuple[float, float], np.ndarray]
    lam: float
    name: str = "site_map"

    def field_db(self, flight: FlightSamples, rx_xy: np.ndarray) -> np.ndarray:
        c = self.coef.get(tx_key(flight.tx_enu_m))
        if c is None:
            return np.zeros(len(rx_xy))
        return site_design(*site_variables(flight.tx_enu_m, rx_xy))[0] @ c


def fit_site_map(
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    resid: Sequence[np.ndarray],
    loss: str = "l2",
    f_scale_db: float = 6.0,
    period_s: float = 30.0,
) -> tuple[SiteMap, dict[str, Any]]:
    """Per transmitter position, a weighted ridge fit of the offset-free training residuals (centred
    per flight, soft-L1 IRLS weights for a robust loss); lambda by inner two-fold CV over alternate
    ``period_s`` stretches of flight, pooled over the positions."""
    groups: dict[
        tuple[float, float], list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
    ] = {}
    pen = site_design(np.zeros(1), np.zeros(1))[1]
    for f, i, r in zip(flights, idx, resid, strict=True):
        if len(i) < 10:
            continue
        X = site_design(*site_variables(f.tx_enu_m, f.enu_m[i, :2]))[0]
        r = np.asarray(r, dtype=float)
        w = np.ones(len(r)) if loss == "l2" else 1.0 / np.sqrt(1.0 + (r / f_scale_db) ** 2)
        half = np.floor(f.t_s[i] / period_s).astype(int) % 2
        groups.setdefault(tx_key(f.tx_enu_m), []).append((X, r, w, half))
    # one ridge fit per transmitter position, one lambda for all (CV errors pooled over the
    # positions)
    fits = {
        key: ridge_cv(*(list(col) for col in zip(*parts, strict=True)), pen, SITE_LAMBDAS, min_n=5)
        for key, parts in groups.items()
    }
    errs = np.sum([e for e, _ in fits.values()], axis=0) if fits else np.zeros(len(SITE_LAMBDAS))
    lam = float(SITE_LAMBDAS[int(np.argmin(errs))])
    coef = {key: fit_all(lam) for key, (_, fit_all) in fits.items()}
    sm = SiteMap(coef, lam)
    sizes = []
    for key, parts in groups.items():
        v = np.concatenate([X @ coef[key] for X, _, _, _ in parts])
        sizes.append(float(np.quantile(v, 0.95) - np.quantile(v, 0.05)))
    return sm, {
        "lambda": lam,
        "sites": len(coef),
        "size_db": float(np.mean(sizes)) if sizes else 0.0,
    }


def _smoother(
    name: str,
    description: str,
    fit: Callable[
        [Sequence[FlightSamples], Sequence[np.ndarray], Sequence[np.ndarray], Any],
        tuple[Any, dict[str, Any]],
    ],
) -> Candidate:
    """A smoother candidate: ``fit(flights, idx, resid, cfg) -> (field, params)`` fills the
    pipeline's spatial slot (fitted directly on the training residuals, no parameter search);
    withholding it empties the slot."""

    # only via direct_fit
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        return p

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(spatial=None)

    def direct_fit(
        p: Pipeline,
        flights: Sequence[FlightSamples],
        idx: Sequence[np.ndarray],
        resid: Sequence[np.ndarray],
        rng: np.random.Generator,
        cfg: Any = None,
    ) -> tuple[Pipeline, dict[str, Any]]:
        field_, params = fit(flights, idx, resid, cfg)
        return p.replace(spatial=field_), params

    return Candidate(
        name,
        description,
        (),
        build,
        lambda p: p.spatial is None,
        withhold,
        direct_fit=direct_fit,
        tier=TIER_SMOOTHER,
    )


def site_map_candidate() -> Candidate:
    return _smoother(
        "site_map",
        "site-specific shadowing map around each transmitter position (compass azimuth x "
        "log distance), learned from the training flights there",
        lambda fl, idx, r, cfg: fit_site_map(
            fl, idx, r, getattr(cfg, "loss", "l2"), getattr(cfg, "f_scale_db", 6.0)
        ),
    )


def shares_site(flights: Sequence[Any]) -> bool:
    """Whether at least two flights share a transmitter position (``tx_key``): only then can
    ``site_map`` carry anything from one flight to another (alone, it is one more smoother beside
    kriging)."""
    keys = [tx_key(f.tx_enu_m) for f in flights]
    return len(set(keys)) < len(keys)


def usable_candidates(
    candidates: Sequence[Candidate], flights: Sequence[Any], split: str = "blocks"
) -> list[Candidate]:
    """``candidates`` without ``site_map`` when no two flights share a transmitter position, and
    without the per-flight ``time_drift`` when whole flights are held out or a flight has no times
    (``temporal.usable_in``)."""
    return [
        c
        for c in candidates
        if (c.name != "site_map" or shares_site(flights))
        and (c.name != NAME or usable_in(split, flights))
    ]


def _kriging_fit(
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    resid: Sequence[np.ndarray],
    cfg: Any = None,
) -> tuple[KrigedShadowing, dict[str, Any]]:
    sigma, L, nug = choose_kriging(flights, idx, resid)
    field_ = KrigedShadowing(sigma, L, nug, _group_cells(flights, idx, resid, KRIGING_CELL_M))
    return field_, {"sigma_db": sigma, "corr_len_m": L, "nugget_db": nug}


def spatial_candidate() -> Candidate:
    return _smoother(
        "spatial_shadowing",
        "spatially correlated shadowing (kriging of training residuals)",
        _kriging_fit,
    )
