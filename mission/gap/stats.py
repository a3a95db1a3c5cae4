"""Statistics for autocorrelated residuals: block length from the autocorrelation, circular block
bootstrap.

Why: consecutive RSS samples (30 Hz) share the same shadowing, multipath and pointing, so their
residuals are strongly autocorrelated; an i.i.d. bootstrap or a t-interval would call almost every
bin "significant". Resampling whole blocks whose length covers the autocorrelation keeps that
dependence inside each block. The block length comes from the integrated autocorrelation time of the
residual (Sokal's window), and every flight is resampled on its own (flights are independent of each
other).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


def autocorrelation(x: np.ndarray, max_lag: int | None = None) -> np.ndarray:
    """Sample autocorrelation rho_k, k = 0..max_lag (FFT, mean removed; NaN-free input)."""
    x = np.asarray(x, dtype=float)
    n = x.size
    max_lag = n - 1 if max_lag is None else min(max_lag, n - 1)
    x = x - x.mean()
    m = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfft(x, m)
    ac = np.fft.irfft(f * np.conj(f), m)[: max_lag + 1]
    return ac / ac[0] if ac[0] > 0 else np.zeros_like(ac)


def block_length(
    x: np.ndarray, cutoff: float = 0.05, min_len: int = 1, max_frac: float = 0.1
) -> int:
    """Bootstrap block length ~ 2 x the integrated autocorrelation time of ``x``.

    tau_int = 1 + 2 sum_{k < K} rho_k with K the first lag where rho drops below ``cutoff``; the
    block is ceil(2 tau_int), kept within [min_len, max_frac * n] so that there are at least ~10
    blocks.
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    if n < 4:
        return 1
    hi = max(1, int(max_frac * n))
    rho = autocorrelation(x, max_lag=hi)
    below = np.nonzero(rho < cutoff)[0]
    k = int(below[0]) if below.size else rho.size
    tau = 1.0 + 2.0 * float(np.sum(rho[1:k]))
    return int(np.clip(np.ceil(2.0 * tau), min_len, hi))


def _window_sums(v: np.ndarray, L: int) -> np.ndarray:
    """Circular window sums over the last axis: S[..., s] = sum_{j=s}^{s+L-1} v[..., j mod n]."""
    n = v.shape[-1]
    ext = np.concatenate([v, v[..., : min(L, n)]], axis=-1)
    c = np.concatenate([np.zeros(v.shape[:-1] + (1,)), np.cumsum(ext, axis=-1)], axis=-1)
    return c[..., L : L + n] - c[..., :n]


