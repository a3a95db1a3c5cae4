"""The unseen-flight benchmark's evaluation (``rfsl evaluate --suite``): each method on each suite
flight, exactly as ``localize`` would run it on a real log, the error against the truth kept beside
the log, the coverage of the estimate's uncertainty regions, and a breakdown of the errors by any
drawn axis.

Split from ``mission.workshop.evaluate`` (simulated test sets and real flights), whose ``Row`` and
``suite_method`` (a benchmark method spec -> ``localize_log`` arguments, also used by
``mission.workshop.predictive``) it uses.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from matplotlib.path import Path as MPath

from mission.errors import InputError
from mission.localize.api import localize_log
from mission.localize.region import ELLIPSE_KEYS, Ellipse, Region
from mission.localize.uncertainty import region_covers
from mission.threads import limit_worker, pool_context
from mission.workshop.evaluate import Row, suite_method
from mission.workshop.predictive import flight_statistics
from mission.workshop.suite import (
    BENCHMARK_SEED,
    FamilyArg,
    draw_flight,
    family_label,
    family_sha256,
    resolve_family,
    unseen_flight,
)
from mission.workshop.suite_cache import read_suite


def _level(lv) -> str | None:
    """A level (0.9, 90 or "90") as the row's key ("90"); None when it is not a number."""
    try:
        v = float(lv)
    except (TypeError, ValueError):
        return None
    return f"{round(v * 100 if v <= 1 else v):d}"


def region_contains(region: dict, xy) -> bool:
    """Whether point ``xy`` (log ENU m) lies in a region of a composer's own layout (an estimate's
    ``extras["regions"]`` that is not typed ``Region``).

    Accepted shapes: ``{"polygon": [[x, y], ...]}`` (also ``polygon_xy_m``), or an ellipse
    ``{"center_m": [x, y], "semi_axes_m": [a, b], "angle_deg": t}`` with the first semi-axis ``t``
    degrees counter-clockwise from east (``center``/``center_xy_m``, ``axes_m``/``semi_axes`` and
    ``angle`` also read), or ``{"center_m": [x, y], "cov_m2": [[..], [..]], "chi2": k}`` = the set
    ``d^T cov^-1 d <= k``, or the ``ellipse`` of ``mission.localize.uncertainty``'s layout (``x_m,
    y_m, a_m, b_m, angle_deg``).
    """
    p = np.asarray(xy, dtype=float)[:2]
    if "ellipse" in region and not any(
        k in region for k in ("polygon", "polygon_xy_m", "center_m")
    ):
        # the mission.localize.uncertainty layout (error circles of error_circles too)
        el = region["ellipse"]
        return Ellipse(*(float(el[k]) for k in ELLIPSE_KEYS)).contains(p[0], p[1])
    poly = region.get("polygon", region.get("polygon_xy_m"))
    if poly is not None:
        return bool(MPath(np.asarray(poly, dtype=float)).contains_point(p))
    c = np.asarray(
        next(region[k] for k in ("center_m", "center_xy_m", "center") if k in region), dtype=float
    )
    if "cov_m2" in region or "cov" in region:
        d = p - c[:2]
        cov = np.asarray(region.get("cov_m2", region.get("cov")), dtype=float)
        return bool(d @ np.linalg.solve(cov, d) <= float(region.get("chi2", 1.0)))
    a, b = (
        float(v)
        for v in next(region[k] for k in ("semi_axes_m", "axes_m", "semi_axes") if k in region)
    )
    t = float(region.get("angle_deg", region.get("angle", 0.0)))
    return Ellipse(float(c[0]), float(c[1]), a, b, t).contains(p[0], p[1])


def _regions(est) -> dict[str, Region | dict]:
    """Level ("50", "90") -> region of an estimate: its typed ``regions``, else a composer's own
    layout in ``extras["regions"]`` (dict keyed by level or list of dicts with "level")."""
    if est.regions:
        return {lvl: r for r in est.regions if (lvl := _level(r.level)) is not None}
    regs = (est.extras or {}).get("regions")
    if not regs:
        return {}
    items = regs.items() if isinstance(regs, dict) else ((None, r) for r in regs)
    out = {}
    for k, r in items:
        if isinstance(r, dict) and (lvl := _level(r.get("level", k))) is not None:
            out[lvl] = r
    return out


