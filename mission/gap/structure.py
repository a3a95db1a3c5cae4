"""What is left and how large: residual correlation (variograms) and the footprint of a fitted
effect.

Why: an effect that no candidate can predict on held-out data can still be *measured*.  Correlated
shadowing is the common case: kriging cannot predict a chunk of flight over ground never flown, but
the residual's semivariogram shows a correlated part (sigma, correlation length) above a white-noise
floor (nugget).  Two variograms are fitted (``mission.physics.shadowing.fit_variogram``, exponential
covariance, bootstrap 90 % intervals): along the path (lag in seconds, pairs within a flight) and
over space (lag in metres, pairs around the same transmitter).  The verdict (``STRUCTURE_RULE``,
``correlation_test``) does not rest on the fitted correlation length, whose lower bound can reach 0
on real data: it compares the semivariance of near pairs (< 15 m) with that of all pairs, with a
block-bootstrap bound, and names "correlated shadowing" when the correlated part is clearly there,
else "white noise".

``footprint`` turns a fitted candidate into "how large and where": the change it makes to the
prediction on the flown samples (``size_db``: median |change| where it is at least half its maximum,
i.e. its size where it acts; also the 5-95 % range) and the geometry (distance, body
azimuth/depression, world azimuth) of the samples where it acts most.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from mission.gap.align import align
from mission.gap.fit import RANKING_RULE, heldout_residuals, make_folds, rank_candidates
from mission.gap.frame import frame_for, resolve
from mission.gap.pipeline import Pipeline
from mission.gap.spatial import tx_key, usable_candidates
from mission.physics.shadowing import fit_variogram
from mission.samples import FlightSamples

SHORT_LAG_M = 15.0  # "near" pairs of the correlation test: the first three 5 m lag bins
RATIO_THRESHOLD = (
    0.8  # near / all semivariance below this: correlated std >= 1/2 the uncorrelated std
)
STRUCTURE_RULE = (
    "correlated shadowing when the semivariance of residual pairs closer than 15 m (same "
    "transmitter), divided by that of all pairs, has a one-sided 95 % block-bootstrap upper bound "
    "below 0.8 (the correlated std is at least half the uncorrelated one) and the correlated std "
    "sqrt((1 - ratio) var) is at least 1 dB; otherwise correlated within flights when the "
    "along-path "
    "variogram's correlated fraction exceeds 0.5 (sigma >= 1 dB): structure along each flight that "
    "does not repeat over the same ground; otherwise white noise.  The spatial variogram "
    "(sigma, L, "
    "nugget) is reported but not used: L's lower bound can reach 0 on real data"
)


WITHIN_FLIGHT = "correlated within flights"


def structure_verdict(test: dict[str, Any], along: dict[str, Any]) -> str:
    """One verdict on what is left (``STRUCTURE_RULE``): "correlated shadowing" when near pairs over
    the ground are alike (``correlation_test``); else "correlated within flights" when the residual
    along each flight's path is mostly correlated (variogram ``correlated_fraction`` > 0.5,
    correlated sigma >= 1 dB) yet does not repeat over the same ground; else "white noise"."""
    if test.get("correlated"):
        return "correlated shadowing"
    if along.get("correlated_fraction", 0.0) > 0.5 and along.get("sigma_db", 0.0) >= 1.0:
        return WITHIN_FLIGHT
    return "white noise"


def correlation_test(
    xy: np.ndarray,
    r: np.ndarray,
    groups: np.ndarray,
    rng: np.random.Generator,
    short_m: float = SHORT_LAG_M,
    max_points: int = 1200,
    n_blocks: int = 20,
    n_boot: int = 400,
) -> dict[str, Any]:
    """Near-pair to all-pair semivariance ratio of residuals ``r`` at ``xy`` (pairs within a group
    only), with a one-sided 95 % upper bound from a bootstrap of contiguous blocks of points.

    White noise: every pair differs alike, ratio ~ 1.  Correlated shadowing: near pairs are alike,
    ratio ~ nugget^2 / sill.  Model-free (no correlation length to fit), so it cannot be fooled by
    an unidentified L. The block bootstrap is exact on precomputed block-pair sums: a replicate with
    block multiplicities m has pair sums m^T S m.
    """
    r = np.asarray(r, dtype=float)
    if len(r) > max_points:
        sel = np.sort(rng.choice(len(r), max_points, replace=False))
        xy, r, groups = xy[sel], r[sel], groups[sel]
    n = len(r)
    out: dict[str, Any] = {
        "short_lag_m": short_m,
        "ratio": float("nan"),
        "ratio_ci": [float("nan")] * 2,
        "correlated_std_db": 0.0,
        "n_near_pairs": 0,
        "correlated": False,
    }
    if n < 2 * n_blocks:
        return out
    d = xy[:, None, :] - xy[None, :, :]
    h = np.sqrt((d * d).sum(-1))
    same = (groups[:, None] == groups[None, :]) & (h > 0)
    g = 0.5 * (r[:, None] - r[None, :]) ** 2
    near = same & (h <= short_m)
    blk = np.minimum(np.arange(n) * n_blocks // n, n_blocks - 1)
    onehot = np.eye(n_blocks)[blk]  # (n, B)

    def block_sums(w: np.ndarray) -> np.ndarray:
        return onehot.T @ w @ onehot  # (B, B): sums over ordered pairs by block

    S_n, C_n, S_a, C_a = (
        block_sums(w) for w in (g * near, near.astype(float), g * same, same.astype(float))
    )
    n_near = int(C_n.sum() / 2)
    out["n_near_pairs"] = n_near
    if n_near < 30 or C_a.sum() == 0:
        return out
    ratio = float((S_n.sum() / C_n.sum()) / (S_a.sum() / C_a.sum()))
    m = np.stack(
        [
            np.bincount(rng.integers(0, n_blocks, n_blocks), minlength=n_blocks)
            for _ in range(n_boot)
        ]
    )
    m = m.astype(float)

    def quad(S: np.ndarray) -> np.ndarray:
        return np.einsum("bi,ij,bj->b", m, S, m)

    with np.errstate(invalid="ignore", divide="ignore"):
        rb = (quad(S_n) / quad(C_n)) / (quad(S_a) / quad(C_a))
    rb = rb[np.isfinite(rb)]
    lo, hi = np.quantile(rb, [0.05, 0.95]) if rb.size else (np.nan, np.nan)
    var = float(S_a.sum() / C_a.sum())
    c_std = float(np.sqrt(max(0.0, 1.0 - ratio) * var))
    out.update(
        ratio=ratio,
        ratio_ci=[float(lo), float(hi)],
        correlated_std_db=c_std,
        correlated=bool(hi < RATIO_THRESHOLD and c_std >= 1.0),
    )
    return out


def residual_structure(
    flights: Sequence[FlightSamples],
    resid: Sequence[np.ndarray],
    rng: np.random.Generator,
    max_points: int = 1200,
    n_boot: int = 25,
) -> dict[str, Any]:
    """Variograms along the path and over space of residuals (NaN = not scored), and the verdict."""
    t, xy, r, g_f, g_tx = [], [], [], [], []
    keys: dict[tuple[float, float], int] = {}
    for k, (f, x) in enumerate(zip(flights, resid, strict=True)):
        ok = np.isfinite(x)
        if not ok.any():
            continue
        t.append(f.t_s[ok])
        xy.append(f.enu_m[ok, :2])
        r.append(x[ok] - np.mean(x[ok]))
        g_f.append(np.full(int(ok.sum()), k))
        g_tx.append(np.full(int(ok.sum()), keys.setdefault(tx_key(f.tx_enu_m), len(keys))))
    if not r:
        return {"verdict": "no data", "rule": STRUCTURE_RULE}
    T, XY, R = np.concatenate(t), np.concatenate(xy), np.concatenate(r)
    along = fit_variogram(
        T,
        R,
        rng,
        max_lag=60.0,
        n_bins=30,
        max_points=max_points,
        n_boot=n_boot,
        groups=np.concatenate(g_f),
        unit="s",
    )
    space = fit_variogram(
        XY,
        R,
        rng,
        max_lag=150.0,
        n_bins=30,
        max_points=max_points,
        n_boot=n_boot,
        groups=np.concatenate(g_tx),
        unit="m",
    )
    test = correlation_test(XY, R, np.concatenate(g_tx), rng)
    return {
        "verdict": structure_verdict(test, along.as_dict()),
        "rule": STRUCTURE_RULE,
        "test": test,
        "residual_std_db": float(np.std(R)),
        "along_path": along.as_dict(),
        "spatial": space.as_dict(),
    }


def footprint(
    base: Pipeline, new: Pipeline, flights: Sequence[FlightSamples], max_samples: int = 3000
) -> dict[str, Any]:
    """Size (5-95 % range of new - base, dB, offset-free) and where the change acts most (top 5 %
    |change|)."""
    d, geo = [], []
    for f in flights:
        i = np.arange(0, len(f), max(1, len(f) // max_samples))
        diff = new.predict(f, i) - base.predict(f, i)
        d.append(diff - np.median(diff))
        a = align(f.select(np.isin(np.arange(len(f)), i)))
        geo.append(
            np.column_stack(
                [a.d_h, np.rad2deg(a.az_b), np.rad2deg(a.dep_b), np.rad2deg(a.az_world)]
            )
        )
    D, G = np.concatenate(d), np.concatenate(geo)
    acting = np.abs(D) >= 0.5 * np.max(np.abs(D))
    size = float(np.median(np.abs(D[acting]))) if D.size else 0.0
    top = np.abs(D) >= np.quantile(np.abs(D), 0.95)
    sign = "loss" if np.median(D[top]) < 0 else "gain"

    def circ(x: np.ndarray) -> float:
        a = np.deg2rad(x)
        return float(np.rad2deg(np.arctan2(np.sin(a).mean(), np.cos(a).mean())) % 360.0)

    return {
        "size_db": size,
        "range_5_95_db": float(np.quantile(D, 0.95) - np.quantile(D, 0.05)),
        "max_abs_db": float(np.max(np.abs(D))),
        "acts_as": sign,
        "where": {
            "distance_m": float(np.median(G[top, 0])),
            "body_azimuth_deg": circ(G[top, 1]),
            "body_depression_deg": float(np.median(G[top, 2])),
            "world_azimuth_deg": circ(G[top, 3]),
            "share_of_samples": float(np.mean(acting)),
        },
    }


def name_missing(ranking: Sequence[Any], structure: dict[str, Any] | None) -> str | None:
    """What the diagnosis names: the top-ranked significant candidate; else "spatial_shadowing" when
    the residual structure is correlated shadowing; else None (nothing)."""
    if ranking and ranking[0].significant:
        return ranking[0].name
    if structure is not None and structure.get("verdict") == "correlated shadowing":
        return "spatial_shadowing"
    return None


def identify(
    flights: Sequence[FlightSamples],
    base: Pipeline,
    candidates: Sequence[Any],
    cfg: Any,
    progress: Any = None,
) -> dict[str, Any]:
    """One ranking on top of ``base`` plus the residual structure: what is missing, how large,
    where.

    Returns ``named`` (``name_missing``, then ``frame.resolve``: where a ground map and a body-angle
    map both explain the residual, the one that holds out across headings and on unseen ground), the
    ranking rows, the structure of the base's held-out residuals, ``frame`` (that test, or None),
    and for the named effect its ``footprint`` (fold 0's fit against the base) and fitted
    parameters.
    """
    rng = np.random.default_rng(cfg.seed)

    candidates = usable_candidates(candidates, flights, cfg.split)
    folds = make_folds(flights, cfg)
    pipes = [base] * len(folds)
    base_res = heldout_residuals(pipes, flights, folds, cfg)
    ranking = rank_candidates(
        pipes, flights, folds, candidates, cfg, rng, base_res, progress, "rank"
    )
    struct = residual_structure(flights, base_res, rng)

    frame = frame_for(ranking, base, flights, cfg, cfg.seed)
    named = resolve(name_missing(ranking, struct), ranking, frame)
    out: dict[str, Any] = {
        "named": named,
        "rule": RANKING_RULE,
        "structure": struct,
        "frame": frame,
        "significant": [r.name for r in ranking if r.significant],
        "ranking": [
            {
                "name": r.name,
                "tier": r.tier,
                "rel_reduction": r.rel_reduction,
                "loss_reduction_db2": r.loss_reduction,
                "ci_lo_db2": r.ci_lo,
                "significant": r.significant,
            }
            for r in ranking
        ],
    }
    hit = next(
        (r for r in ranking if r.name == named and (r.significant or frame is not None)), None
    )
    if hit is not None:
        out["footprint"] = footprint(base, hit.pipes[0], flights)
        big = ("shape", "resemblances", "time_shapes")
        out["params"] = {k: v for k, v in hit.params_mean().items() if k not in big}
    elif named == "spatial_shadowing":
        sp = struct["spatial"]
        out["footprint"] = {
            "size_db": 2 * 1.645 * sp["sigma_db"],
            "where": {"corr_len_m": sp["corr_len"]},
        }
        out["params"] = {
            "sigma_db": sp["sigma_db"],
            "corr_len_m": sp["corr_len"],
            "nugget_db": sp["nugget_db"],
        }
    return out