def bootstrap_group_means(
    values: Sequence[np.ndarray],
    groups: Sequence[np.ndarray],
    n_groups: int,
    block_lens: Sequence[int],
    n_boot: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Circular block bootstrap of per-group means, pooled over independent flights.

    ``values[f]``, ``groups[f]`` (ints in [0, n_groups), -1 = excluded) belong to flight f,
    resampled with block length ``block_lens[f]``.  Returns (n_boot, n_groups) replicate means (NaN
    where a replicate has no sample of that group).
    """
    sums = np.zeros((n_boot, n_groups))
    cnts = np.zeros((n_boot, n_groups))
    for v, g, L in zip(values, groups, block_lens, strict=True):
        n = v.size
        if n == 0:
            continue
        L = int(max(1, min(L, n)))
        onehot = (g[None, :] == np.arange(n_groups)[:, None]).astype(float)  # (G, n)
        ws = _window_sums(onehot * v[None, :], L)
        wc = _window_sums(onehot, L)
        k = int(np.ceil(n / L))
        starts = rng.integers(0, n, size=(n_boot, k))
        sums += ws[:, starts].sum(axis=-1).T
        cnts += wc[:, starts].sum(axis=-1).T
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(cnts > 0, sums / np.where(cnts > 0, cnts, 1.0), np.nan)


def bootstrap_mean(
    values: Sequence[np.ndarray], block_lens: Sequence[int], n_boot: int, rng: np.random.Generator
) -> np.ndarray:
    """Block-bootstrap replicates (n_boot,) of the pooled mean of ``values`` (one array per
    flight)."""
    groups = [np.zeros(v.size, dtype=int) for v in values]
    return bootstrap_group_means(values, groups, 1, block_lens, n_boot, rng)[:, 0]


@dataclass
class ErrorSummary:
    """The gap in one number set: |error| median and 90th percentile, RMS, bias (dB)."""

    n: int
    median_abs: float
    p90_abs: float
    rms: float
    mean: float

    def as_dict(self) -> dict[str, float]:
        return {
            "n": self.n,
            "median_abs_db": self.median_abs,
            "p90_abs_db": self.p90_abs,
            "rms_db": self.rms,
            "mean_db": self.mean,
        }


def summarize(err: np.ndarray) -> ErrorSummary:
    """Summary of a residual array (NaNs ignored)."""
    e = np.asarray(err, dtype=float)
    e = e[np.isfinite(e)]
    if e.size == 0:
        return ErrorSummary(0, np.nan, np.nan, np.nan, np.nan)
    a = np.abs(e)
    return ErrorSummary(
        int(e.size),
        float(np.median(a)),
        float(np.percentile(a, 90)),
        float(np.sqrt(np.mean(e * e))),
        float(np.mean(e)),
    )


def ecdf(x: np.ndarray, n_points: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Empirical CDF of |x| sampled at ``n_points`` quantiles (for plots and JSON)."""
    a = np.sort(np.abs(np.asarray(x, dtype=float)[np.isfinite(x)]))
    if a.size == 0:
        return np.zeros(0), np.zeros(0)
    q = np.linspace(0.0, 1.0, n_points)
    return np.quantile(a, q), q


@dataclass
class BinnedResidual:
    """Mean residual per bin of one variable, with block-bootstrap confidence intervals and
    flags."""

    variable: str
    centers: np.ndarray
    edges: np.ndarray
    count: np.ndarray
    mean: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    flagged: np.ndarray

    def as_dict(self) -> dict:
        return {
            "variable": self.variable,
            "edges": self.edges.tolist(),
            "centers": self.centers.tolist(),
            "count": self.count.tolist(),
            "mean_db": _nan_list(self.mean),
            "ci_lo_db": _nan_list(self.lo),
            "ci_hi_db": _nan_list(self.hi),
            "flagged": self.flagged.tolist(),
        }


def _nan_list(a: np.ndarray) -> list:
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(a, dtype=float)]


def binned_residual(
    variable: str,
    xs: Sequence[np.ndarray],
    residuals: Sequence[np.ndarray],
    edges: np.ndarray,
    block_lens: Sequence[int],
    rng: np.random.Generator,
    n_boot: int = 300,
    level: float = 0.95,
    min_count: int = 30,
    categorical: bool = False,
) -> BinnedResidual:
    """Bin ``residuals`` by ``xs`` (one array per flight) and flag bins whose mean departs from
    zero.

    A bin is flagged when its block-bootstrap ``level`` interval excludes 0 (the residual has the
    per-flight offset removed, so a flagged bin is a systematic departure of the model there).
    """
    edges = np.asarray(edges, dtype=float)
    nb = len(edges) if categorical else len(edges) - 1
    groups = []
    for x in xs:
        if categorical:
            g = np.searchsorted(edges, x)
            g = np.where((g < nb) & (edges[np.minimum(g, nb - 1)] == x), g, -1)
        else:
            g = np.digitize(x, edges) - 1
            g = np.where((g >= 0) & (g < nb), g, -1)
        groups.append(g.astype(int))
    allg = np.concatenate(groups) if groups else np.zeros(0, int)
    allr = np.concatenate(residuals) if residuals else np.zeros(0)
    count = np.bincount(allg[allg >= 0], minlength=nb)[:nb]
    s = np.bincount(allg[allg >= 0], weights=allr[allg >= 0], minlength=nb)[:nb]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, s / np.maximum(count, 1), np.nan)
    boot = bootstrap_group_means(list(residuals), groups, nb, block_lens, n_boot, rng)
    a = (1.0 - level) / 2.0
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns (empty bins)
        lo = np.nanquantile(boot, a, axis=0)
        hi = np.nanquantile(boot, 1.0 - a, axis=0)
    ok = count >= min_count
    flagged = ok & ((lo > 0) | (hi < 0))
    centers = edges.copy() if categorical else 0.5 * (edges[:-1] + edges[1:])
    return BinnedResidual(variable, centers, edges, count, mean, lo, hi, flagged)
