"""Fixed vs adaptive flights of one mission, paired in the same simulated worlds (benchmark and
preview).

Flight ``i`` of seed ``S`` draws its physics from the family, its transmitter and its shadowing map
from ``SeedSequence(S, spawn_key=(i,))`` (``flight_rng``); its fixed and adaptive versions share
them and the same attitude/noise seed, so their difference is the path's alone.  Each arm is scored
by what the product shows its user after landing (``product_answer``: the spiral network on a fixed
simulated spiral, the live method on an adaptive flight; issue 33 item 4), and also by the live
estimator on both (``live_error_m``, what the rounds were planned with).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mission.adaptive.simflight import (
    MISSION_PHYSICS,
    FlightWorld,
    adaptive_flight,
    estimator,
    fixed_flight,
)
from mission.errors import InputError
from mission.evidence import compare_methods, mean_interval
from mission.localize.api import localize_log
from mission.localize.rounds_answer import survey_attitude
from mission.physics.family import load_family
from mission.simulate import SimConfig
from mission.workshop.evaluate_suite import region_coverage
from mission.workshop.flight_draws import flight_rng


def product_answer(flight_log):
    """The estimate ``localize`` gives by default after a simulated flight: ``api.localize_log``
    on the log it writes (``SimLog.flight_log``); None when it refuses the log."""

    try:
        return localize_log(flight_log)
    except InputError:
        return None


def shown_regions(shown, tx) -> dict:
    """What the regions ``localize`` prints after the flight say about the truth ``tx``: whether
    each level's region holds it, the 90 % region's area, the truth's HPD level in the answer's
    posterior (None without one: the smallest mass whose set holds it, so masses can be
    recalibrated offline) and whether the shown point lies in its own 90 % region."""

    if shown is None:
        return {"covered": {}, "area_m2": None, "level": None, "point_inside": None}
    post = shown.posterior
    reg = shown.region(0.9)
    return {
        "covered": {k: bool(v) for k, v in region_coverage(shown, tx).items()},
        "area_m2": None if reg is None else reg.area_m2,
        "level": None
        if post is None or post.grid is None
        else post.hpd_level(float(tx[0]), float(tx[1])),
        "point_inside": region_coverage(shown, (shown.x_m, shown.y_m)).get("90"),
    }


def sim_config(spec, dt_s: float, vehicle: dict | None = None) -> SimConfig:
    """The mission's simulator settings at sample period ``dt_s``, with ``vehicle``'s fields of
    the simulated vehicle's ``Kinematics`` overridden (None or empty: the mission's own)."""
    cfg = dataclasses.replace(spec.sim_config(), dt_s=dt_s)
    if vehicle:
        cfg = dataclasses.replace(cfg, kinematics=dataclasses.replace(cfg.kinematics, **vehicle))
    return cfg


def pair(
    spec,
    adaptive,
    family: str,
    seed: int,
    i: int,
    dt_s: float | None = None,
    vehicle: dict | None = None,
) -> dict:
    """Errors (of the product's answer and of the live estimate), the live estimate's 90 % region
    coverage and area, the product's regions (``shown_regions``), durations and rounds of flight
    ``i``, fixed and adaptive.

    ``dt_s``: the RSS sample period (None: the mission's own, ``source.sample_period_s``, what
    ``fly-mission`` logs).  Why not coarser: the networks were trained at the mission's period, and
    at 0.1 s (the default before 2026-11-29) the fixed spiral erred 23.7 m where it errs 9.6 m at
    0.033 s (40 flights nose down, seed 2051), which overstated the adaptive finish's gain
    (docs/adaptive.md, "The benchmark's sample period").

    ``family``: a physics family (``load_family``) or ``"mission"``, the mission's own source model
    without shadowing (what ``fly-mission`` simulates against a SITL).  ``vehicle``: fields of the
    simulated vehicle's ``Kinematics`` to override (e.g. a steeper cruise pitch, as real autopilots
    fly), for both missions; the planner keeps the mission's own."""

    cfg = sim_config(spec, spec.sim_config().dt_s if dt_s is None else dt_s, vehicle)
    loc = estimator(spec)
    fam = None if family == MISSION_PHYSICS else load_family(family)
    w = FlightWorld(spec, fam, flight_rng(seed, i))
    out = {"i": i, "tx": [float(w.tx[0]), float(w.tx[1])]}
    for name, o in (
        ("fixed", fixed_flight(spec, w, cfg, np.random.default_rng([seed, i, 1]), loc)),
        (
            "adaptive",
            adaptive_flight(spec, adaptive, w, cfg, np.random.default_rng([seed, i, 1]), loc),
        ),
    ):

        def err(e):
            return None if e is None else float(np.hypot(e[0] - w.tx[0], e[1] - w.tx[1]))

        flown = adaptive if name == "adaptive" else None
        flog = None if o.log is None else o.log.flight_log(spec, flown)
        shown = None if flog is None else product_answer(flog)
        survey_att = survey_attitude(flog) if name == "adaptive" and flog is not None else None
        out[name] = {
            "error_m": None if shown is None else err((shown.x_m, shown.y_m)),
            "method": None if shown is None else shown.method,
            # what each member the answer weighed would have erred (the rounds' candidates)
            "member_errors_m": {}
            if shown is None
            else {k: err((c.x_m, c.y_m)) for k, c in shown.components.items()},
            # and where each stood (the survey's fixed-flight default: a fallback's trigger)
            "member_xy": {}
            if shown is None
            else {k: [float(c.x_m), float(c.y_m)] for k, c in shown.components.items()},
            # the networks' physics residual at each candidate (rounds_answer's judge)
            "physics_rms_db": None if shown is None else shown.extras.get("physics_rms_db"),
            "live_error_m": err(o.final),
            "area_m2": o.final[2] if o.final else None,
            "covered": o.final[3] if o.final else None,
            "fast_error_m": err(o.fast),
            "duration_s": o.duration_s,
            "rounds": o.rounds,
            "planned": o.planned,  # each round's [target, centre flown]
            "shown_regions": shown_regions(shown, w.tx),
            # the survey's roll and pitch spans (an adaptive flight's; rounds_answer)
            "survey_attitude_deg": survey_att,
        }
    return out


def summarize_pairs(rows: list[dict]) -> dict:
    """Mean (90 % bootstrap interval), paired difference adaptive - fixed, p90, coverage, median
    region area, mean duration and rounds per mission; the fast (3-minute) estimate's mean error;
    the same means and difference for the live estimator (``live``) and which methods answered."""

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
    live = [
        r for r in ok if None not in (r["fixed"]["live_error_m"], r["adaptive"]["live_error_m"])
    ]
    if live:
        lv = compare_methods(
            {k: np.array([r[k]["live_error_m"] for r in live]) for k in ("fixed", "adaptive")},
            "fixed",
        )
        out["live"] = {"n": len(live), **{k: lv[k] for k in ("fixed", "adaptive")}}
    if "live" in out:  # the adaptive arm's answer against its live estimate on the same flights
        ad = np.array([r["adaptive"]["error_m"] for r in live])
        ad_live = np.array([r["adaptive"]["live_error_m"] for r in live])
        out["answer_vs_live"] = compare_methods({"live": ad_live, "answer": ad}, "live")["answer"]
    out["methods"] = {
        k: sorted({str(r[k].get("method")) for r in ok}) for k in ("fixed", "adaptive")
    }
    return out
