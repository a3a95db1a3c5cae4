"""Posterior-predictive checks of a benchmark against real flights: does the family look like
reality?

Why: a benchmark that errs twice as much as reality, or whose RSS spreads half as much, cannot
arbitrate between methods.  Before a physics family is used to decide anything, the same statistics
are computed on the real flights and on the benchmark flights drawn from it, the same way on both:

- ``rss_spread_db``: the 5-95 % range of the RSS over the samples a localizer uses (cruise);
- the residual after a log-distance fit at the truth (RSS = a - 10 n log10 d, a and n least squares
  per flight: offset and slope free, so only the structure is compared): its exponential
  semivariogram (``mission.physics.shadowing.fit_variogram``): ``resid_sill_db`` = sqrt(sigma^2 +
  nugget^2), the total residual spread, ``resid_range_m`` = the correlation length L (1/e at L),
  ``resid_nugget_db``;
- each method's error (m) on each flight.

A check (``predictive_check``): the benchmark's 10-90 % band of the per-flight statistic, how many
real flights fall inside it (about 80 % should), and the predictive p-value of the real *mean*: the
share of means of as many benchmark flights (drawn with replacement, seeded) that lie below it.  The
check **passes** when 0.05 <= p <= 0.95, i.e. the real mean is not in either 5 % tail of what the
family predicts for that many flights.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from rich.markup import escape
from rich.table import Table

from mission.errors import InputError
from mission.flightlog import read_flight_log
from mission.localize.api import localize_log
from mission.localize.preprocess import select_samples
from mission.physics.geometry import link_delta, slant_distance
from mission.physics.shadowing import fit_variogram
from mission.workshop.evaluate import suite_method

STATISTICS = ("rss_spread_db", "resid_sill_db", "resid_range_m", "resid_nugget_db")
BAND = (0.10, 0.90)
P_PASS = (0.05, 0.95)


def log_distance_residual(
    pos_enu: np.ndarray, rss_dbm: np.ndarray, tx_enu: np.ndarray
) -> np.ndarray:
    """RSS minus its least-squares fit a - 10 n log10(d) at the true transmitter (d 3D, floored at 1
    m)."""
    d = np.maximum(
        slant_distance(*link_delta(np.asarray(tx_enu, float)[None, :], np.asarray(pos_enu, float))),
        1.0,
    )
    A = np.column_stack([np.ones(len(d)), -10.0 * np.log10(d)])
    y = np.asarray(rss_dbm, float)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return y - A @ coef


def sample_statistics(
    pos_enu: np.ndarray,
    rss_dbm: np.ndarray,
    tx_enu: np.ndarray,
    rng: np.random.Generator,
    max_points: int = 800,
) -> dict[str, float]:
    """The check statistics (module docstring) of one flight's used samples."""
    rss = np.asarray(rss_dbm, float)
    ok = np.isfinite(rss)
    pos, rss = np.asarray(pos_enu, float)[ok], rss[ok]
    lo, hi = np.percentile(rss, [5.0, 95.0])
    r = log_distance_residual(pos, rss, tx_enu)
    vg = fit_variogram(pos[:, :2], r, rng, kind="exponential", max_points=max_points, n_boot=0)
    return {
        "rss_spread_db": float(hi - lo),
        "resid_sill_db": float(np.hypot(vg.sigma_db, vg.nugget_db)),
        "resid_range_m": float(vg.corr_len),
        "resid_nugget_db": float(vg.nugget_db),
    }


def flight_statistics(log, truth_xy, tx_height_m: float, seed: int = 0) -> dict[str, float]:
    """The check statistics of a ``FlightLog`` (the samples ``localize`` uses) with its truth (log
    ENU m)."""
    part, _ = select_samples(log)
    tx = np.array([float(truth_xy[0]), float(truth_xy[1]), float(tx_height_m)])
    return sample_statistics(part.enu(), part["rss_dbm"], tx, np.random.default_rng(seed))


def predictive_check(
    real: Sequence[float], sim: Sequence[float], n_boot: int = 4000, seed: int = 0
) -> dict:
    """Real per-flight values against the benchmark's: band, real inside it, predictive p of the
    real mean."""
    x = np.asarray(real, float)
    s = np.asarray(sim, float)
    x, s = x[np.isfinite(x)], s[np.isfinite(s)]
    if x.size == 0 or s.size == 0:
        raise ValueError("a predictive check needs real and benchmark values")
    lo, hi = np.quantile(s, BAND)
    rng = np.random.default_rng(seed)
    means = s[rng.integers(0, s.size, size=(n_boot, x.size))].mean(axis=1)
    return _check_record(x, s, means, int(np.sum((x >= lo) & (x <= hi))))