def region_coverage(est, truth) -> dict[str, bool]:
    """Level -> whether the truth lies in the estimate's region: on the posterior grid when the
    estimate has one (``mission.localize.uncertainty.region_covers``), else by the region's drawn
    shape (a typed region's ellipse: an error circle's circle)."""
    x, y = float(truth[0]), float(truth[1])
    out = {}
    for lvl, r in _regions(est).items():
        if isinstance(r, Region):
            c = region_covers(est, x, y, r.level)
            out[lvl] = r.ellipse.contains(x, y) if c is None else c
            continue
        c = region_covers(est, x, y, float(r["level"])) if "level" in r else None
        out[lvl] = region_contains(r, truth) if c is None else c
    return out


_SUITE: dict = {}


def _suite_init(methods: dict[str, dict], source: dict, one_thread: bool = False) -> None:
    # worker processes: one BLAS/OpenMP thread each (k-means threads spin on a busy machine)
    if one_thread:
        limit_worker()
    _SUITE.clear()
    _SUITE.update(methods=methods, source=source)
    if "dir" in source:
        _SUITE["cached"] = read_suite(source["dir"])


def _suite_flight(i: int) -> dict:
    """Every method on flight ``i``: {label: [error m, {level: covered}, seconds]}."""
    src = _SUITE["source"]
    if "cached" in _SUITE:
        log, truth, draw = _SUITE["cached"].load(i)
    else:
        log, truth, draw = unseen_flight(src["seed"], i, src["family"], src["center"])
    out: dict = {}
    if src.get("stats"):  # the posterior-predictive check statistics (mission.workshop.predictive)
        out["__stats__"] = flight_statistics(log, truth, draw["tx_height_m"], seed=i)
    for label, kw in _SUITE["methods"].items():
        t0 = time.perf_counter()
        est = localize_log(log, **kw)
        dt = time.perf_counter() - t0
        cov = region_coverage(est, truth)
        out[label] = [float(np.hypot(est.x_m - truth[0], est.y_m - truth[1])), cov, dt]
    return out


def evaluate_suite(
    methods: Sequence[str],
    n: int = 200,
    seed: int | None = None,
    suite_dir: str | Path | None = None,
    family: FamilyArg = "afar",
    center: str = "afar",
    workers: int = 2,
    progress: Callable[[int, int], None] | None = None,
    warn: Callable[[str], None] | None = None,
    stats_out: list | None = None,
) -> tuple[list[Row], dict[str, float]]:
    """Methods on the unseen-flight benchmark (``mission.workshop.suite``): (rows, mean seconds per
    flight).

    Flights come from ``suite_dir`` (a cache written by ``write_suite``; its first ``n``) or are
    simulated here from ``seed`` (default ``BENCHMARK_SEED``).  Each method sees only the log
    (``localize_log``); the error is 2D against the truth kept beside it; when an estimate carries
    ``extras["regions"]`` the rows count how often the truth lies in the 50 % / 90 % region.
    Results do not depend on ``workers``.

    A ``suite_dir`` written by other simulator code than this (``CachedSuite.check_current``) is
    still scored, but its one-line warning goes to ``warn`` first (default: ``warnings.warn``).
    ``stats_out`` (a list) receives each flight's posterior-predictive statistics
    (``mission.workshop.predictive.flight_statistics``), in order.
    """
    fam = resolve_family(family)
    labels = {m: suite_method(m) for m in methods}
    if not labels:
        raise InputError("no methods to evaluate", field="--methods")
    source, test, n = _suite_source(fam, n, seed, suite_dir, center, warn, stats_out is not None)
    rows = {
        m: Row(test, m, None, "onnx" if kw.get("method") == "onnx" else "classical", [], [])
        for m, kw in labels.items()
    }
    secs = {m: 0.0 for m in labels}
    with _flight_results(labels, source, n, workers) as results:
        for i, res in enumerate(results):
            if (st := res.pop("__stats__", None)) is not None and stats_out is not None:
                stats_out.append(st)
            for m, (err, cov, dt) in res.items():
                rows[m].errors.append(err)
                rows[m].names.append(f"flight_{i:05d}")
                for lvl, c in cov.items():
                    rows[m].covered.setdefault(lvl, []).append(c)
                secs[m] += dt
            if progress:
                progress(i + 1, n)
    return list(rows.values()), {m: s / max(n, 1) for m, s in secs.items()}


