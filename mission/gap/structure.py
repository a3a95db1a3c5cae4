"""What is left and how large: residual correlation (variograms) and the footprint of a fitted effect.

Why: an effect that no candidate can predict on held-out data can still be *measured*.  Correlated shadowing
is the common case: kriging cannot predict a chunk of flight over ground never flown, but the residual's
semivariogram shows a correlated part (sigma, correlation length) above a white-noise floor (nugget).  Two
variograms are fitted (``mission.physics.shadowing.fit_variogram``, exponential covariance, bootstrap 90 %
intervals): along the path (lag in seconds, pairs within a flight) and over space (lag in metres, pairs
around the same transmitter).  The verdict rule (``STRUCTURE_RULE``) names "correlated shadowing" when the
spatial variogram's correlated part is clearly there, else "white noise".

``footprint`` turns a fitted candidate into "how large and where": the change it makes to the prediction on
the flown samples (``size_db``: median |change| where it is at least half its maximum, i.e. its size where it
acts; also the 5-95 % range) and the geometry (distance, body azimuth/depression, world azimuth) of
the samples where it acts most.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from mission.gap.align import align
from mission.gap.pipeline import Pipeline
from mission.gap.spatial import tx_key
from mission.physics.shadowing import fit_variogram
from mission.samples import FlightSamples

STRUCTURE_RULE = ("correlated shadowing when the spatial variogram's correlated std has a 90 % lower bound "
                  ">= 1 dB and >= 0.5 x the nugget, and its correlation length a lower bound above the first "
                  "lag bin (5 m); otherwise white noise")


def residual_structure(flights: Sequence[FlightSamples], resid: Sequence[np.ndarray], rng: np.random.Generator,
                       max_points: int = 1200, n_boot: int = 25) -> dict[str, Any]:
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
    along = fit_variogram(T, R, rng, max_lag=60.0, n_bins=30, max_points=max_points, n_boot=n_boot,
                          groups=np.concatenate(g_f), unit="s")
    space = fit_variogram(XY, R, rng, max_lag=150.0, n_bins=30, max_points=max_points, n_boot=n_boot,
                          groups=np.concatenate(g_tx), unit="m")
    bin_w = 150.0 / 30
    corr = (space.sigma_ci[0] >= 1.0 and space.sigma_ci[0] >= 0.5 * space.nugget_db
            and space.corr_len_ci[0] > bin_w)
    return {"verdict": "correlated shadowing" if corr else "white noise", "rule": STRUCTURE_RULE,
            "residual_std_db": float(np.std(R)), "along_path": along.as_dict(), "spatial": space.as_dict()}


def footprint(base: Pipeline, new: Pipeline, flights: Sequence[FlightSamples], max_samples: int = 3000) -> dict[str,
              Any]:
    """Size (5-95 % range of new - base, dB, offset-free) and where the change acts most (top 5 % |change|)."""
    d, geo = [], []
    for f in flights:
        i = np.arange(0, len(f), max(1, len(f) // max_samples))
        diff = new.predict(f, i) - base.predict(f, i)
        d.append(diff - np.median(diff))
        a = align(f.select(np.isin(np.arange(len(f)), i)))
        geo.append(np.column_stack([a.d_h, np.rad2deg(a.az_b), np.rad2deg(a.dep_b), np.rad2deg(a.az_world)]))
    D, G = np.concatenate(d), np.concatenate(geo)
    acting = np.abs(D) >= 0.5 * np.max(np.abs(D))
    size = float(np.median(np.abs(D[acting]))) if D.size else 0.0
    top = np.abs(D) >= np.quantile(np.abs(D), 0.95)
    sign = "loss" if np.median(D[top]) < 0 else "gain"

    def circ(x: np.ndarray) -> float:
        a = np.deg2rad(x)
        return float(np.rad2deg(np.arctan2(np.sin(a).mean(), np.cos(a).mean())) % 360.0)

    return {"size_db": size, "range_5_95_db": float(np.quantile(D, 0.95) - np.quantile(D, 0.05)),
            "max_abs_db": float(np.max(np.abs(D))), "acts_as": sign,
            "where": {"distance_m": float(np.median(G[top, 0])), "body_azimuth_deg": circ(G[top, 1]),
                      "body_depression_deg": float(np.median(G[top, 2])), "world_azimuth_deg": circ(G[top, 3]),
                      "share_of_samples": float(np.mean(acting))}}


def name_missing(ranking: Sequence[Any], structure: dict[str, Any] | None) -> str | None:
    """What the diagnosis names: the top-ranked significant candidate; else "spatial_shadowing" when the
    residual structure is correlated shadowing; else None (nothing)."""
    if ranking and ranking[0].significant:
        return ranking[0].name
    if structure is not None and structure.get("verdict") == "correlated shadowing":
        return "spatial_shadowing"
    return None


def identify(flights: Sequence[FlightSamples], base: Pipeline, candidates: Sequence[Any], cfg: Any,
             progress: Any = None) -> dict[str, Any]:
    """One ranking on top of ``base`` plus the residual structure: what is missing, how large, where.

    Returns ``named`` (``name_missing``), the ranking rows, the structure of the base's held-out residuals,
    and for the named effect its ``footprint`` (fold 0's fit against the base) and fitted parameters.
    """
    from mission.gap.fit import RANKING_RULE, heldout_residuals, make_folds, rank_candidates

    rng = np.random.default_rng(cfg.seed)
    folds = make_folds(flights, cfg)
    pipes = [base] * len(folds)
    base_res = heldout_residuals(pipes, flights, folds, cfg)
    ranking = rank_candidates(pipes, flights, folds, candidates, cfg, rng, base_res, progress, "rank")
    struct = residual_structure(flights, base_res, rng)
    named = name_missing(ranking, struct)
    out: dict[str, Any] = {"named": named, "rule": RANKING_RULE, "structure": struct,
                           "significant": [r.name for r in ranking if r.significant],
                           "ranking": [{"name": r.name, "tier": r.tier, "rel_reduction": r.rel_reduction,
                                        "loss_reduction_db2": r.loss_reduction, "ci_lo_db2": r.ci_lo,
                                        "significant": r.significant} for r in ranking]}
    hit = next((r for r in ranking if r.name == named and r.significant), None)
    if hit is not None:
        out["footprint"] = footprint(base, hit.pipes[0], flights)
        out["params"] = {k: v for k, v in hit.params_mean().items() if k not in ("shape", "resemblances")}
    elif named == "spatial_shadowing":
        sp = struct["spatial"]
        out["footprint"] = {"size_db": 2 * 1.645 * sp["sigma_db"], "where": {"corr_len_m": sp["corr_len"]}}
        out["params"] = {"sigma_db": sp["sigma_db"], "corr_len_m": sp["corr_len"], "nugget_db": sp["nugget_db"]}
    return out