def _check_record(x: np.ndarray, pooled: np.ndarray, means: np.ndarray, inside: int) -> dict:
    """A check's fields from the real values ``x``, the simulated ones ``pooled``, the simulated
    means of as many flights ``means`` and the count of real flights inside their band."""
    p = float(np.mean(means < x.mean()) + 0.5 * np.mean(means == x.mean()))
    return {
        "real_mean": float(x.mean()),
        "real_median": float(np.median(x)),
        "sim_mean": float(pooled.mean()),
        "sim_median": float(np.median(pooled)),
        "band": [float(v) for v in np.quantile(pooled, BAND)],
        "inside": inside,
        "n_real": int(x.size),
        "n_sim": int(pooled.size),
        "p": p,
        "passes": bool(P_PASS[0] <= p <= P_PASS[1]),
    }


def design_check(
    real: Sequence[float], sim: Sequence[Sequence[float]], n_boot: int = 4000, seed: int = 0
) -> dict:
    """Real per-flight values against replicates of the same flights (``sim[f]``: flight f's
    values simulated along its own track, with its own transmitter): ``predictive_check``'s fields,
    each real flight judged against its own replicates' 10-90 % band, and the predictive p of the
    real mean among means of one replicate per flight.  Why: a benchmark of other tracks and other
    transmitter positions mixes the geometry into a check meant for the physics; replicates of the
    same design (a posterior-predictive check with the covariates held) do not."""
    x = np.asarray(real, float)
    rows = [np.asarray(r, float) for r in sim]
    if x.size == 0 or len(rows) != x.size or any(r.size == 0 for r in rows):
        raise ValueError("a design check needs each real flight's value and its replicates")
    keep = np.isfinite(x) & np.array([np.isfinite(r).any() for r in rows])
    x, rows = x[keep], [r[np.isfinite(r)] for r, k in zip(rows, keep, strict=True) if k]
    rng = np.random.default_rng(seed)
    means = np.mean([r[rng.integers(0, r.size, size=n_boot)] for r in rows], axis=0)
    bands = np.array([np.quantile(r, BAND) for r in rows])
    inside = int(np.sum((x >= bands[:, 0]) & (x <= bands[:, 1])))
    return _check_record(x, np.concatenate(rows), means, inside)


def family_checks(
    real_stats: Sequence[Mapping[str, float]],
    sim_stats: Sequence[Mapping[str, float]],
    real_errors: Mapping[str, Sequence[float]] | None = None,
    sim_errors: Mapping[str, Sequence[float]] | None = None,
    seed: int = 0,
) -> dict[str, dict]:
    """Every check: the RSS and residual statistics, then ``error m: METHOD`` per method present on
    both."""
    out = {
        k: predictive_check([r[k] for r in real_stats], [r[k] for r in sim_stats], seed=seed)
        for k in STATISTICS
    }
    for m, e in (real_errors or {}).items():
        if sim_errors and m in sim_errors:
            out[f"error m: {m}"] = predictive_check(e, sim_errors[m], seed=seed)
    return out


def verdict(checks: Mapping[str, dict]) -> str:
    """One line: passes, or which checks fail."""
    bad = [k for k, c in checks.items() if not c["passes"]]
    if not bad:
        return f"the family passes all {len(checks)} predictive checks"
    return f"the family fails {len(bad)} of {len(checks)} predictive checks: {', '.join(bad)}"


def checks_table(checks: Mapping[str, dict], title: str):
    """A rich table that reads at 80 columns."""
    t = Table(title=escape(title))
    for c in ("statistic", "real mean", "bench 10-90 %", "in", "p", "ok"):
        t.add_column(c, justify="left" if c == "statistic" else "right", overflow="fold")
    for k, c in checks.items():
        lo, hi = c["band"]
        t.add_row(
            escape(k),
            f"{c['real_mean']:.1f}",
            f"{lo:.1f}-{hi:.1f}",
            f"{c['inside']}/{c['n_real']}",
            f"{c['p']:.2f}",
            "yes" if c["passes"] else "NO",
        )
    return t


def score_real(
    logs: Sequence, methods: Sequence[str], seed: int = 0
) -> tuple[list[dict], dict[str, list[float]]]:
    """(check statistics per real log, {method: error m per log}) of real logs with truth in their
    sidecars; methods as ``rfsl evaluate --suite`` names them
    (``mission.workshop.evaluate.suite_method``)."""
    kws = {m: suite_method(m) for m in methods}
    stats: list[dict] = []
    errors: dict[str, list[float]] = {m: [] for m in methods}
    for p in logs:
        log = p if hasattr(p, "columns") else read_flight_log(p)  # a FlightLog or a path
        truth = log.truth_enu
        if truth is None:
            raise InputError(
                "a real flight for the predictive checks needs its truth in the sidecar",
                source=str(p),
            )
        stats.append(flight_statistics(log, truth[:2], float(truth[2]), seed=seed))
        for m, kw in kws.items():
            est = localize_log(log, **kw)
            errors[m].append(float(np.hypot(est.x_m - truth[0], est.y_m - truth[1])))
    return stats, errors
