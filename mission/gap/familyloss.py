"""One loss for a physics family: the loop check and the posterior-predictive checks, weighed.

Why: a family is judged twice.  The loop check (``loopcheck``: flights simulated along the real
tracks, re-fitted, must give the family's parameters, held-out p90, variogram sill and range back)
asks whether it reproduces the *residuals*; the posterior-predictive checks
(``mission.workshop.predictive``: RSS spread, residual sill, range, nugget and each localizer's
error on the real flights against a benchmark drawn from the family) ask whether it reproduces what
the real flights *look like* and how hard they are.  The shipped refit passed the first and failed
more of the second (8 of 13 against 5): tuning a family on one check alone moves it away from the
other.  So the family's free knobs (the shadowing's and the per-flight nuisance's scale) are chosen
by one loss, stated here before any fit:

    L = 1/2 mean_c miss_ppc(c) + 1/2 mean_r miss_loop(r)

- ``miss_ppc(c)`` for a predictive check with predictive p: 0 inside the pass band
  ``[P_PASS[0], P_PASS[1]]`` (= [0.05, 0.95]), else the distance to the band over its margin
  ``P_PASS[0]``: 1 at p = 0 or p = 1.  A check that passes costs nothing (a family is not rewarded
  for p = 0.5 over p = 0.3: both are what the real flights look like).
- ``miss_loop(r)`` per loop rule: the pooled held-out p90 ``max(0, |sim - real| - tol) / tol``
  (tol 1 dB, the rule's); every interval rule (each re-fitted parameter's mean, the sill, the
  range) its distance outside the interval over the interval's width (0 inside).
- Means within each group, then equal weights: the 13 predictive checks do not drown the loop's
  rules, nor the reverse.  L = 0 exactly when every check of both kinds passes; the counts that are
  reported (predictive checks failed, loop passed) come with it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from mission.gap.loopcheck import P90_TOL_DB
from mission.workshop.predictive import P_PASS

W_PPC, W_LOOP = 0.5, 0.5


def ppc_miss(p: float) -> float:
    """A predictive check's miss: 0 inside the pass band, linear outside, 1 at p = 0 or 1."""
    lo, hi = P_PASS
    return max(0.0, lo - p, p - hi) / lo


def interval_miss(v: float, iv: list[float] | tuple[float, float]) -> float:
    """How far ``v`` lies outside the interval, in interval widths (0 inside)."""
    lo, hi = float(iv[0]), float(iv[1])
    width = max(hi - lo, 1e-9)
    return max(0.0, lo - v, v - hi) / width


def loop_misses(loop: Mapping[str, Any]) -> dict[str, float]:
    """Each loop rule's miss (``loopcheck.loop_check``'s record, or ``checks.loop`` of a family)."""
    p = loop["heldout_p90_db"]
    out = {"heldout_p90_db": max(0.0, abs(p["sim"] - p["real"]) - P90_TOL_DB) / P90_TOL_DB}
    for k, v in loop.get("params", {}).items():
        out[f"param {k}"] = interval_miss(v["refit_mean"], v["interval"])
    out["sill_db"] = interval_miss(loop["sill_db"]["sim"], loop["sill_db"]["interval"])
    out["range_m"] = interval_miss(loop["range_m"]["sim"], loop["range_m"]["interval"])
    return out


def family_loss(
    loop: Mapping[str, Any] | None, ppc: Mapping[str, Mapping[str, Any]] | None
) -> dict[str, Any]:
    """The module's loss of one family from its loop check and its predictive checks (either may be
    missing: its group is then left out and the other carries the whole weight); with the terms and
    the counts."""
    lm = loop_misses(loop) if loop else {}
    pm = {k: ppc_miss(float(c["p"])) for k, c in (ppc or {}).items()}
    groups = [(W_LOOP, lm), (W_PPC, pm)]
    used = [(w, g) for w, g in groups if g]
    total_w = sum(w for w, _ in used)
    loss = sum(w * sum(g.values()) / len(g) for w, g in used) / total_w if used else 0.0
    return {
        "loss": float(loss),
        "loop_misses": lm,
        "ppc_misses": pm,
        "ppc_failed": sum(1 for c in (ppc or {}).values() if not c["passes"]),
        "ppc_checks": len(ppc or {}),
        "loop_passed": None if not loop else bool(loop.get("passed")),
        "weights": {"loop": W_LOOP, "ppc": W_PPC},
    }
