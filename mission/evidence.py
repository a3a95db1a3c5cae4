"""Error bars over flights: paired bootstrap intervals of mean errors and of their differences.

Why: with a handful of real flights at three transmitter positions a 10 m difference of means is
noise; a comparison is only worth reporting with the interval of its difference, resampled over the
unit that is independent (a flight; on real data a team, whose flights share a vehicle, antenna and
habits).  Resampling is *paired*: one bootstrap replicate picks the same flights (or teams) for
every method, so what varies is the flights, not the pairing.  Cluster bootstrap: a replicate draws
whole groups with replacement and keeps all their flights.  Every replicate set comes from the
caller's seed.

Also the two statistics every coverage claim rests on: the split-conformal quantile (a region's size
from held-out scores) and the exact binomial interval of a coverage share (k truths inside out of
n).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import betaincinv  # the beta quantile (scipy.stats costs seconds to import)

LEVEL = 0.90  # the project's interval: a 90 % percentile interval
N_BOOT = 4000


@dataclass(frozen=True)
class Interval:
    """A statistic with its bootstrap percentile interval."""

    value: float
    lo: float
    hi: float
    level: float = LEVEL

    def excludes_zero(self) -> bool:
        """True when the whole interval lies on one side of zero (a difference that the data
        resolve)."""
        return self.lo > 0.0 or self.hi < 0.0

    def fmt(self, digits: int = 1) -> str:
        """``12.3 [8.1, 17.0]``: the value and its interval, short enough for an 80-column table."""
        return f"{self.value:.{digits}f} [{self.lo:.{digits}f}, {self.hi:.{digits}f}]"

    def to_dict(self) -> dict:
        return {"value": self.value, "lo": self.lo, "hi": self.hi, "level": self.level}


def replicate_weights(
    n: int, groups: Sequence | None = None, n_boot: int = N_BOOT, seed: int = 0
) -> np.ndarray:
    """(n_boot, n) multiplicities of each flight in each replicate: flights drawn with replacement,
    or, with ``groups`` (one label per flight), whole groups drawn with replacement (cluster
    bootstrap)."""
    rng = np.random.default_rng(seed)
    if n < 1:
        raise ValueError("need at least one flight")
    if groups is None:
        idx = rng.integers(0, n, size=(n_boot, n))
        w = np.zeros((n_boot, n))
        np.add.at(w, (np.arange(n_boot)[:, None], idx), 1.0)
        return w
    labels = np.asarray([str(g) for g in groups])
    if labels.shape != (n,):
        raise ValueError(f"need one group label per flight ({n}), got {labels.shape}")
    uniq, inv = np.unique(labels, return_inverse=True)
    k = len(uniq)
    pick = rng.integers(0, k, size=(n_boot, k))
    counts = np.zeros((n_boot, k))
    np.add.at(counts, (np.arange(n_boot)[:, None], pick), 1.0)
    return counts[:, inv]


def _interval(stat: float, reps: np.ndarray, level: float) -> Interval:
    a = (1.0 - level) / 2.0
    lo, hi = np.nanquantile(reps, [a, 1.0 - a])
    return Interval(float(stat), float(lo), float(hi), level)


def mean_interval(
    errors: Sequence[float],
    groups: Sequence | None = None,
    level: float = LEVEL,
    n_boot: int = N_BOOT,
    seed: int = 0,
) -> Interval:
    """Mean error over flights with its (cluster) bootstrap interval."""
    e = np.asarray(errors, dtype=float)
    w = replicate_weights(len(e), groups, n_boot, seed)
    reps = (w @ e) / np.maximum(w.sum(axis=1), 1e-12)
    return _interval(float(e.mean()), reps, level)


def paired_difference(
    errors_a: Sequence[float],
    errors_b: Sequence[float],
    groups: Sequence | None = None,
    level: float = LEVEL,
    n_boot: int = N_BOOT,
    seed: int = 0,
) -> Interval:
    """Mean of ``a - b`` over the same flights, with its paired (cluster) bootstrap interval:
    negative = a errs less."""
    a, b = np.asarray(errors_a, dtype=float), np.asarray(errors_b, dtype=float)
    if a.shape != b.shape:
        raise ValueError(f"paired errors need the same flights: {a.shape} vs {b.shape}")
    return mean_interval(a - b, groups, level, n_boot, seed)


def compare_methods(
    errors: Mapping[str, Sequence[float]],
    reference: str,
    groups: Sequence | None = None,
    level: float = LEVEL,
    n_boot: int = N_BOOT,
    seed: int = 0,
) -> dict[str, dict[str, Interval]]:
    """Per method: its mean error and its paired difference to ``reference``, all from one replicate
    set."""
    if reference not in errors:
        raise ValueError(f"reference {reference!r} is not among the methods")
    n = len(next(iter(errors.values())))
    w = replicate_weights(n, groups, n_boot, seed)
    tot = np.maximum(w.sum(axis=1), 1e-12)
    ref = np.asarray(errors[reference], dtype=float)
    out: dict[str, dict[str, Interval]] = {}
    for name, e in errors.items():
        e = np.asarray(e, dtype=float)
        if e.shape != ref.shape:
            raise ValueError(f"{name}: {e.shape} errors, reference has {ref.shape}")
        out[name] = {
            "mean": _interval(float(e.mean()), (w @ e) / tot, level),
            "diff": _interval(float((e - ref).mean()), (w @ (e - ref)) / tot, level),
        }
    return out


def conformal_quantile(scores: Sequence[float], level: float) -> float:
    """Split-conformal quantile: the ``ceil((n + 1) level)``-th smallest of ``n`` held-out scores
    (inf when n is too small).  A fresh exchangeable score is at most it with probability ``ceil((n
    + 1) level) / (n + 1)`` (rank argument): an error circle's radius, or the HPD mass of a
    posterior region."""
    e = np.sort(np.asarray(scores, dtype=float).ravel())
    k = math.ceil((e.size + 1) * float(level))
    return float(e[k - 1]) if 1 <= k <= e.size else float("inf")


def coverage_interval(k: int, n: int, level: float = LEVEL) -> Interval:
    """Share ``k / n`` of truths inside a region with its exact (Clopper-Pearson) binomial
    interval."""
    if n < 1 or not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n and n >= 1, got k={k}, n={n}")
    a = (1.0 - level) / 2.0
    lo = float(betaincinv(k, n - k + 1, a)) if k > 0 else 0.0
    hi = float(betaincinv(k + 1, n - k, 1.0 - a)) if k < n else 1.0
    return Interval(k / n, lo, hi, level)
