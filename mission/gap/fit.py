"""Fitting: free constants, per-candidate parameter fits, held-out ranking and the greedy ladder.

Why these choices:

- The receiver's dB are uncalibrated (SPEC section 5), so every comparison removes a per-flight
  constant offset (and, optionally, a per-flight path-gain slope: ``meas ~ c + s * pred``) fitted on
  the very samples being scored.  This costs one (two) degrees of freedom per flight and fold, the
  same for every candidate.
- Candidates are fitted on training blocks and scored on the complementary blocks ("cross-fitting"):
  each flight is cut into ``n_chunks`` contiguous chunks (default 8, tens of seconds each, far
  longer than the residual's correlation time) and the two folds are the even and the odd chunks, so
  both folds see the whole geometry; or (``split="flights"``) each whole flight is held out in turn.
  Never random samples: neighbouring samples share their shadowing, so a random split would reward
  over-fitting.
- Ranking: by the held-out mean reduction of the per-sample loss (squared error, or soft-L1 for real
  data with deep fades); significance by a circular block bootstrap of that reduction (block length
  from its autocorrelation, per flight), one-sided at ``alpha / m`` (Bonferroni over the m
  candidates tried), and at least ``min_rel`` relative reduction (a practically negligible gain is
  not "significant").
- The greedy ladder adds the best significant candidate, keeps its fitted parameters (fold by fold)
  and ranks the remaining ones on top, until none is significant.  Spatially correlated shadowing is
  a catch-all (kriged residuals absorb any smooth misfit, and would go stale when a channel effect
  is added after it), so it joins the ladder only once no structured effect is significant; it is
  always ranked.
"""

from __future__ import annotations

import itertools
import multiprocessing as mp
import signal
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from mission.gap.candidate import (
    TIER_FREEFORM,
    TIER_NAMED,
    TIER_SMOOTHER,
    Candidate,
)
from mission.gap.optim import minimize_from_grid
from mission.gap.pipeline import Pipeline, Selection, joint_offset_residuals, offset_residuals
from mission.gap.stats import block_length, bootstrap_mean, summarize
from mission.robust import offset_residual, per_sample_loss  # noqa: F401  (their home; re-exported)
from mission.samples import FlightSamples


@dataclass(frozen=True)
class FitConfig:
    """Settings of the fits and the significance test."""

    split: str = "blocks"  # blocks | flights
    n_chunks: int = 8  # contiguous chunks per flight (blocks split)
    fit_max_samples: int = (
        3000  # training samples per flight used by the optimiser (evenly decimated)
    )
    fit_max_total: int = 5000  # ... and in all flights together (many flights: fewer per flight)
    max_folds: int = 4  # flights split: at most this many folds (groups of whole flights)
    slope: bool = False  # also fit a per-flight path-gain slope
    loss: str = "l2"  # l2 | soft_l1
    f_scale_db: float = 6.0  # soft_l1 scale
    max_evals: int = 60  # Nelder-Mead evaluations per start
    # Nelder-Mead stops once its simplex spans at most polish_xatol in every parameter (the
    # candidates' units: deg, dB, s, exponents) and its losses polish_fatol dB^2: finer than any
    # held-out figure can tell (the diagnosis reports 0.1 dB), and 8 % fewer calls than 1e-3 / 1e-6
    polish_xatol: float = 1e-2
    polish_fatol: float = 1e-4
    alpha: float = 0.05
    min_rel: float = (
        0.01  # minimum relative held-out loss reduction to call a candidate significant
    )
    n_boot: int = 400
    seed: int = 0
    workers: int = 1  # threads for the (candidate, fold) fits (1: the fits are GIL-bound now)
    processes: int = (
        1  # processes for the (candidate, fold) fits (fork; results bit-identical to 1)
    )
    rate_hz: float = 0.0  # thin flights to at most this sample rate before the diagnosis (0: all)


