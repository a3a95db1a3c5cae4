"""Fixed vs adaptive flights of one mission, paired in the same simulated worlds (benchmark and
preview).

Flight ``i`` of seed ``S`` draws its physics from the family, its transmitter and its shadowing map
from ``SeedSequence(S, spawn_key=(i,))`` (``flight_rng``); its fixed and adaptive versions share
them and the same attitude/noise seed, so their difference is the path's alone.  Both are scored
with the live estimator.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mission.adaptive.simflight import FlightWorld, adaptive_flight, estimator, fixed_flight
from mission.evidence import compare_methods, mean_interval
from mission.physics.family import load_family
from mission.workshop.flight_draws import flight_rng


def pair(spec, adaptive, family: str, seed: int, i: int, dt_s: float = 0.1) -> dict:
    """Errors, 90 % region coverage and area, durations and rounds of flight ``i``, fixed and
    adaptive."""
    cfg = dataclasses.replace(spec.sim_config(), dt_s=dt_s)
    loc = estimator(spec)
    w = FlightWorld(spec, load_family(family), flight_rng(seed, i))
    out = {"i": i, "tx": [float(w.tx[0]), float(w.tx[1])]}
    for name, o in (
        ("fixed", fixed_flight(spec, w, cfg, np.random.default_rng([seed, i, 1]), loc)),
        (
            "adaptive",
            adaptive_flight(spec, adaptive, w, cfg, np.random.default_rng([seed, i, 1]), loc),
        ),
    ):
        err = lambda e: None if e is None else float(np.hypot(e[0] - w.tx[0], e[1] - w.tx[1]))  # noqa: E731
        out[name] = {
            "error_m": err(o.final),
            "area_m2": o.final[2] if o.final else None,
            "covered": o.final[3] if o.final else None,
            "fast_error_m": err(o.fast),
            "duration_s": o.duration_s,
            "rounds": o.rounds,
        }
    return out


def summarize_pairs(rows: list[dict]) -> dict:
    """Mean (90 % bootstrap interval), paired difference adaptive - fixed, p90, coverage, median
    region area, mean duration and rounds per mission; the fast (3-minute) estimate's mean error."""
    ok = [
        r
        for r in rows
        if r["fixed"]["error_m"] is not None and r["adaptive"]["error_m"] is not None
    ]
    if not ok:
        return {"n": 0, "n_total": len(rows)}
    e = {k: np.array([r[k]["error_m"] for r in ok]) for k in ("fixed", "adaptive")}
    cmp = compare_methods(e, "fixed")
    out: dict = {"n": len(ok), "n_total": len(rows)}
    for k in ("fixed", "adaptive"):
        areas = [r[k]["area_m2"] for r in ok if r[k]["area_m2"] is not None]
        out[k] = {
            "mean": cmp[k]["mean"],
            "diff": cmp[k]["diff"],
            "p90_m": float(np.percentile(e[k], 90)),
            "coverage": float(np.mean([bool(r[k]["covered"]) for r in ok])),
            "area_m2": float(np.median(areas)) if areas else float("nan"),
            "duration_s": float(np.mean([r[k]["duration_s"] for r in ok])),
            "rounds": float(np.mean([r[k]["rounds"] for r in ok])),
        }
    fast = np.array(
        [r["fixed"]["fast_error_m"] for r in ok if r["fixed"]["fast_error_m"] is not None]
    )
    out["fast"] = (mean_interval(fast), float(np.percentile(fast, 90))) if len(fast) else None
    out["ratio"] = float(e["adaptive"].mean() / e["fixed"].mean())
    return out
