"""From a diagnosis to a checked physics family (``rfsl gap --family F.json``).

Why a module of its own: the per-flight fits (``familyfit``) and the loop-closing check
(``loopcheck``, which re-runs those fits on simulated flights) are separate jobs; this one strings
them together -- fit the ladder's effects per flight, check the loop, recalibrate the shadowing
while the check misses -- so that the check may import the fits without the fits importing the
check.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from mission.gap.familyfit import effects_of_ladder, fit_family
from mission.gap.fit import FitConfig
from mission.gap.loopcheck import P90_TOL_DB, calibrate_residual, loop_check

SECANT_LIMIT = 1.5  # the recalibration's secant step changes the shadowing scale by at most this


def family_from_diagnosis(
    d: Any,
    cfg: FitConfig,
    name: str = "family",
    source: dict[str, Any] | None = None,
    check: bool = True,
    repeats: int = 4,
    structure: bool | Sequence[str] = False,
    shadowing_over: str = "ground",
    marginal: bool = False,
    covariance: str = "gaussian",
) -> dict[str, Any]:
    """The family of a ``Diagnosis``: its ladder's effects (``effects_of_ladder``) fitted per
    flight; with ``check``, the loop-closing check (``loopcheck``) on the flights it was fitted on,
    in ``checks.loop`` (``repeats`` simulated copies of every track: one copy of five flights
    scatters by +-1.5 dB in p90); ``structure``: per-flight nuisance drawn beside the shadowing
    (``familyfit.fit_flight``); ``shadowing_over``: the drawn shadowing fixed to the ground or
    to the path, ``marginal``: of the held-out residuals' shape (``familyfit.build_family``), and
    ``covariance``: the shadowing's covariance, fitted and drawn (``familyfit.fit_flight``)."""
    effects, left = effects_of_ladder([r.added for r in d.rungs])
    rec, fits = fit_family(
        d.flights,
        effects,
        cfg,
        seed=cfg.seed,
        name=name,
        source=source,
        not_in_family=left,
        structure=structure,
        shadowing_over=shadowing_over,
        marginal=marginal,
        covariance=covariance,
    )
    rec["ladder"] = [r.added for r in d.rungs if r.added]
    if check:
        used = [f for f, ft in zip(d.flights, fits, strict=True) if not ft.excluded]
        lc = loop_check(rec, used, cfg, seed=cfg.seed + 1, repeats=repeats)
        # recalibrate (secant on the total-std scale), fresh draws
        if not lc["heldout_p90_db"]["within_1db"]:
            rec["checks"]["loop_before_calibration"] = {
                k: v for k, v in lc.items() if k not in ("draws", "refit")
            }
            base_sh = rec["residual"]["shadowing_db"]
            pts = [(1.0, lc["heldout_p90_db"]["sim"])]
            k = calibrate_residual(rec, lc)
            for step in range(2):
                lc = loop_check(rec, used, cfg, seed=cfg.seed + 2 + step, repeats=repeats)
                pts.append((k, lc["heldout_p90_db"]["sim"]))
                if lc["heldout_p90_db"]["within_1db"] or step == 1:
                    break
                (k0, p0), (k1, p1) = pts[-2], pts[-1]
                real = lc["heldout_p90_db"]["real"]
                # more shadowing never narrows the p90: a secant through two noisy checks that
                # slopes the other way (p90 scatters ~1.5 dB per copy), or rises by less than the
                # check's own tolerance (noise, not a slope: a nearly flat secant steps to the
                # limit), gives way to the ratio step, and no step moves the scale more than x1.5
                rising = (p1 - p0) * (k1 - k0) > 0 and abs(p1 - p0) >= P90_TOL_DB
                k = k1 + (real - p1) * (k1 - k0) / (p1 - p0) if rising else k1 * real / p1
                k = float(min(max(k, k1 / SECANT_LIMIT), k1 * SECANT_LIMIT))
                rec["residual"]["shadowing_db"] = base_sh
                calibrate_residual(rec, {"heldout_p90_db": {"real": k, "sim": 1.0}})
            rec["residual_calibration"].update(
                shadowing_db_before=base_sh, steps=[list(q) for q in pts]
            )
        rec["checks"]["loop"] = {k: v for k, v in lc.items() if k not in ("draws", "refit")}
        rec["checks"]["loop"]["p90_tolerance_db"] = P90_TOL_DB
    return rec