@dataclass
class Fold:
    """Training and test sample indices, one array per flight (may be empty); ``make_folds`` makes
    them ``Selection``s, which keep their joint geometry for the many candidates scored on them."""

    train: list[np.ndarray]
    test: list[np.ndarray]


def make_folds(flights: Sequence[FlightSamples], cfg: FitConfig) -> list[Fold]:
    """Contiguous-chunk folds (even/odd chunks), or whole flights held out: one flight per fold up
    to ``cfg.max_folds`` flights, beyond that the flights are dealt round-robin into ``max_folds``
    groups (the cost of a diagnosis grows with folds x training samples, so it stays bounded for
    many flights)."""
    if cfg.split == "flights" and len(flights) >= 2:
        k_folds = min(len(flights), cfg.max_folds)
        folds = []
        for k in range(k_folds):
            tr = [
                np.arange(len(f)) if j % k_folds != k else np.zeros(0, int)
                for j, f in enumerate(flights)
            ]
            te = [
                np.arange(len(f)) if j % k_folds == k else np.zeros(0, int)
                for j, f in enumerate(flights)
            ]
            folds.append(Fold(Selection(flights, tr), Selection(flights, te)))
        return folds
    chunk_of = [
        np.minimum((np.arange(len(f)) * cfg.n_chunks) // max(len(f), 1), cfg.n_chunks - 1)
        for f in flights
    ]
    folds = []
    for parity in (0, 1):
        te = [np.nonzero(c % 2 == parity)[0] for c in chunk_of]
        tr = [np.nonzero(c % 2 != parity)[0] for c in chunk_of]
        folds.append(Fold(Selection(flights, tr), Selection(flights, te)))
    return folds


def decimate(idx: np.ndarray, n_max: int) -> np.ndarray:
    """Every k-th index so that at most ``n_max`` remain."""
    if len(idx) <= n_max:
        return idx
    return idx[:: int(np.ceil(len(idx) / n_max))]


def residuals(
    pipe: Pipeline,
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    cfg: FitConfig,
    cache: list[np.ndarray] | None = None,
) -> list[np.ndarray]:
    """Offset-removed residuals per flight on the samples ``idx`` (``pipeline.offset_residuals``
    with the config's slope and loss; ``cache``: channel predictions to reuse)."""
    return offset_residuals(pipe, flights, idx, cfg.slope, cfg.loss, cfg.f_scale_db, cache)


def objective(
    pipe: Pipeline,
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    cfg: FitConfig,
    cache: list[np.ndarray] | None = None,
) -> float:
    """Mean per-sample loss over the given samples of all flights."""
    joint = joint_offset_residuals(pipe, flights, idx, cfg.slope, cfg.loss, cfg.f_scale_db, cache)
    if joint is not None:
        r = joint[0]
        return float(np.add.reduce(per_sample_loss(r, cfg.loss, cfg.f_scale_db)) / max(len(r), 1))
    rs = residuals(pipe, flights, idx, cfg, cache)
    n = sum(len(r) for r in rs)
    return float(sum(per_sample_loss(r, cfg.loss, cfg.f_scale_db).sum() for r in rs) / max(n, 1))


def _start_grid(
    cand: Candidate, cache: list[np.ndarray] | None, params: Sequence[Any] = ()
) -> list[tuple[float, ...]]:
    if cand.name == "receiver" and cache is not None:
        p = np.concatenate(cache)
        lo, hi = float(p.min()), float(p.max())
        floors = [lo - 30.0] + [float(np.quantile(p, q)) for q in (0.05, 0.15, 0.3)]
        sats = [hi + 30.0] + [float(np.quantile(p, q)) for q in (0.99, 0.95, 0.85)]
        return list(itertools.product(floors, sats))
    return list(itertools.product(*[prm.grid for prm in params]))


def _bounds(
    cand: Candidate, cache: list[np.ndarray] | None, params: Sequence[Any] = ()
) -> list[tuple[float, float]]:
    if cand.name == "receiver" and cache is not None:
        p = np.concatenate(cache)
        lo, hi = float(p.min()), float(p.max())
        return [(lo - 40.0, hi + 10.0), (lo - 10.0, hi + 40.0)]
    return [(prm.lo, prm.hi) if prm.period is None else (-np.inf, np.inf) for prm in params]


def _clipped(x: Sequence[float], bounds: Sequence[tuple[float, float]]) -> list[float]:
    """Each value clipped to its bounds, as ``float(np.clip(v, lo, hi))`` gives it (NaN stays NaN)
    without numpy's per-scalar overhead: the objective is called ~10^5 times a diagnosis."""
    return [float(min(max(v, lo), hi)) for v, (lo, hi) in zip(x, bounds, strict=True)]


def fit_selection(
    flights: Sequence[FlightSamples], idx: Sequence[np.ndarray], cfg: FitConfig
) -> Selection:
    """The training samples a fit uses: ``idx`` evenly decimated to ``cfg.fit_max_samples`` per
    flight and ``cfg.fit_max_total`` in all.  A fold's selection keeps it as a child, with the
    joint geometry and the prepared links, for every candidate fitted on the fold."""
    n_used = max(1, sum(len(i) > 0 for i in idx))
    n_max = min(cfg.fit_max_samples, max(200, cfg.fit_max_total // n_used))
    if isinstance(idx, Selection) and idx.of(flights):
        return idx.child(("decimate", n_max), lambda i: decimate(i, n_max))
    return Selection(flights, [decimate(i, n_max) for i in idx])


def coarse_selection(idx: Selection) -> Selection:
    """The thinned copy of a fit's samples that ranks dense start grids (every 4th sample: the
    residual is correlated over seconds)."""
    return idx.child("coarse", lambda i: i[::4])


def warm_selections(
    pipes: Sequence[Pipeline],
    flights: Sequence[FlightSamples],
    folds: Sequence[Fold],
    cfg: FitConfig,
) -> None:
    """Evaluate every fold's rung once on the samples its fits and scores use, so that the
    selections hold the joint geometry, the prepared links and the rung's own terms before the
    fits are forked: each process inherits them instead of making them again (same values)."""
    for pipe, fold in zip(pipes, folds, strict=True):
        if not isinstance(fold.train, Selection) or not fold.train.of(flights):
            continue
        sel = fit_selection(flights, fold.train, cfg)
        for s in (sel, coarse_selection(sel), fold.test):
            objective(pipe, flights, s, cfg)


@dataclass
class CandidateFit:
    """A candidate fitted on one training set."""

    pipeline: Pipeline
    params: dict[str, Any]
    train_loss: float


def _steps(params: Sequence[Any], bounds: Sequence[tuple[float, float]]) -> list[float]:
    """The first simplex edge per parameter: half the finest spacing of its start grid, else an
    eighth of its bounds (10 where unbounded)."""
    steps = [(b - a) / 8.0 if np.isfinite(b - a) else 10.0 for a, b in bounds]
    for j, prm in enumerate(params):
        if len(prm.grid) > 1:
            steps[j] = float(np.min(np.diff(np.sort(prm.grid)))) / 2.0
    return steps


def _fit_choice(
    cand: Candidate,
    pipe: Pipeline,
    flights: Sequence[FlightSamples],
    sels: tuple[Selection, Selection],
    caches: tuple[list[np.ndarray] | None, list[np.ndarray] | None],
    cfg: FitConfig,
    params: Sequence[Any],
    choice: dict[str, Any],
) -> CandidateFit:
    """``cand``'s continuous parameters for one categorical ``choice``: the start grid ranked (on
    the thinned samples ``sels[1]`` where the loss is multimodal in several dimensions), then
    Nelder-Mead on the fit's samples ``sels[0]`` (``caches``: their channel predictions, if
    any)."""
    names = [p.name for p in params]
    bounds = _bounds(cand, caches[0], params)

    def make(sel: Selection, cache: list[np.ndarray] | None) -> Callable[[np.ndarray], float]:
        def f(x: np.ndarray) -> float:
            xx = _clipped(x, bounds)
            return objective(
                cand.build(pipe, dict(zip(names, xx, strict=True)), choice),
                flights,
                sel,
                cfg,
                cache,
            )

        return f

    grid = np.array(_start_grid(cand, caches[0], params), dtype=float)
    # several starts where the loss is multimodal in several dims
    multi = len(params) >= 2 and len(grid) > 8
    xb, loss = minimize_from_grid(
        make(sels[0], caches[0]),
        grid,
        _steps(params, bounds),
        cfg.max_evals,
        n_starts=3 if multi else 1,
        xatol=cfg.polish_xatol,
        fatol=cfg.polish_fatol,
        coarse=make(sels[1], caches[1]) if multi else None,
    )
    x = _clipped(xb, bounds)
    for j, prm in enumerate(params):
        if prm.period:
            x[j] = x[j] % prm.period
    th = dict(zip(names, x, strict=True))
    return CandidateFit(cand.build(pipe, th, choice), {**th, **choice}, loss)


def fit_candidate(
    cand: Candidate,
    pipe: Pipeline,
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    cfg: FitConfig,
    rng: np.random.Generator,
) -> CandidateFit:
    """Fit ``cand`` added to ``pipe`` on the samples ``idx``: its own direct fit, or per
    categorical choice a coarse grid then bounded Nelder-Mead (``_fit_choice``); the choice with
    the lowest training loss wins."""
    idx = fit_selection(flights, idx, cfg)
    if cand.direct_fit is not None:
        res = residuals(pipe, flights, idx, cfg)
        new, params = cand.direct_fit(pipe, list(flights), idx, res, rng, cfg)
        return CandidateFit(new, params, objective(new, flights, idx, cfg))
    cache = None
    if cand.post_only:
        cache = [
            pipe.predict_channel(f, i) if len(i) else np.zeros(0)
            for f, i in zip(flights, idx, strict=True)
        ]
    params = cand.params_for(pipe)
    sels = (idx, coarse_selection(idx))
    caches = (cache, None if cache is None else [c[::4] for c in cache])
    best: CandidateFit | None = None
    for choice in cand.choices(pipe):
        if not params:
            new = cand.build(pipe, {}, choice)
            fit = CandidateFit(new, dict(choice), objective(new, flights, idx, cfg, cache))
        else:
            fit = _fit_choice(cand, pipe, flights, sels, caches, cfg, params, choice)
        if best is None or fit.train_loss < best.train_loss:
            best = fit
    assert best is not None
    return best


def heldout_residuals(
    pipes: Sequence[Pipeline],
    flights: Sequence[FlightSamples],
    folds: Sequence[Fold],
    cfg: FitConfig,
) -> list[np.ndarray]:
    """Held-out residual per sample (NaN where a sample is in no test set), one array per flight."""
    out = [np.full(len(f), np.nan) for f in flights]
    for pipe, fold in zip(pipes, folds, strict=True):
        rs = residuals(pipe, flights, fold.test, cfg)
        for k, (i, r) in enumerate(zip(fold.test, rs, strict=True)):
            out[k][i] = r
    return out


@dataclass
class CandidateResult:
    """One candidate tried on top of the current rung."""

    name: str
    fold_params: list[dict[str, Any]]
    pipes: list[Pipeline]
    residuals: list[np.ndarray]
    loss_reduction: float  # held-out mean loss reduction (dB^2)
    rel_reduction: float  # relative to the current rung's held-out loss
    ci_lo: float  # one-sided lower bound of the reduction (block bootstrap)
    significant: bool
    rms_before: float
    rms_after: float
    p90_before: float
    p90_after: float
    block_len: int = 0
    tier: str = TIER_NAMED

    def params_mean(self) -> dict[str, Any]:
        """Fold-averaged parameters (circular mean for angles); categorical ones from the first
        fold."""
        out: dict[str, Any] = {}
        for k, v in self.fold_params[0].items():
            vals = [fp.get(k) for fp in self.fold_params]
            if isinstance(v, dict | list | tuple):  # shapes, where-it-acts: the first fold's
                out[k] = v
            elif isinstance(v, bool | str) or v is None:
                out[k] = v if all(x == v for x in vals) else "/".join(str(x) for x in vals)
            elif "heading" in k or "azimuth" in k:
                a = np.deg2rad(np.array(vals, dtype=float))
                out[k] = float(np.rad2deg(np.arctan2(np.sin(a).mean(), np.cos(a).mean())) % 360.0)
            else:
                out[k] = float(np.mean(vals))
        return out


def _pooled(rs: Sequence[np.ndarray]) -> np.ndarray:
    return np.concatenate([r[np.isfinite(r)] for r in rs]) if rs else np.zeros(0)


def compare(
    base_res: Sequence[np.ndarray],
    new_res: Sequence[np.ndarray],
    cfg: FitConfig,
    m: int,
    rng: np.random.Generator,
) -> tuple[float, float, float, bool, int]:
    """Held-out loss reduction: mean, relative, one-sided lower bound, significant, block length."""
    ds, Ls = [], []
    for a, b in zip(base_res, new_res, strict=True):
        ok = np.isfinite(a) & np.isfinite(b)
        d = per_sample_loss(a[ok], cfg.loss, cfg.f_scale_db) - per_sample_loss(
            b[ok], cfg.loss, cfg.f_scale_db
        )
        ds.append(d)
        Ls.append(block_length(d) if d.size > 3 else 1)
    alld = np.concatenate(ds)
    base_loss = float(np.mean(per_sample_loss(_pooled(base_res), cfg.loss, cfg.f_scale_db)))
    mean = float(alld.mean()) if alld.size else 0.0
    boot = bootstrap_mean(
        [d for d in ds if d.size],
        [L for d, L in zip(ds, Ls, strict=True) if d.size],
        cfg.n_boot,
        rng,
    )
    # one-sided lower bound: the alpha / m quantile of the replicates (percentile bootstrap; the
    # reductions are right-skewed -- a few deep fades fixed -- so a normal approximation would be
    # far too conservative)
    lo = float(np.quantile(boot, cfg.alpha / max(m, 1)))
    rel = mean / base_loss if base_loss > 0 else 0.0
    return mean, rel, lo, bool(lo > 0 and rel >= cfg.min_rel), int(max(Ls) if Ls else 1)


# The ranking rule (reported with every ranking): a candidate's score is its held-out loss reduction
# divided by its tier's margin; significant candidates come first, then by score.  A free-form shape
# must therefore reduce the loss 25 % more than a named physical effect to be ranked above it, and a
# generic smoother (kriging) twice as much as either: explanations are preferred to descriptions,
# descriptions to smoothers.
TIER_MARGIN = {TIER_NAMED: 1.0, TIER_FREEFORM: 1.25, TIER_SMOOTHER: 2.0}
RANKING_RULE = (
    "significant first, then by held-out loss reduction / tier margin (named 1.0, free-form 1.25, "
    "smoother 2.0): a free-form shape must beat a named effect by 25 %, a smoother must beat both "
    "by 100 %; the ladder adds a smoother only when nothing else is significant"
)


def rank_key(r: CandidateResult) -> tuple[bool, float]:
    return (not r.significant, -r.loss_reduction / TIER_MARGIN.get(r.tier, 1.0))


# (fn, items) of the running process map: the forked workers read it, nothing is pickled
_FORKED: list[Any] = []


def _forked_call(i: int) -> Any:
    fn, items = _FORKED[-1]
    return fn(items[i])


def _init_worker() -> None:
    """A forked worker: BLAS single-threaded, and SIGTERM back to its default.  Why the signal: a
    worker inherits the parent's Python handler (a test's, a CLI's), and a handler does not end a
    worker waiting on the pool's task-queue lock, so the pool's terminate never ended it and its
    join waited forever (a CI run hung in ``test_gap_time_frame``, 2026-11-28)."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    threadpool_limits(limits=1, user_api="blas")


def _map(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    workers: int,
    processes: int = 1,
    done: Callable[[int], None] | None = None,
    order: Sequence[int] | None = None,
    arrived: Callable[[int, Any], None] | None = None,
) -> list[Any]:
    """``fn`` over ``items``, in ``processes`` forked processes (the closures are inherited by the
    fork, only the results travel back, pickled), else in ``workers`` threads (numpy releases the
    GIL in the heavy parts); the results in the items' order, so they are those of one call after
    another, bit for bit.  ``order``: the order the processes are handed the items in (the longest
    first, so that they finish together; the results do not depend on it).  ``done(k)``: called in
    this process as the k-th result arrives (progress); ``arrived(i, result)``: called in this
    process with item i's result as it arrives (work on it while the processes go on).

    BLAS runs single-threaded meanwhile: the fits' matrices are small (kriging systems of a few
    hundred cells, Gram matrices of ~100 columns), the parallelism is over the fits, and a
    multi-threaded OpenBLAS on a busy machine spins for its cores (a 350 x 350 Cholesky took 70 ms
    with 2 BLAS threads against 2 ms with one at load 10 on 2 cores).  ``threadpoolctl`` comes with
    scikit-learn."""

    def tick(it: Any, seq: Sequence[int]) -> list[Any]:
        out: list[Any] = [None] * len(items)
        for k, (i, r) in enumerate(zip(seq, it, strict=True)):
            out[i] = r
            if arrived is not None:
                arrived(i, r)
            if done is not None:
                done(k + 1)
        return out

    with threadpool_limits(limits=1, user_api="blas"):
        if processes > 1 and len(items) > 1:
            _FORKED.append((fn, items))
            seq = list(range(len(items))) if order is None else list(order)
            try:
                with mp.get_context("fork").Pool(
                    min(processes, len(items)), initializer=_init_worker
                ) as pool:
                    out = tick(pool.imap(_forked_call, seq), seq)
                    pool.close()  # the workers end on the queue's sentinel: no terminate needed
                    pool.join()
                    return out
            finally:
                _FORKED.pop()
        if workers <= 1 or len(items) <= 1:
            return tick((fn(x) for x in items), range(len(items)))

        with ThreadPoolExecutor(max_workers=workers) as ex:
            return tick(ex.map(fn, items), range(len(items)))


def longest_first(costs: Sequence[float]) -> list[int]:
    """Indices by decreasing cost (ties in index order): the order to hand tasks to processes in, so
    that the last ones handed out are short and the processes finish together."""
    return sorted(range(len(costs)), key=lambda k: (-costs[k], k))


Progress = Callable[[str, int, int], None]  # (description, done, total)


def _scored(
    cand: Candidate,
    part: Sequence[tuple[CandidateFit, list[np.ndarray], float]],
    flights: Sequence[FlightSamples],
    folds: Sequence[Fold],
    base_res: list[np.ndarray],
    cfg: FitConfig,
    m: int,
    rng: np.random.Generator,
) -> CandidateResult:
    """One candidate's fold fits (``part``: fit, test residuals, seconds) scored against the base
    rung's held-out residuals (``compare``, Bonferroni over ``m`` candidates)."""
    fits = [ft for ft, _, _ in part]
    res = [np.full(len(f), np.nan) for f in flights]
    for (_, rs, _), fold in zip(part, folds, strict=True):
        for q, (i, r) in enumerate(zip(fold.test, rs, strict=True)):
            res[q][i] = r
    mean, rel, lo, sig, L = compare(base_res, res, cfg, m, rng)
    b, s = summarize(_pooled(base_res)), summarize(_pooled(res))
    return CandidateResult(
        cand.name,
        [ft.params for ft in fits],
        [ft.pipeline for ft in fits],
        res,
        mean,
        rel,
        lo,
        sig,
        b.rms,
        s.rms,
        b.p90_abs,
        s.p90_abs,
        L,
        cand.tier,
    )


def rank_candidates(
    pipes: Sequence[Pipeline],
    flights: Sequence[FlightSamples],
    folds: Sequence[Fold],
    candidates: Sequence[Candidate],
    cfg: FitConfig,
    rng: np.random.Generator,
    base_res: list[np.ndarray] | None = None,
    progress: Progress | None = None,
    label: str = "",
    costs: dict[str, float] | None = None,
) -> list[CandidateResult]:
    """Fit every applicable candidate on each fold's training data, score on its test data, rank
    (``rank_key``).

    The (candidate, fold) fits run in ``cfg.processes`` processes or ``cfg.workers`` threads; each
    gets its own generator spawned from ``rng`` in a fixed order, so results do not depend on the
    scheduling.  Each candidate's bootstrap has its own generator too, drawn before any fit: a
    candidate is scored as soon as its folds are in (while the processes fit the rest), and one
    fit's change (a block length) no longer moves every later candidate's bound.  ``costs``:
    seconds a fit of each candidate took, kept by the caller across rankings (the ladder's rungs):
    the processes are handed the costliest fits first (a candidate not timed yet counts as costlier
    than any), and the times of this ranking are stored back.
    """
    base_res = base_res if base_res is not None else heldout_residuals(pipes, flights, folds, cfg)
    tried = [c for c in candidates if c.applicable(pipes[0])]
    tasks = [(c, k) for c in tried for k in range(len(folds))]
    seeds = rng.integers(0, 2**63 - 1, size=len(tasks))
    boot_seeds = rng.integers(0, 2**63 - 1, size=len(tried))
    nf = len(folds)

    def run(
        task_seed: tuple[tuple[Candidate, int], int],
    ) -> tuple[CandidateFit, list[np.ndarray], float]:
        (cand, k), seed = task_seed
        t0 = time.process_time()
        ft = fit_candidate(
            cand, pipes[k], flights, folds[k].train, cfg, np.random.default_rng(seed)
        )
        res = residuals(ft.pipeline, flights, folds[k].test, cfg)
        return ft, res, time.process_time() - t0

    order = None
    if cfg.processes > 1:
        warm_selections(pipes, flights, folds, cfg)
        known = costs or {}
        order = longest_first([known.get(c.name, np.inf) for c, _ in tasks])

    def done(n: int) -> None:
        if progress is not None:
            k = n - 1 if order is None else order[n - 1]
            progress(f"{label}: {tasks[k][0].name}", n, len(tasks))

    got: dict[int, Any] = {}
    scored: dict[int, CandidateResult] = {}

    def arrived(i: int, r: Any) -> None:
        got[i] = r
        j = i // nf
        if all(j * nf + k in got for k in range(nf)):
            part = [got[j * nf + k] for k in range(nf)]
            scored[j] = _scored(
                tried[j],
                part,
                flights,
                folds,
                base_res,
                cfg,
                len(tried),
                np.random.default_rng(boot_seeds[j]),
            )

    results = _map(
        run,
        list(zip(tasks, seeds, strict=True)),
        cfg.workers,
        cfg.processes,
        done,
        order,
        arrived,
    )
    if costs is not None:
        for j, cand in enumerate(tried):
            costs[cand.name] = float(np.mean([t for _, _, t in results[j * nf : (j + 1) * nf]]))
    out = [scored[j] for j in range(len(tried))]
    out.sort(key=rank_key)
    return out