def _suite_source(
    fam,
    n: int,
    seed: int | None,
    suite_dir: str | Path | None,
    center: str,
    warn: Callable[[str], None] | None,
    stats: bool,
) -> tuple[dict, str, int]:
    """(where the workers get their flights, the test's label, the number of flights): the cache
    ``suite_dir`` (checked against ``fam``, a stale cache warned about) or the family and seed."""
    if suite_dir is not None:
        cs = read_suite(suite_dir)
        if (stale := cs.check_current()) is not None:
            if warn is None:
                warnings.warn(stale, UserWarning, stacklevel=3)  # evaluate_suite's caller
            else:
                warn(stale)
        n = min(n, len(cs)) if n else len(cs)
        mf = cs.manifest
        check_cache_family(cs, fam)
        source: dict = {"dir": str(suite_dir), "stats": stats}
        return source, f"suite:unseen[seed={mf['seed']},family={mf['family']},n={n}]", n
    seed = BENCHMARK_SEED if seed is None else seed
    source = {"seed": int(seed), "family": fam, "center": center, "stats": stats}
    return source, f"suite:unseen[seed={seed},family={family_label(fam)},n={n}]", n


@contextmanager
def _flight_results(labels: dict, source: dict, n: int, workers: int) -> Iterator:
    """Each flight's results in flight order: in this process, or from a pool of ``workers``
    processes closed on the way out."""
    if workers <= 1:
        _suite_init(labels, source)
        yield map(_suite_flight, range(n))
        return
    ctx = pool_context()
    pool = ctx.Pool(workers, initializer=_suite_init, initargs=(labels, source, True))
    try:
        yield pool.imap(_suite_flight, range(n), chunksize=1)
    finally:
        pool.close()
        pool.join()


def check_cache_family(cs, fam) -> None:
    """Refuse a cache drawn from another family than the family file given beside it (a built-in
    name is not checked: the CLIs pass ``afar`` by default)."""
    if isinstance(fam, str):
        return

    have = cs.manifest.get("family_sha256")
    if have != family_sha256(fam):
        raise InputError(
            f"the cache was drawn from family {cs.manifest.get('family')!r}, not from the "
            "family file "
            f"given ({fam.name!r}); drop --family or rewrite the cache",
            source=str(cs.path),
            field="--family",
        )


def suite_draws(
    n: int,
    seed: int | None = None,
    suite_dir: str | Path | None = None,
    family: FamilyArg = "afar",
    center: str = "afar",
) -> list[dict]:
    """The draws (every parameter) of benchmark flights 0..n-1, from a cache or redrawn (cheap: no
    flying)."""
    if suite_dir is not None:
        return [f["draw"] for f in read_suite(suite_dir).manifest["flights"][:n]]
    s = BENCHMARK_SEED if seed is None else seed
    return [draw_flight(s, i, resolve_family(family), center)[0] for i in range(n)]


def _axis_value(draw: dict, axis: str):
    v: object = draw
    for part in axis.split("."):  # e.g. physics.rx_antenna, trajectory_params.region
        if not isinstance(v, dict) or part not in v:
            raise InputError(
                f"benchmark draws have no axis {axis!r} (e.g. heading_habit, "
                "tx_outside_flight_area, "
                "altitude_m, physics.rx_antenna, trajectory)",
                field="--by",
            )
        v = v[part]
    return v


def breakdown(
    rows: Sequence[Row], draws: Sequence[dict], axis: str, bins: int = 3
) -> dict[str, dict[str, float]]:
    """Mean error per method by the value of one draw axis: {group label: {method: mean m, "n":
    count}}.

    Text / bool axes group by value; numeric axes by ``bins`` equal-count bins (label ``lo-hi``)."""
    vals = [_axis_value(d, axis) for d in draws]
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in vals):
        x = np.asarray(vals, dtype=float)
        edges = np.quantile(x, np.linspace(0, 1, bins + 1))
        idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, bins - 1)
        labels = [f"{edges[k]:.3g}-{edges[k + 1]:.3g}" for k in range(bins)]
        keys = [labels[k] for k in idx]
    else:
        keys = [str(v) for v in vals]
    out: dict[str, dict[str, float]] = {}
    for g in dict.fromkeys(sorted(set(keys))):
        m = np.array([k == g for k in keys])
        out[g] = {"n": int(m.sum())}
        for r in rows:
            e = np.asarray(r.errors, dtype=float)[: len(m)]
            out[g][r.method] = float(e[m[: e.size]].mean())
    return out
