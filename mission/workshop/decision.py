"""The rule that changes the real-log default (models/README.md, "Decisions with error bars",
written before scoring): a candidate replaces the incumbent only when it wins on the pooled evidence
beyond its interval.

Evidence per method, paired with the incumbent on the same flights: ``real`` (errors on the real
flights held out by team, with each flight's team) and ``bench`` (errors on the benchmark drawn from
the reality-fitted family).  Statistic: the relative paired difference of mean errors, (mean
candidate - mean incumbent) / mean incumbent, on each source; pooled = the average of the two.
Interval: 90 % percentile bootstrap (``mission.evidence``), real flights resampled by team,
benchmark flights by flight, independently.

A candidate wins when its pooled interval lies below zero and neither source's own interval lies
above zero; among winners the lowest pooled value is chosen; else the incumbent stays.  A winner
whose 90 % regions cover less than ``MIN_COVERAGE_90`` of the benchmark's truths is reported, not
adopted.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from mission.evidence import LEVEL, N_BOOT, Interval, _interval, replicate_weights

MIN_COVERAGE_90 = 0.80


def _relative(w: np.ndarray, cand: np.ndarray, inc: np.ndarray) -> np.ndarray:
    """Per replicate: (weighted mean of cand - inc) / weighted mean of inc."""
    return (w @ (cand - inc)) / np.maximum(w @ inc, 1e-12)


def pooled_decision(
    real: Mapping[str, Sequence[float]],
    teams: Sequence,
    bench: Mapping[str, Sequence[float]],
    incumbent: str,
    coverage_90: Mapping[str, float] | None = None,
    level: float = LEVEL,
    n_boot: int = N_BOOT,
    seed: int = 0,
) -> dict:
    """Apply the rule (module docstring); returns ``{"choice", "changed", "why", "methods": {name:
    {...}}}``.

    Candidates are the methods present in both ``real`` and ``bench`` other than the incumbent."""
    if incumbent not in real or incumbent not in bench:
        raise ValueError(f"the incumbent {incumbent!r} needs real and benchmark errors")
    r_inc = np.asarray(real[incumbent], float)
    b_inc = np.asarray(bench[incumbent], float)
    w_r = replicate_weights(len(r_inc), teams, n_boot, seed)
    w_b = replicate_weights(len(b_inc), None, n_boot, seed + 1)
    one_r, one_b = np.ones((1, len(r_inc))), np.ones((1, len(b_inc)))
    out: dict[str, dict] = {}
    for name in (m for m in real if m in bench and m != incumbent):
        rc, bc = np.asarray(real[name], float), np.asarray(bench[name], float)
        if rc.shape != r_inc.shape or bc.shape != b_inc.shape:
            raise ValueError(f"{name}: errors must be paired with the incumbent's flights")
        rr, rb = _relative(w_r, rc, r_inc), _relative(w_b, bc, b_inc)
        ivs = {
            "real": _interval(float(_relative(one_r, rc, r_inc)[0]), rr, level),
            "bench": _interval(float(_relative(one_b, bc, b_inc)[0]), rb, level),
        }
        ivs["pooled"] = _interval(
            0.5 * (ivs["real"].value + ivs["bench"].value), 0.5 * (rr + rb), level
        )
        out[name] = {**ivs, **_verdict(ivs, (coverage_90 or {}).get(name))}
    winners = [m for m, d in out.items() if d["adoptable"]]
    if not winners:
        return {
            "choice": incumbent,
            "changed": False,
            "methods": out,
            "why": "no candidate wins on the pooled evidence beyond its interval: the "
            "incumbent stays",
        }
    best = min(winners, key=lambda m: out[m]["pooled"].value)
    return {
        "choice": best,
        "changed": True,
        "methods": out,
        "why": f"{best} errs {-100 * out[best]['pooled'].value:.0f} % less on the pooled evidence "
        f"({_pct(out[best]['pooled'])}), not worse on either source",
    }


def _pct(iv: Interval) -> str:
    return f"{100 * iv.value:+.0f} % [{100 * iv.lo:+.0f}, {100 * iv.hi:+.0f}]"


def _verdict(ivs: dict[str, Interval], cov90: float | None) -> dict:
    """Whether one candidate wins (and is adoptable), with the reason in words."""
    if ivs["pooled"].lo > 0:
        return {"wins": False, "adoptable": False, "reason": f"worse: pooled {_pct(ivs['pooled'])}"}
    if not ivs["pooled"].hi < 0:
        return {
            "wins": False,
            "adoptable": False,
            "reason": f"pooled {_pct(ivs['pooled'])} reaches zero",
        }
    worse = [k for k in ("real", "bench") if ivs[k].lo >= 0]
    if worse:
        return {
            "wins": False,
            "adoptable": False,
            "reason": f"worse beyond its interval on {worse[0]} ({_pct(ivs[worse[0]])})",
        }
    if cov90 is not None and cov90 < MIN_COVERAGE_90:
        return {
            "wins": True,
            "adoptable": False,
            "reason": f"wins, but its 90 % regions cover {100 * cov90:.0f} %",
        }
    return {"wins": True, "adoptable": True, "reason": f"wins: pooled {_pct(ivs['pooled'])}"}
