"""Closing the loop: flights simulated from a fitted family, diagnosed again, must give the family
back.

Why: a family is only useful if what it simulates looks like the flights it came from.  Along each
real track (same positions, attitudes, transmitter), one flight's physics is drawn from the family
and its RSS simulated (``mission.physics.family.simulate_rss``); the same per-flight fit
(``familyfit.fit_flight``) is run on the simulated flights.  Pass rules, written before scoring:

- every fitted parameter's mean over the simulated flights lies inside the family's interval for it
  (``checks.intervals``: the real per-flight range widened by one standard error);
- the UAV/rover antenna pattern fitted on a simulated flight is the one drawn for it (reported as a
  share);
- the pooled held-out p90 |residual| of the simulated flights is within 1 dB of the real flights';
- the variogram sill (sqrt(sigma^2 + nugget^2)) and range (``shadowing_corr_m``) averaged over the
  simulated flights lie inside the real flights' intervals.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from mission.gap.familyfit import NUISANCE_KINDS, PATTERN_KEYS, fit_family
from mission.gap.fit import FitConfig
from mission.physics.family import PhysicsFamily, simulate_rss
from mission.samples import FlightSamples

P90_TOL_DB = 1.0


def simulate_along(
    family: PhysicsFamily, flights: list[FlightSamples], rng: np.random.Generator
) -> tuple[list[FlightSamples], list[dict[str, Any]]]:
    """One family draw per real track: the simulated flights and their draws."""
    sims, draws = [], []
    for f in flights:
        dr = family.draw(rng)
        rss = simulate_rss(dr, f.tx_enu_m, f.enu_m, f.attitude_rad, rng)
        sims.append(replace(f, rss_dbm=np.asarray(rss, dtype=float), name=f"{f.name}~sim"))
        draws.append(dr.to_dict())
    return sims, draws


def _inside(v: float, iv: list[float]) -> bool:
    return bool(iv[0] <= v <= iv[1])


def loop_check(
    record: dict[str, Any],
    flights: list[FlightSamples],
    cfg: FitConfig,
    seed: int = 0,
    repeats: int = 1,
) -> dict[str, Any]:
    """Simulate ``repeats`` copies of the real tracks from ``record``, re-fit, compare (module
    docstring)."""
    fam = PhysicsFamily.from_dict(record)
    rng = np.random.default_rng(seed)
    sims, draws = [], []
    for _ in range(repeats):
        s, d = simulate_along(fam, flights, rng)
        sims += s
        draws += d
    kinds = tuple(k for k, key in NUISANCE_KINDS.items() if key in record.get("nuisance", {}))
    cov = record.get("shadowing_covariance", "gaussian")  # re-fitted as the family was fitted
    rec2, fits2 = fit_family(
        sims, record.get("effects", []), cfg, seed=seed, structure=kinds, covariance=cov
    )
    iv = record["checks"]["intervals"]
    params = {}
    for k, s in rec2["spread"].items():
        if k in iv and "mean" in s and k != "offset_db":
            params[k] = {
                "refit_mean": s["mean"],
                "interval": iv[k],
                "inside": _inside(s["mean"], iv[k]),
            }
    same = [
        all(ft.spec.get(k) == dr["spec"].get(k, ft.spec.get(k)) for k in PATTERN_KEYS)
        for ft, dr in zip(fits2, draws, strict=True)
    ]
    real_p90 = record["checks"]["heldout_p90_db"]["pooled"]
    sim_p90 = rec2["checks"]["heldout_p90_db"]["pooled"]
    sill, rng_m = rec2["checks"]["sill_db"]["mean"], rec2["spread"]["shadowing_corr_m"]["mean"]
    out = {
        "flights": len(sims),
        "params": params,
        "patterns_recovered": float(np.mean(same)) if same else 1.0,
        "heldout_p90_db": {
            "real": real_p90,
            "sim": sim_p90,
            "diff": sim_p90 - real_p90,
            "within_1db": bool(abs(sim_p90 - real_p90) <= P90_TOL_DB),
        },
        "sill_db": {"sim": sill, "interval": iv["sill_db"], "inside": _inside(sill, iv["sill_db"])},
        "range_m": {
            "sim": rng_m,
            "interval": iv["shadowing_corr_m"],
            "inside": _inside(rng_m, iv["shadowing_corr_m"]),
        },
        "draws": draws,
        "refit": [f.as_dict() for f in fits2],
    }
    out["passed"] = bool(
        all(p["inside"] for p in params.values())
        and out["heldout_p90_db"]["within_1db"]
        and out["sill_db"]["inside"]
        and out["range_m"]["inside"]
    )
    return out


def calibrate_residual(record: dict[str, Any], check: dict[str, Any]) -> float:
    """Scale the family's shadowing so that simulated flights' held-out p90 meets the real one (in
    place).

    Why: the per-flight fits absorb part of a simulated field (a slope, a heading bend with it), so
    flights simulated with the real held-out spread come out narrower.  One indirect-inference step:
    the total std sqrt(s^2 + n^2) is scaled by real p90 / simulated p90, the noise kept; returns the
    factor.
    """
    p = check["heldout_p90_db"]
    k = float(p["real"] / p["sim"]) if p["sim"] > 0 else 1.0
    res = record["residual"]
    sh, nz = res["shadowing_db"], res.get("noise_db", 0.0)
    n = float(nz["mean"]) if isinstance(nz, dict) else float(nz)
    m = float(sh["mean"]) if isinstance(sh, dict) else float(sh)
    m_new = float(np.sqrt(max(k * k * (m * m + n * n) - n * n, 0.0)))
    if isinstance(sh, dict):
        res["shadowing_db"] = {
            **sh,
            "mean": round(m_new, 4),
            "sd": round(float(sh["sd"]) * m_new / max(m, 1e-9), 4),
        }
    else:
        res["shadowing_db"] = round(m_new, 4)
    record["residual_calibration"] = {
        "p90_scale": k,
        "shadowing_db_before": sh,
        "rule": "total std scaled by real / simulated held-out p90 (one step)",
    }
    return k
